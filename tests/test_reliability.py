"""Bad input from a careful user and a hostile one, every case in its own
process (a 60 s limit): an abort, a hang or a crash fails its case instead of
killing the test run. The processes fork from a server that imported
nrdepth and torch once (``multiprocessing``'s forkserver), so a case costs
no interpreter start. Each case must raise the named exception with a message
that names the argument or file (API), or exit 2 with one line that does
(CLI), and must write nothing it should not."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

import nrdepth
from nrdepth.engine.dataset import write_dataset

TINY = "nrdepth.GeneratorConfig(frames=4, size=16, grid=16, texture_size=32)"

PRELUDE = """
import json, math, os, sys
from pathlib import Path
import numpy as np
import nrdepth
MODEL, DATA = Path(os.environ["CASE_MODEL"]), Path(os.environ["CASE_DATA"])
"""

# (id, code, expected "Type: message start" of what it raises)
API_CASES = [
    ("surface-huge", "nrdepth.synthesize_surface(nrdepth.sample_surface_params(0), frames=4096, grid=4096)", "ValueError: grid:"),
    ("surface-grid-1", "nrdepth.synthesize_surface(nrdepth.sample_surface_params(0), frames=4, grid=1)", "ValueError: grid:"),
    ("surface-frames-0", "nrdepth.synthesize_surface(nrdepth.sample_surface_params(0), frames=0, grid=8)", "ValueError: frames:"),
    ("surface-frames-float", "nrdepth.synthesize_surface(nrdepth.sample_surface_params(0), frames=2.5, grid=8)", "TypeError: frames:"),
    ("surfaces-not-dicts", "nrdepth.synthesize_surfaces([1, 2])", "TypeError: params"),
    ("surface-params-seed", "nrdepth.sample_surface_params(-1)", "ValueError: seed:"),
    ("layout-huge", "nrdepth.patch_layout((2**20,) * 3)", "ValueError: shape:"),
    ("layout-fraction", "nrdepth.patch_layout((16.7, 64, 64))", "ValueError: shape:"),
    ("layout-two-sizes", "nrdepth.patch_layout((16, 64))", "ValueError: shape:"),
    ("layout-zero", "nrdepth.patch_layout((0, 64, 64))", "ValueError: shape:"),
    ("clips-start-wraps", "nrdepth.generate_clips(2, start=2**64 - 1)", "ValueError: start:"),
    ("clips-negative", "nrdepth.generate_clips(-1)", "ValueError: n:"),
    ("clips-seed", "nrdepth.generate_clips(2, seed=-1)", "ValueError: seed:"),
    ("clips-config-type", "nrdepth.generate_clips(2, config='fast')", "TypeError: config:"),
    ("config-azimuth-reversed", "nrdepth.GeneratorConfig(light_azimuth=(1.0, -1.0))", "ValueError: config.light_azimuth"),
    ("config-azimuth-out", "nrdepth.GeneratorConfig(light_azimuth=(-7.0, 0.0))", "ValueError: config.light_azimuth"),
    ("config-azimuth-wide", "nrdepth.GeneratorConfig(light_azimuth=(-4.0, 4.0))", "ValueError: config.light_azimuth"),
    ("config-size-0", "nrdepth.GeneratorConfig(size=0)", "ValueError: config.size"),
    ("config-frames-float", "nrdepth.GeneratorConfig(frames=2.5)", "TypeError: config.frames"),
    ("config-noise-reversed", "nrdepth.GeneratorConfig(noise_std=(0.1, 0.0))", "ValueError: config.noise_std"),
    ("config-family", "nrdepth.GeneratorConfig(texture_families=('tartan',))", "ValueError: config.texture_families"),
    ("config-textures", "nrdepth.GeneratorConfig(textures='/no/such/folder')", "ValueError: config.textures"),
    ("mae-constant-gt", "nrdepth.mae_sn(np.random.rand(2, 8, 8), np.ones((2, 8, 8)))", "ValueError: gt: frame 0 is constant"),
    ("mae-tiny-constant-gt", "nrdepth.mae_sn(np.random.rand(2, 8, 8), 1e-300 * np.ones((2, 8, 8)))", "ValueError: gt: frame 0 is constant"),
    ("mae-shapes", "nrdepth.mae_sn(np.zeros((2, 8, 8)), np.zeros((2, 8, 9)))", "ValueError: pred:"),
    ("mae-nan", "nrdepth.mae_sn(np.zeros((2, 8, 8)), np.full((2, 8, 8), np.nan))", "ValueError: gt:"),
    ("mae-align", "nrdepth.mae_sn(np.random.rand(2, 8, 8), np.random.rand(2, 8, 8), align='last')", "ValueError: align:"),
    ("stitch-foreign-layout",
     "L = nrdepth.patch_layout((16, 64, 64)); L2 = L._replace(origins=L.origins[::-1].copy())\n"
     "nrdepth.stitch(np.zeros((len(L.origins), 16, 64, 64), np.float32), np.zeros((16, 64, 64), np.float32), L2)", "ValueError: layout:"),
    ("stitch-patch-count",
     "L = nrdepth.patch_layout((16, 64, 64))\nnrdepth.stitch(np.zeros((3, 16, 64, 64), np.float32), np.zeros((16, 64, 64), np.float32), L)", "ValueError: patches:"),
    ("temporal-int", "nrdepth.temporal_align(np.zeros((2, 8, 8), np.int32))", "ValueError: depth:"),
    ("reconstruct-float-255", "nrdepth.reconstruct(np.random.rand(16, 64, 64).astype(np.float32) * 255, MODEL)", r"ValueError: video: expected float frames in \[0, 1\], got values in \[.*\]; divide 0..255 data by 255"),
    ("reconstruct-progress-bool", "nrdepth.reconstruct(np.zeros((4, 32, 32), np.uint8), MODEL, progress=False)", "TypeError: progress:"),
    ("reconstruct-model-int", "nrdepth.reconstruct(np.zeros((4, 32, 32), np.uint8), model=123)", "TypeError: model:"),
    ("reconstruct-batch-0", "nrdepth.reconstruct(np.zeros((4, 32, 32), np.uint8), MODEL, batch_size=0)", "ValueError: batch_size:"),
    ("reconstruct-roi-out", "nrdepth.reconstruct(np.zeros((4, 32, 32), np.uint8), MODEL, roi=(20, 0, 20, 20))", "ValueError: roi:"),
    ("reconstruct-frames-step", "nrdepth.reconstruct(np.zeros((4, 32, 32), np.uint8), MODEL, frames=slice(None, None, -1))", "ValueError: frames:"),
    ("reconstruct-2d", "nrdepth.reconstruct(np.zeros((32, 32), np.uint8), MODEL)", "ValueError: video:"),
    ("reconstruct-nan", "nrdepth.reconstruct(np.full((4, 32, 32), np.nan, np.float32), MODEL)", "ValueError: video:"),
    ("reconstruct-int16", "nrdepth.reconstruct(np.zeros((4, 32, 32), np.int16), MODEL)", "TypeError: video:"),
    ("load-missing", "nrdepth.model.load_model(MODEL.parent / 'missing.safetensors')", "ValueError: .*missing.safetensors: not found"),
    ("load-corrupt",
     "import shutil; d = Path('m'); d.mkdir(); shutil.copy(MODEL.with_suffix('.json'), d / 'model.json')\n"
     "(d / 'model.safetensors').write_bytes(os.urandom(256)); nrdepth.model.load_model(d)", "ValueError: m/model.safetensors: not a readable safetensors file"),
    ("load-empty",
     "import shutil; d = Path('m'); d.mkdir(); shutil.copy(MODEL.with_suffix('.json'), d / 'model.json')\n"
     "(d / 'model.safetensors').write_bytes(b''); nrdepth.model.load_model(d)", "ValueError: m/model.safetensors: not a readable safetensors file"),
    ("load-truncated",
     "import shutil; d = Path('m'); d.mkdir(); shutil.copy(MODEL.with_suffix('.json'), d / 'model.json')\n"
     "(d / 'model.safetensors').write_bytes(MODEL.read_bytes()[:len(MODEL.read_bytes()) // 2]); nrdepth.model.load_model(d)",
     "ValueError: m/model.safetensors: not a readable safetensors file"),
    ("load-huge-header",
     "import shutil, struct; d = Path('m'); d.mkdir(); shutil.copy(MODEL.with_suffix('.json'), d / 'model.json')\n"
     "(d / 'model.safetensors').write_bytes(struct.pack('<Q', 2**62) + b'{}'); nrdepth.model.load_model(d)",
     "ValueError: m/model.safetensors: not a readable safetensors file"),
    ("load-bad-json",
     "import shutil; d = Path('m'); d.mkdir(); shutil.copy(MODEL, d / 'model.safetensors')\n"
     "(d / 'model.json').write_text('{architecture'); nrdepth.model.load_model(d)", "ValueError: m/model.json: not valid JSON"),
    ("load-empty-json",
     "import shutil; d = Path('m'); d.mkdir(); shutil.copy(MODEL, d / 'model.safetensors')\n"
     "(d / 'model.json').write_text('{}'); nrdepth.model.load_model(d)", "ValueError: m/model.json: expected an object"),
    ("load-mismatched",
     "import shutil; d = Path('m'); d.mkdir(); shutil.copy(MODEL, d / 'model.safetensors')\n"
     "(d / 'model.json').write_text(json.dumps({'architecture': 'unet3d', 'config': {'base': 4}})); nrdepth.model.load_model(d)",
     "ValueError: m/model.safetensors: the weights do not fit"),
    ("load-unknown-arch",
     "import shutil; d = Path('m'); d.mkdir(); shutil.copy(MODEL, d / 'model.safetensors')\n"
     "(d / 'model.json').write_text(json.dumps({'architecture': 'resnet', 'config': {}})); nrdepth.model.load_model(d)",
     "ValueError: m/model.json: cannot build"),
    ("load-path-int", "nrdepth.model.load_model(5)", "TypeError: model:"),
    ("train-workers-str", "from nrdepth.learning import TrainConfig; TrainConfig(workers='2')", "TypeError: workers:"),
    ("train-seed", "from nrdepth.learning import TrainConfig; TrainConfig(seed=-1)", "ValueError: seed:"),
    ("train-arch", "from nrdepth.learning import TrainConfig; TrainConfig(arch='resnet')", "ValueError: arch:"),
    ("train-loss", "from nrdepth.learning import TrainConfig; TrainConfig(loss='l2')", "ValueError: loss:"),
    ("train-schedule", "from nrdepth.learning import TrainConfig; TrainConfig(schedule='linear')", "ValueError: schedule:"),
    ("train-lr-nan", "from nrdepth.learning import TrainConfig; TrainConfig(lr=float('nan'))", "ValueError: lr:"),
    ("train-data-missing", "from nrdepth.learning import TrainConfig; TrainConfig(data='/no/such/data')", "ValueError: data:"),
    ("train-numpy-ints", "from nrdepth.learning import TrainConfig; c = TrainConfig(batch_size=np.int64(2), epochs=np.int32(1)); print(c.batch_size + c.epochs)", None),
    ("material-str", "nrdepth.Material(ambient='x')", "TypeError: material.ambient:"),
    ("light-kind", "nrdepth.Light(kind='spot')", "ValueError: light.kind:"),
    ("store-no-manifest", "from nrdepth.engine.dataset import ClipStore; ClipStore('.')", "ValueError: root:"),
    ("store-bad-manifest", "from nrdepth.engine.dataset import ClipStore; Path('d').mkdir(); Path('d/manifest.json').write_text('not json'); ClipStore('d')",
     "ValueError: d/manifest.json: not valid JSON"),
    ("store-empty-manifest", "from nrdepth.engine.dataset import ClipStore; Path('d').mkdir(); Path('d/manifest.json').write_text('{}'); ClipStore('d')",
     "ValueError: d/manifest.json: not an nrdepth dataset manifest"),
    ("store-float-index", "from nrdepth.engine.dataset import ClipStore; ClipStore(DATA)[1.5]", "TypeError: index:"),
    ("store-index-range", "from nrdepth.engine.dataset import ClipStore; ClipStore(DATA, 'test')[10**6]", "IndexError: clip"),
    ("store-zero-byte-shard",
     "import shutil; from nrdepth.engine.dataset import ClipStore; shutil.copytree(DATA, 'd'); Path('d/shard-00000.h5').write_bytes(b'')\n"
     "ClipStore('d')[0]", "ValueError: d/shard-00000.h5: not a readable shard"),
    ("store-numpy-index", "from nrdepth.engine.dataset import ClipStore; print(ClipStore(DATA)[np.int64(1)][0].shape)", None),
    ("dataset-seed-writes-nothing",
     f"from nrdepth.engine.dataset import write_dataset\ntry:\n    write_dataset('d', 4, seed=-1, config={TINY}, progress=False)\nfinally:\n    assert not Path('d').exists()",
     "ValueError: seed:"),
    ("dataset-numpy-clips", f"from nrdepth.engine.dataset import write_dataset; write_dataset('d', np.int64(4), config={TINY}, progress=False, shard_size=np.int64(2))", None),
    ("render-int-vertices",
     "nrdepth.render(np.zeros((3, 3), np.int32), np.array([[0, 1, 2]], np.uint32), np.zeros((3, 2), np.float32), np.ones((4, 4), np.float32), (8, 8), (-1, -1, 1, 1), [nrdepth.Light()], nrdepth.Material())",
     "TypeError: vertices:"),
    ("render-huge",
     "v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32)\n"
     "nrdepth.render(v, np.array([[0, 1, 2]], np.uint32), np.zeros((3, 2), np.float32), np.ones((4, 4), np.float32), 8192, (-1, -1, 1, 1), supersample=8)",
     "ValueError: size:"),
    ("raycast-nan",
     "nrdepth.raycast_depth(np.full((3, 3), np.nan, np.float32), np.array([[0, 1, 2]], np.uint32), (8, 8), (-1, -1, 1, 1))", "ValueError: vertices:"),
    ("save-into-cwd", "from nrdepth.io import save_reconstruction; save_reconstruction('.', np.zeros((2, 8, 8), np.uint8), np.zeros((2, 8, 8)), overwrite=True)",
     "ValueError: out: refusing"),
    ("save-ply-nan", "from nrdepth.io import save_reconstruction; save_reconstruction('o', np.zeros((2, 8, 8), np.uint8), np.zeros((2, 8, 8)), ply=True, ply_relief=float('nan'))",
     "ValueError: ply_relief:"),
    ("unet2p1d-width", "nrdepth.model.UNet2p1D(width=0)", "ValueError: width:"),
    ("build-model-name", "nrdepth.model.build_model('resnet')", "ValueError: architecture:"),
]

# (id, argv after `nrdepth`, message start on stderr after "nrdepth CMD: error: ")
CLI_CASES = [
    ("cli-out-cwd", ["reconstruct", "input.npy", "-o", ".", "--overwrite", "--model", "{model}"], "--out: refusing"),
    ("cli-out-holds-input", ["reconstruct", "out/input.npy", "-o", "out", "--overwrite", "--model", "{model}"], "--out: out contains the input"),
    ("cli-out-not-ours", ["reconstruct", "input.npy", "-o", "notes", "--overwrite", "--model", "{model}"], "--out: notes was not written by nrdepth"),
    ("cli-ply-nan", ["reconstruct", "input.npy", "-o", "o", "--ply", "--ply-relief", "nan", "--model", "{model}"], "--ply-relief:"),
    ("cli-coarse-weight", ["reconstruct", "input.npy", "-o", "o", "--alignment", "joint", "--coarse-weight", "0", "--model", "{model}"], "--coarse-weight: expected"),
    ("cli-temporal-weight", ["reconstruct", "input.npy", "-o", "o", "--temporal-weight", "-1", "--model", "{model}"], "--temporal-weight: expected"),
    ("cli-focal-tiny", ["reconstruct", "input.npy", "-o", "o", "--focal", "0.001", "--model", "{model}"], "--focal: f_x = 0.001 px sees 180.0°"),
    ("cli-focal-huge", ["reconstruct", "input.npy", "-o", "o", "--focal", "1e9", "--model", "{model}"], "--focal: f_x = 1e+09 px sees 1.8e-06° across the frame's 32 pixels; the sheet's shape needs perspective"),
    ("cli-sheet-tiny", ["reconstruct", "input.npy", "-o", "o", "--focal", "50", "--sheet", "0,0,1,1", "--model", "{model}"], "--sheet: expected room for at least 4 points"),
    ("cli-out-under-a-file", ["reconstruct", "input.npy", "-o", "notes/mine.txt/new", "--model", "{model}"], "--out: cannot make notes/mine.txt/new: "),
    ("cli-model-missing", ["reconstruct", "input.npy", "-o", "o", "--model", "/missing.safetensors"], "--model: /missing.safetensors not found"),
    ("cli-model-corrupt", ["reconstruct", "input.npy", "-o", "o", "--model", "bad"], "--model: bad/model.safetensors: not a readable"),
    ("cli-roi-negative", ["reconstruct", "input.npy", "-o", "o", "--roi", "-10,0,100,100", "--model", "{model}"], "--roi: expected x, y, width, height inside"),
    ("cli-float-255", ["reconstruct", "float255.npy", "-o", "o", "--model", "{model}"], "input: expected float frames in [0, 1]"),
    ("cli-generate-seed", ["generate", "ds", "--clips", "4", "--seed", "-1", "--quiet"], "seed:"),
    ("cli-train-seed", ["train", "run", "--seed", "-1", "--quiet", "--device", "cpu"], "seed:"),
    ("cli-evaluate-missing", ["evaluate", "/missing/run", "--clips", "1", "--device", "cpu"], "/missing/run: not found"),
    ("cli-train-empty-validation", ["train", "run", "--data", "{small_data}", "--quiet", "--device", "cpu", "--batch-size", "2", "--validation-clips", "1", "--base", "2"],
     "data: the validation split"),
]


@pytest.fixture(scope="module")
def assets(tmp_path_factory):
    import torch

    import nrdepth.model

    root = tmp_path_factory.mktemp("assets")
    torch.manual_seed(0)
    nrdepth.model.save_model(nrdepth.model.UNet3D(base=2), root / "model.safetensors")
    config = nrdepth.GeneratorConfig(frames=4, size=16, grid=16, texture_size=32)
    write_dataset(root / "data", 20, seed=1, config=config, shard_size=8, progress=False)
    write_dataset(root / "small_data", 6, seed=1, config=config, shard_size=8, progress=False)  # validation split: 0 clips
    return root


class Case:
    """What a case's process did: its exit status and what it wrote."""

    def __init__(self, returncode: int, stdout: str, stderr: str) -> None:
        self.returncode, self.stdout, self.stderr = returncode, stdout, stderr


