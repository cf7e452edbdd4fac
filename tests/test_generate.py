"""Clip generation and datasets: no background, the drawn noise, bit-identical
reproducibility (threads, batch split, fork, interrupted and resumed runs)."""

import hashlib
import json
import multiprocessing
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest

import nrdepth
from nrdepth import GeneratorConfig
from nrdepth.engine.dataset import ClipStore, write_dataset

SMALL = GeneratorConfig(frames=4, size=24, grid=24, texture_size=64)


def test_clips_have_the_documented_shapes_and_no_background():
    clips = nrdepth.generate_clips(6, seed=1, config=SMALL)
    assert clips.video.shape == clips.depth.shape == (6, 4, 24, 24)
    assert clips.video.dtype == np.uint8 and clips.depth.dtype == np.float32
    assert np.isfinite(clips.depth).all()
    assert len(clips.params) == 6 and all(p["redraws"] >= 0 for p in clips.params)
    # The depth really is the surface's: near the camera plane minus a small relief.
    assert (np.abs(clips.depth - nrdepth.CAMERA_Z) < 1.0).all()
    assert clips.video.std() > 5


def test_gouraud_clips_share_everything_but_the_shading():
    phong = nrdepth.generate_clips(2, seed=8, config=SMALL)
    gouraud = nrdepth.generate_clips(2, seed=8, config=SMALL.replace(shading="gouraud"))
    np.testing.assert_array_equal(phong.depth, gouraud.depth)
    assert phong.params == gouraud.params
    difference = np.abs(phong.video.astype(int) - gouraud.video.astype(int))
    assert 0 < difference.mean() < 3


def test_a_too_large_window_is_redrawn_and_counted():
    config = SMALL.replace(window_width=(1.7, 1.7), max_redraws=5000)
    clips = nrdepth.generate_clips(3, seed=2, config=config)
    assert np.isfinite(clips.depth).all()
    assert sum(p["redraws"] for p in clips.params) > 0
    with pytest.raises(ValueError, match="background"):
        nrdepth.generate_clips(1, seed=2, config=SMALL.replace(window_width=(2.0, 2.0), max_redraws=2))


def test_noise_has_the_drawn_variance():
    # Only noise_std changes between the two configs: every other draw is the same.
    clean = nrdepth.generate_clips(4, seed=3, config=SMALL.replace(noise_std=(0.0, 0.0)))
    noisy = nrdepth.generate_clips(4, seed=3, config=SMALL.replace(noise_std=(0.04, 0.04)))
    np.testing.assert_array_equal(clean.depth, noisy.depth)
    diff = noisy.video.astype(float) - clean.video.astype(float)
    unclipped = (clean.video > 40) & (clean.video < 215)
    sigma = diff[unclipped].std() / 255.0
    assert sigma == pytest.approx(0.04, rel=0.08)
    assert all(p["noise_std"] == 0.04 for p in noisy.params)


def test_camera_blur_and_response_change_only_the_frames():
    # Drawn after everything else: the surface, lights and depth stay those of the plain config.
    plain = nrdepth.generate_clips(3, seed=6, config=SMALL.replace(noise_std=(0.0, 0.0)))
    camera = nrdepth.generate_clips(3, seed=6, config=SMALL.replace(noise_std=(0.0, 0.0), blur=(1.5, 1.5), gamma=(0.5, 0.5)))
    np.testing.assert_array_equal(plain.depth, camera.depth)
    assert [{k: v for k, v in p.items() if k not in ("blur", "gamma")} for p in camera.params] == [
        {k: v for k, v in p.items() if k not in ("blur", "gamma")} for p in plain.params]
    assert all(p["blur"] == 1.5 and p["gamma"] == 0.5 for p in camera.params)
    assert all(p["blur"] == 0.0 and p["gamma"] == 1.0 for p in plain.params)
    # Blur removes fine detail; gamma 0.5 brightens (v ↦ √v).
    detail = lambda v: np.abs(np.diff(v.astype(float), axis=-1)).mean()
    assert detail(camera.video) < 0.6 * detail(plain.video)
    assert camera.video.mean() > plain.video.mean() + 20
    with pytest.raises(ValueError, match="config.gamma"):
        SMALL.replace(gamma=(0.0, 1.0))


