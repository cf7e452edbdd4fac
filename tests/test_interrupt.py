"""Ctrl-C during ``nrdepth reconstruct``, in real subprocesses: at every
stage the run stops, exits 130 and leaves nothing behind (no output folder,
no ``.partial``), also when a library swallows the first KeyboardInterrupt;
a rerun then succeeds."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest
import torch

import nrdepth
from nrdepth.model import save_model

# Runs the CLI with SIGINT sent to itself as TARGET (module:attribute) is first entered.
# With SWALLOW the first KeyboardInterrupt is caught inside the stage, as a library may do.
HOOKED_CLI = textwrap.dedent("""
    import importlib, os, signal, sys, time
    signal.signal(signal.SIGINT, signal.default_int_handler)  # as in a terminal: a background job starts with SIGINT ignored
    target, swallow = sys.argv[1], sys.argv[2] == "swallow"
    module_name, _, attribute = target.rpartition(":")
    owner = importlib.import_module(module_name)
    *path, name = attribute.split(".")
    for part in path:
        owner = getattr(owner, part)
    original = getattr(owner, name)

    def hooked(*args, **kwargs):
        if not hooked.fired:
            hooked.fired = True
            print(f"entered {target}", file=sys.stderr, flush=True)
            if swallow:
                try:
                    os.kill(os.getpid(), signal.SIGINT)
                    time.sleep(1.0)
                except KeyboardInterrupt:
                    pass
            else:
                os.kill(os.getpid(), signal.SIGINT)  # handled before the stage's first line: on a loaded machine a timer may miss it
        return original(*args, **kwargs)

    hooked.fired = False
    setattr(owner, name, hooked)
    from nrdepth.cli import main
    sys.exit(main(sys.argv[3:]))
""")

STAGES = [
    "nrdepth.io.decode:VideoSource.chunks",  # decoding
    "nrdepth.reconstruct.pipeline:coarse_half",  # the coarse pass
    "nrdepth.reconstruct.stitching:field_frames",  # the fine pass
    "nrdepth.reconstruct.stitching:make_stitcher",  # stitching
    "nrdepth.reconstruct.api:sheet_depth",  # the sheet's stage (with a focal length)
    "nrdepth.reconstruct.api:units_of",  # units
    "nrdepth.io.writers:Mp4Writer.write",  # the MP4s
    "nrdepth.io.folder:write_page",  # the 3-D page
]


@pytest.fixture(scope="module")
def job(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("interrupt")
    torch.manual_seed(0)
    save_model(nrdepth.model.UNet3D(base=2), root / "model.safetensors")
    y, x = np.mgrid[0:96, 0:96]
    frames = [128 + 90 * np.sin(0.3 * (x - 2 * k)) * np.cos(0.2 * y + 0.05 * k) for k in range(24)]
    np.save(root / "video.npy", np.rint(np.stack(frames)).astype(np.uint8))
    return root


def reconstruct_argv(root: Path, out: Path, *extra: str) -> list:
    return ["reconstruct", str(root / "video.npy"), "-o", str(out), "--model", str(root / "model.safetensors"), *extra]


def leftovers(parent: Path) -> list:
    return sorted(p.name for p in parent.iterdir() if p.name.startswith((".out", "out")))


def run_hooked(root: Path, target: str, how: str, argv: list) -> subprocess.CompletedProcess:
    env = dict(os.environ, OMP_NUM_THREADS="1")
    return subprocess.run([sys.executable, "-c", HOOKED_CLI, target, how, *argv], env=env, capture_output=True, text=True, timeout=120)


@pytest.mark.parametrize("how", ["signal", "swallow"])
@pytest.mark.parametrize("target", STAGES, ids=[s.rpartition(":")[2] for s in STAGES])
def test_ctrl_c_at_every_stage_exits_130_and_leaves_nothing(job, tmp_path, target, how):
    if how == "swallow" and not target.endswith(("chunks", "Mp4Writer.write")):
        pytest.skip("a swallowed interrupt is caught at the next stage's check: decoding's and the MP4s' are enough")
    extra = ("--focal", "120") if "sheet" in target else ()
    result = run_hooked(job, target, how, reconstruct_argv(job, tmp_path / "out", *extra))
    assert f"entered {target}" in result.stderr, result.stderr[-2000:]
    assert result.returncode == 130, (result.returncode, result.stderr[-2000:])
    assert result.stderr.strip().splitlines()[-1] == "nrdepth reconstruct: interrupted", result.stderr[-2000:]
    assert leftovers(tmp_path) == []


def test_ctrl_c_from_outside_mid_run_is_honoured_and_a_rerun_succeeds(job, tmp_path):
    """SIGINT from another process, as a terminal sends it, once the progress bar shows."""
    env = dict(os.environ, OMP_NUM_THREADS="1")
    argv = [sys.executable, "-m", "nrdepth", *reconstruct_argv(job, tmp_path / "out")]
    # As from a terminal: a test run started in the background (nohup, CI) hands its children SIGINT ignored.
    process = subprocess.Popen(argv, env=env, stderr=subprocess.PIPE, text=True, preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    seen = ""
    while "frames:" not in seen:
        piece = process.stderr.read(1)
        assert piece, f"the run ended before its bar showed: {seen[-2000:]}"
        seen += piece
    sent = time.perf_counter()
    process.send_signal(signal.SIGINT)
    rest = process.communicate(timeout=60)[1]
    assert process.returncode == 130 and rest.strip().endswith("nrdepth reconstruct: interrupted"), (process.returncode, rest[-2000:])
    assert time.perf_counter() - sent < 10.0  # a second or two here; a loaded machine takes longer
    assert leftovers(tmp_path) == []
    rerun = subprocess.run(argv, env=env, capture_output=True, text=True, timeout=120)
    assert rerun.returncode == 0, rerun.stderr[-2000:]
    assert leftovers(tmp_path) == ["out"] and (tmp_path / "out" / "depth.npz").is_file()


def test_ctrl_c_after_the_output_is_in_place_keeps_it_and_exits_0(job, tmp_path):
    """Exit 130 means nothing was written, 0 that everything was: never 130 beside a finished folder."""
    result = run_hooked(job, "nrdepth.cli.job:npz_header", "signal", reconstruct_argv(job, tmp_path / "out"))
    assert "entered nrdepth.cli.job:npz_header" in result.stderr
    assert result.returncode == 0, (result.returncode, result.stderr[-2000:])
    assert result.stdout.splitlines()[-1].startswith("wrote ") and leftovers(tmp_path) == ["out"]  # after the sheet stage's line
    assert nrdepth.io.npz_header(tmp_path / "out" / "depth.npz", "depth")[0] == (24, 96, 96)