def _case_process(code, argv, cwd, env, out, err):  # in the forked process
    import torch

    os.chdir(cwd)
    os.environ.update(env)
    torch.set_num_threads(1)
    for fd, path in ((1, out), (2, err)):
        os.dup2(os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC), fd)
    try:
        if argv is None:
            exec(compile(PRELUDE + code, "<case>", "exec"), {"__name__": "__case__"})
            status = 0
        else:
            from nrdepth.cli import main

            status = main(argv)  # as `python -m nrdepth` runs it: sys.exit(main())
    except SystemExit as e:
        status = e.code if isinstance(e.code, int) else (0 if e.code is None else 1)
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(status)


def in_its_own_process(*, code: str = None, argv: list = None, cwd: Path, env: dict) -> Case:
    """``code`` (after PRELUDE) or the CLI's ``argv`` in a process forked from the server, at most 60 s."""
    import multiprocessing
    import tempfile

    with tempfile.TemporaryDirectory() as streams:  # outside cwd: a case must write nothing there
        out, err = Path(streams) / "stdout", Path(streams) / "stderr"
        process = multiprocessing.get_context("forkserver").Process(target=_case_process, args=(code, argv, str(cwd), env, str(out), str(err)))
        process.start()
        process.join(60)
        if process.is_alive():
            process.kill()
            process.join()
            raise AssertionError("the case hung for 60 s")
        return Case(process.exitcode, *(path.read_text() if path.exists() else "" for path in (out, err)))