def test_sheets_bend_the_patch_and_leave_everything_else_drawn_as_it_was():
    # The sheet is drawn after everything else: lights, material, texture and noise stay the plain clip's.
    plain = nrdepth.generate_clips(6, seed=3, config=SMALL)
    sheets = nrdepth.generate_clips(6, seed=3, config=SMALL.replace(sheet_probability=1.0))
    assert all(p["sheet"] is None for p in plain.params)
    assert all(p["sheet"] is not None and p["sheet"]["terms"] for p in sheets.params)
    first_tries = [(a, b) for a, b in zip(plain.params, sheets.params) if a["redraws"] == b["redraws"] == 0]
    assert len(first_tries) >= 3
    for a, b in first_tries:
        assert {k: v for k, v in a.items() if k != "sheet"} == {k: v for k, v in b.items() if k != "sheet"}
    assert np.isfinite(sheets.depth).all() and not np.array_equal(sheets.depth, plain.depth)
    # Bent sheets have depth beyond a plane's: the residual of each frame's best plane fit.
    def off_plane(depth):
        t, h, w = depth.shape[1:]
        y, x = np.mgrid[0:h, 0:w]
        a = np.stack([np.ones(h * w), x.ravel(), y.ravel()], 1)
        frames = depth.reshape(-1, h * w).T
        return np.abs(frames - a @ np.linalg.lstsq(a, frames, rcond=None)[0]).mean()
    flat = SMALL.replace(surface=nrdepth.SurfaceConfig(intensity=(0.0, 0.0)))
    assert off_plane(nrdepth.generate_clips(6, seed=3, config=flat.replace(sheet_probability=1.0)).depth) > 20 * off_plane(
        nrdepth.generate_clips(6, seed=3, config=flat).depth) + 1e-3
    half = nrdepth.generate_clips(8, seed=3, config=SMALL.replace(sheet_probability=0.5, texture_families=("print",)), start=1)
    assert 0 < sum(p["sheet"] is not None for p in half.params) < 8
    assert all(p["texture"]["family"] == "print" for p in half.params)


def test_sheet_phases_bend_a_long_clip_several_ways():
    # Each phase draws new knots after everything else: the first phase's knots are the one-phase sheet's.
    config = SMALL.replace(frames=9, sheet_probability=1.0)
    one = nrdepth.generate_clips(4, seed=5, config=config)
    four = nrdepth.generate_clips(4, seed=5, config=config.replace(sheet_phases=4))
    for a, b in zip(one.params, four.params):
        assert len(b["sheet"]["axis"]) == 5 and b["sheet"]["axis"][:2] == a["sheet"]["axis"]
        assert all(len(t["angle"]) == len(t["centre"]) == 5 and t["angle"][:2] == s["angle"] for s, t in zip(a["sheet"]["terms"], b["sheet"]["terms"]))
    assert not np.array_equal(one.depth, four.depth)
    with pytest.raises(ValueError, match="sheet_phases"):
        nrdepth.GeneratorConfig(sheet_phases=0)
    # A flat start zeroes the first knot's turns and draws everything else as it was (in a draw both keep).
    flat = nrdepth.generate_clips(4, seed=5, config=config.replace(sheet_phases=4, sheet_flat_start=True))
    kept = [(a, b) for a, b in zip(four.params, flat.params) if a["redraws"] == b["redraws"]]
    assert len(kept) >= 2
    for a, b in kept:
        assert all(t["angle"][0] == 0 and t["angle"][1:] == s["angle"][1:] for s, t in zip(a["sheet"]["terms"], b["sheet"]["terms"]))
    with pytest.raises(TypeError, match="sheet_flat_start"):
        nrdepth.GeneratorConfig(sheet_flat_start=1)