@pytest.fixture(scope="module", autouse=True)
def case_server():
    """The server the cases fork from, with nrdepth, its CLI and torch imported."""
    import multiprocessing

    multiprocessing.set_forkserver_preload(["numpy", "torch", "nrdepth", "nrdepth.model", "nrdepth.cli"])
    yield


def run_case(code: str, cwd: Path, assets: Path) -> Case:
    body = "try:\n" + textwrap.indent(code, "    ") + "\nexcept BaseException as e:\n    print(f'RAISED {type(e).__name__}: {e}')\nelse:\n    print('OK')\n"
    env = dict(CASE_MODEL=str(assets / "model.safetensors"), CASE_DATA=str(assets / "data"))
    return in_its_own_process(code=body, cwd=cwd, env=env)


@pytest.mark.parametrize("code, expected", [c[1:] for c in API_CASES], ids=[c[0] for c in API_CASES])
def test_api_bad_input_is_named(code, expected, tmp_path, assets):
    import re

    result = run_case(code, tmp_path, assets)
    assert result.returncode == 0, f"the process died ({result.returncode}): {result.stderr[-2000:]}"
    last = result.stdout.strip().splitlines()[-1]
    if expected is None:
        assert last == "OK", last
    else:
        assert re.match("RAISED " + expected, last), last


@pytest.mark.parametrize("argv, expected", [c[1:] for c in CLI_CASES], ids=[c[0] for c in CLI_CASES])
def test_cli_bad_input_is_one_line_and_exit_2(argv, expected, tmp_path, assets):
    np.save(tmp_path / "input.npy", np.zeros((4, 32, 32), np.uint8))
    np.save(tmp_path / "float255.npy", np.full((4, 32, 32), 200.0, np.float32))
    (tmp_path / "out").mkdir()
    np.save(tmp_path / "out" / "input.npy", np.zeros((4, 32, 32), np.uint8))
    (tmp_path / "notes").mkdir()
    (tmp_path / "notes" / "mine.txt").write_text("keep me")
    (tmp_path / "bad").mkdir()
    (tmp_path / "bad" / "model.safetensors").write_bytes(b"\0" * 64)
    (tmp_path / "bad" / "model.json").write_text(json.dumps({"architecture": "unet3d", "config": {"base": 2}}))
    before = sorted(str(p.relative_to(tmp_path)) for p in tmp_path.rglob("*"))
    argv = [a.format(model=assets / "model.safetensors", small_data=assets / "small_data") for a in argv]
    result = in_its_own_process(argv=argv, cwd=tmp_path, env={})
    assert result.returncode == 2, (result.returncode, result.stderr[-2000:])
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"nrdepth {argv[0]}: error: {expected}"), result.stderr
    after = sorted(str(p.relative_to(tmp_path)) for p in tmp_path.rglob("*"))
    assert after == before, "a refused command wrote or deleted files"