@pytest.mark.parametrize("camera", [{}, {"sheet_probability": 1.0, "camera_fov": (0.7, 1.4), "crop_share": (1.0, 1.0)},
                                    {"camera_fov": (0.6, 1.3), "crop_share": (0.3, 1.0), "backdrop_probability": 1.0}],
                         ids=["orthographic", "pinhole sheets", "pinhole crops over backdrops"])
def test_the_meshes_project_where_the_depth_shows_them(camera):
    from scipy.ndimage import map_coordinates

    config = SMALL.replace(size=48, grid=40, **camera)
    clips = nrdepth.generate_clips(3, seed=8, config=config, vertices=True)
    plain = nrdepth.generate_clips(3, seed=8, config=config)
    assert plain.vertices is None and clips.vertices.shape == (3, 4, 40, 40, 3)
    assert np.array_equal(clips.video, plain.video) and clips.params == plain.params
    for vertices, depth, params in zip(clips.vertices, clips.depth, clips.params):
        points = nrdepth.image_points(vertices, params, config.size)
        errors, mirrored = [], []
        for frame, seen in zip(depth.astype(np.float64), points.reshape(4, -1, 3)):
            seen = seen[(seen[:, :2] > 1).all(axis=1) & (seen[:, :2] < config.size - 2).all(axis=1)]
            for error, rows in ((errors, seen[:, 1]), (mirrored, config.size - 1 - seen[:, 1])):
                at = map_coordinates(frame, [rows, seen[:, 0]], order=1)
                error += list(np.abs(at - seen[:, 2])[np.isfinite(at)])
        # The depth map, read bilinearly where a vertex projects, is the vertex's depth (up to the
        # mesh's curvature within a pixel); read with the rows mirrored, it is not.
        assert np.median(errors) < 5e-4 * np.nanmedian(depth) < np.median(mirrored) / 3
    with pytest.raises(TypeError, match="^vertices:"):
        nrdepth.generate_clips(1, config=SMALL, vertices=1)
    with pytest.raises(ValueError, match="^vertices:"):
        nrdepth.image_points(np.zeros((4, 2)), clips.params[0], 48)
    with pytest.raises(ValueError, match="^params:"):
        nrdepth.image_points(np.zeros((4, 3)), {"window": (0, 1)}, 48)


def test_backdrops_show_the_border_over_a_background_and_mask_the_depth_off_the_sheet():
    # Drawn after the sheet: everything but the window stays the plain clip's.
    plain = nrdepth.generate_clips(6, seed=3, config=SMALL)
    config = SMALL.replace(backdrop_probability=1.0)
    shown = nrdepth.generate_clips(6, seed=3, config=config)
    assert all(p["backdrop"] is None for p in plain.params)
    first_tries = [(a, b) for a, b in zip(plain.params, shown.params) if a["redraws"] == b["redraws"] == 0]
    assert len(first_tries) >= 3
    for a, b in first_tries:
        assert {k: v for k, v in a.items() if k not in ("backdrop", "window")} == {k: v for k, v in b.items() if k not in ("backdrop", "window")}
    widths = nrdepth.engine.generate.window_widths(shown.params)
    assert ((widths >= config.backdrop_window_width[0] - 1e-6) & (widths <= config.backdrop_window_width[1] + 1e-6)).all()
    on_sheet = np.isfinite(shown.depth).mean(axis=(2, 3))
    assert (on_sheet >= config.backdrop_min_cover).all() and on_sheet.min() < 1
    assert np.isnan(shown.depth).any() and np.isfinite(plain.depth).all()
    with pytest.raises(ValueError, match="config.backdrop_min_cover"):
        SMALL.replace(backdrop_min_cover=2.0)


def test_a_perspective_camera_is_drawn_last_and_shows_the_motion_along_its_axis():
    # Drawn after everything else: a clip drawn at its first try keeps every other parameter.
    plain = nrdepth.generate_clips(6, seed=3, config=SMALL)
    config = SMALL.replace(camera_fov=(0.7, 1.2), crop_share=(0.2, 1.0))
    seen = nrdepth.generate_clips(6, seed=3, config=config)
    assert all(p["pinhole"] is None for p in plain.params)
    first_tries = [(a, b) for a, b in zip(plain.params, seen.params) if a["redraws"] == b["redraws"] == 0]
    assert len(first_tries) >= 3
    for a, b in first_tries:
        assert {k: v for k, v in a.items() if k != "pinhole"} == {k: v for k, v in b.items() if k != "pinhole"}
    for p, depth in zip(seen.params, seen.depth):
        x0, y0, x1, y1 = p["window"]
        # camera_z = frame width / (2 tan(fov / 2)) and window = share · frame width, so
        # window / (2 camera_z) = share · tan(fov / 2), within the drawn ranges' bounds.
        spread = (x1 - x0) / (2 * p["pinhole"]["camera_z"])
        lo, hi = config.crop_share[0] * np.tan(config.camera_fov[0] / 2), config.crop_share[1] * np.tan(config.camera_fov[1] / 2)
        assert lo - 1e-5 <= spread <= hi + 1e-5, (spread, lo, hi)
        # The pinhole lies over the frame, which holds the window: at most half a frame less half the window off its centre.
        frame = (x1 - x0) / config.crop_share[0]
        assert np.abs(np.array(p["pinhole"]["xy"]) - [(x0 + x1) / 2, (y0 + y1) / 2]).max() <= (frame - (x1 - x0)) / 2 + 1e-5
        # The target keeps the motion along the axis, which the image shows.
        assert nrdepth.observable_depth(depth, p) is depth
        assert np.isfinite(depth).all() and (depth > p["pinhole"]["camera_z"] / 2).all()
    assert not np.array_equal(seen.video, plain.video)


def test_a_share_of_perspective_clips_are_those_every_clip_through_the_pinhole_would_be():
    config = SMALL.replace(camera_fov=(0.7, 1.2), crop_share=(0.2, 1.0))
    plain, every = (nrdepth.generate_clips(12, seed=8, config=c) for c in (SMALL, config))
    some = nrdepth.generate_clips(12, seed=8, config=config.replace(camera_probability=0.5))
    seen = 0
    for k, p in enumerate(some.params):
        # A redraw after the pinhole's draw moves the stream on; the first tries must match exactly.
        if p["redraws"] or every.params[k]["redraws"] or plain.params[k]["redraws"]:
            continue
        same = every if p["pinhole"] is not None else plain
        seen += p["pinhole"] is not None
        assert p == same.params[k]
        assert some.video[k].tobytes() == same.video[k].tobytes()
        assert some.depth[k].tobytes() == same.depth[k].tobytes()
    assert 0 < seen < 12
    assert all(p["pinhole"] is None for p in nrdepth.generate_clips(4, seed=8, config=config.replace(camera_probability=0.0)).params)


def test_clip_i_depends_only_on_config_seed_and_i():
    whole = nrdepth.generate_clips(6, seed=4, config=SMALL)
    part = nrdepth.generate_clips(3, seed=4, config=SMALL, start=2)
    assert whole.video[2:5].tobytes() == part.video.tobytes()
    assert whole.depth[2:5].tobytes() == part.depth.tobytes()
    assert whole.params[2:5] == part.params
    other = nrdepth.generate_clips(1, seed=5, config=SMALL)
    assert other.video.tobytes() != whole.video[:1].tobytes()


_DIGEST = """
import hashlib, nrdepth
config = nrdepth.GeneratorConfig(frames=4, size=32, grid=32, texture_size=64)
c = nrdepth.generate_clips(8, seed=7, config=config)
s = nrdepth.generate_clips(8, seed=7, config=config.replace(sheet_probability=1.0, backdrop_probability=0.5, texture_families=("print", "weave")))
p = nrdepth.generate_clips(8, seed=7, config=config.replace(camera_fov=(0.5, 1.2), crop_share=(0.1, 1.0), backdrop_probability=0.5))
print(hashlib.sha256(c.video.tobytes() + c.depth.tobytes() + s.video.tobytes() + s.depth.tobytes() + p.video.tobytes() + p.depth.tobytes()).hexdigest())
"""