def test_ctrl_c_stops_a_hopeless_generation_quickly(tmp_path):
    code = textwrap.dedent("""
        import os, signal, threading, time
        import nrdepth
        # As in an interactive shell (a background job starts with SIGINT ignored).
        signal.signal(signal.SIGINT, signal.default_int_handler)
        config = nrdepth.GeneratorConfig(window_width=(2, 2), window_offset=(1, 1), max_redraws=1_000_000)
        threading.Timer(1.0, lambda: os.kill(os.getpid(), signal.SIGINT)).start()
        start = time.time()
        try:
            nrdepth.generate_clips(4, config=config)
        except KeyboardInterrupt:
            print(f"interrupted after {time.time() - start:.1f} s")
    """)
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr[-2000:]
    assert result.stdout.startswith("interrupted after"), result.stdout
    assert float(result.stdout.split()[2]) < 5.0


def test_scale_does_not_change_mae_sn():
    rng = np.random.default_rng(0)
    gt = rng.normal(size=(3, 12, 12)).cumsum(axis=2)
    pred = gt + rng.normal(size=gt.shape)
    reference = nrdepth.mae_sn(pred, gt)
    for scale in (1e-300, 1e-150, 1e150, 1e300):
        assert nrdepth.mae_sn(pred, scale * gt) == pytest.approx(reference, rel=1e-9)
        assert nrdepth.mae_sn(scale * pred, gt) == pytest.approx(reference, rel=1e-9)
    assert nrdepth.mae_sn(1e-300 * pred, gt, "first") == pytest.approx(nrdepth.mae_sn(pred, gt, "first"), rel=1e-9)


def test_reliability_covers_sixty_cases():
    assert len(API_CASES) + len(CLI_CASES) + 2 >= 60