def test_same_bytes_with_one_and_two_threads():
    digests = set()
    for threads in ("1", "2"):
        env = dict(os.environ, RAYON_NUM_THREADS=threads)
        digests.add(subprocess.run([sys.executable, "-c", _DIGEST], env=env, capture_output=True, text=True, check=True).stdout)
    assert len(digests) == 1


def _child(queue):
    clips = nrdepth.generate_clips(4, seed=9, config=SMALL)
    queue.put(hashlib.sha256(clips.video.tobytes()).hexdigest())


def test_generation_works_in_a_forked_child_after_the_parent_used_threads():
    parent = nrdepth.generate_clips(4, seed=9, config=SMALL)  # starts the parent's thread pool
    ctx = multiprocessing.get_context("fork")
    queue = ctx.Queue()
    child = ctx.Process(target=_child, args=(queue,))
    child.start()
    child.join(timeout=60)
    alive = child.is_alive()
    if alive:
        child.kill()
    assert not alive, "generation hung in a forked child"
    assert queue.get(timeout=5) == hashlib.sha256(parent.video.tobytes()).hexdigest()


def test_textures_from_a_folder(tmp_path):
    from nrdepth.engine.preview import save_png

    for k in range(2):
        rng = np.random.default_rng(k)
        save_png(tmp_path / f"t{k}.png", rng.integers(0, 256, (40, 50, 3), dtype=np.uint8))
    (tmp_path / "notes.txt").write_text("not an image")
    config = SMALL.replace(textures=str(tmp_path))
    clips = nrdepth.generate_clips(3, seed=1, config=config)
    assert all(p["texture"]["image"].endswith(".png") for p in clips.params)
    (tmp_path / "broken.png").write_bytes(b"\x89PNG not really")
    with pytest.raises(ValueError, match="textures: cannot read image .*broken.png"):
        nrdepth.generate_clips(1, config=SMALL.replace(textures=str(tmp_path)))
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(ValueError, match="textures: no PNG or JPEG"):
        nrdepth.generate_clips(1, config=SMALL.replace(textures=str(empty)))


@pytest.mark.parametrize(
    "changes, name",
    [
        ({"size": 0}, "config.size"),
        ({"frames": -1}, "config.frames"),
        ({"supersample": 9}, "config.supersample"),
        ({"window_width": (0.5, float("nan"))}, "config.window_width"),
        ({"light_count": (3, 1)}, "config.light_count"),
        ({"texture_families": ("velvet",)}, "config.texture_families"),
        ({"shading": "flat"}, "config.shading"),
        ({"sheet_probability": 1.5}, "config.sheet_probability"),
        ({"sheet_bends": (2, 1)}, "config.sheet_bends"),
        ({"sheet_bends": (-1, 1)}, "config.sheet_bends"),
        ({"sheet_fold_width": (0.0, 0.1)}, "config.sheet_fold_width"),
        ({"textures": "/no/such/folder"}, "config.textures"),
        ({"camera_fov": (0.0, 3.0)}, "config.camera_fov"),
        ({"crop_share": (0.0, 1.0)}, "config.crop_share"),
        ({"camera_probability": -0.1}, "config.camera_probability"),
    ],
)
def test_bad_config_is_named(changes, name):
    with pytest.raises(ValueError) as info:
        SMALL.replace(**changes)
    assert str(info.value).startswith(name), str(info.value)


def test_bad_generate_arguments():
    with pytest.raises(ValueError, match="^n:"):
        nrdepth.generate_clips(-1)
    with pytest.raises(TypeError, match="^config:"):
        nrdepth.generate_clips(1, config={"frames": 4})


# ------------------------------------------------------------------ datasets


def shard_contents(root):
    out = {}
    for path in sorted(Path(root).glob("shard-*.h5")):
        with h5py.File(path, "r") as f:
            out[path.name] = (f["video"][:].tobytes(), f["depth"][:].tobytes(), list(f["params"].asstr()[:]))
    return out


def test_dataset_split_and_random_access_match_the_generator(tmp_path):
    write_dataset(tmp_path, 20, seed=6, config=SMALL, shard_size=7, progress=False)
    manifest = json.loads((tmp_path / "manifest.json").read_text())
    assert manifest["split"] == {"train": [0, 16], "validation": [16, 18], "test": [18, 20]}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["manifest.json", "shard-00000.h5", "shard-00001.h5", "shard-00002.h5"]
    test = ClipStore(tmp_path, "test")
    assert len(test) == 2 and len(ClipStore(tmp_path, "train")) == 16
    video, depth, params = test[1]
    ref = nrdepth.generate_clips(1, seed=6, config=SMALL, start=19)
    np.testing.assert_array_equal(video, ref.video[0])
    np.testing.assert_array_equal(depth, ref.depth[0])
    assert params == json.loads(json.dumps(ref.params[0]))
    assert test.config == SMALL
    with pytest.raises(IndexError):
        test[2]


def test_sharded_writers_and_a_killed_then_resumed_run_give_the_same_bytes(tmp_path):
    args = ["--clips", "48", "--shard-size", "8", "--seed", "3", "--frames", "4", "--size", "32", "--grid", "32", "--quiet"]
    reference = tmp_path / "reference"
    subprocess.run([sys.executable, "-m", "nrdepth", "generate", str(reference), *args], check=True, capture_output=True)

    # Two writers, each taking half of the shards.
    split = tmp_path / "split"
    for i in range(2):
        write_dataset(split, 48, seed=3, config=GeneratorConfig(frames=4, size=32, grid=32), shard_size=8, shard=(i, 2), progress=False)
    assert shard_contents(split) == shard_contents(reference)

    # A run killed once its first shard is complete, then resumed.
    resumed = tmp_path / "resumed"
    proc = subprocess.Popen([sys.executable, "-m", "nrdepth", "generate", str(resumed), *args], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.time() + 60
    while not (resumed / "shard-00000.h5").exists() and time.time() < deadline:
        time.sleep(0.01)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    finished_before_kill = len(list(resumed.glob("shard-*.h5")))
    assert finished_before_kill < 6, "the run finished before it could be interrupted"
    subprocess.run([sys.executable, "-m", "nrdepth", "generate", str(resumed), *args], check=True, capture_output=True)
    assert not list(resumed.glob("*.partial"))
    assert shard_contents(resumed) == shard_contents(reference)
    for name in shard_contents(reference):
        assert (resumed / name).read_bytes() == (reference / name).read_bytes()


def test_a_folder_of_another_run_is_refused(tmp_path):
    write_dataset(tmp_path, 4, seed=1, config=SMALL, shard_size=4, progress=False)
    with pytest.raises(ValueError, match="different dataset"):
        write_dataset(tmp_path, 4, seed=2, config=SMALL, shard_size=4, progress=False)
    with pytest.raises(ValueError, match="different dataset"):
        write_dataset(tmp_path, 4, seed=1, config=SMALL.replace(blur=(0.0, 1.0)), shard_size=4, progress=False)


def test_a_folder_written_before_the_camera_fields_is_the_same_run(tmp_path):
    # Fields added to GeneratorConfig later take their defaults when an older manifest is read.
    write_dataset(tmp_path, 4, seed=1, config=SMALL, shard_size=2, progress=False)
    manifest = json.loads((tmp_path / "manifest.json").read_text())
    for name in ("blur", "gamma", "sheet_probability", "sheet_relief"):
        del manifest["config"][name]
    (tmp_path / "manifest.json").write_text(json.dumps(manifest))
    (tmp_path / "shard-00001.h5").unlink()
    write_dataset(tmp_path, 4, seed=1, config=SMALL, shard_size=2, progress=False)
    assert ClipStore(tmp_path)[3][0].tobytes() == nrdepth.generate_clips(1, seed=1, config=SMALL, start=3).video[0].tobytes()
