"""``nrdepth.reconstruct_many`` and ``nrdepth reconstruct-many``: a batch of
small videos, one corrupt and one too short, through the local pool and a
Ray cluster started here; each good video's folder byte-identical to a
single ``reconstruct_file`` run, the bad ones reported with their errors,
and a batch killed in the middle resumed by redoing only what was not
finished."""

from __future__ import annotations

import csv
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import List

import numpy as np
import pytest
import torch

import nrdepth
from nrdepth.cli import main
from nrdepth.model import save_model
from nrdepth.reconstruct.batch import SUMMARY, list_videos


def drifting(t: int, seed: int, h: int = 48, w: int = 64) -> np.ndarray:
    y, x = np.mgrid[0:h, 0:w]
    phase = np.random.default_rng(seed).random(2) * 6
    return np.rint(np.stack([128 + 90 * np.sin(0.3 * (x - 2 * k) + phase[0]) * np.cos(0.2 * y + phase[1]) for k in range(t)])).astype(np.uint8)


@pytest.fixture(scope="module")
def batch(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("batch")
    torch.manual_seed(0)
    save_model(nrdepth.model.UNet3D(base=2), root / "model.safetensors")
    videos = root / "videos"
    videos.mkdir()
    np.save(videos / "a.npy", drifting(12, 0))
    np.save(videos / "b.npy", drifting(10, 1))
    nrdepth.io.write_mp4(videos / "c.mp4", np.repeat(drifting(8, 2)[..., None], 3, axis=-1))
    (videos / "corrupt.mp4").write_bytes(b"\x00\x00\x00\x18ftypmp42" + bytes(range(256)) * 8)
    np.save(videos / "short.npy", np.zeros((0, 48, 64), np.uint8))
    return root


GOOD, BAD = ["a", "b", "c"], {"corrupt": "ValueError: input: cannot decode", "short": "ValueError: input: expected a video"}


@pytest.fixture(scope="module")
def singles(batch) -> dict:
    """Each good video by a single reconstruct_file run, at one torch thread (a worker's here)."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        found = {}
        for video, _ in list_videos(batch / "videos", batch / "singles"):
            if video.stem in GOOD:
                found[video.stem] = nrdepth.reconstruct_file(video, batch / "singles" / video.stem, batch / "model.safetensors", device="cpu")
        return found
    finally:
        torch.set_num_threads(threads)


def summary(out: Path) -> list:
    with open(out / SUMMARY, newline="") as f:
        return list(csv.DictReader(f))


def check_batch(rows, out: Path, singles: dict) -> None:
    table = summary(out)
    assert [r["input"] for r in table] == [r.input for r in rows] and len(rows) == 5
    for row, line in zip(rows, table):
        name = Path(row.output).name
        assert line["status"] == row.status and line["error"] == row.error
        if name in GOOD:
            assert row.status == "done" and row.error == "" and int(line["frames"]) == {"a": 12, "b": 10, "c": 8}[name]
            assert (out / name / "depth.npz").read_bytes() == (singles[name] / "depth.npz").read_bytes()
        else:
            assert row.status == "failed" and row.error.startswith(BAD[name]) and not (out / name).exists()
    assert not [p.name for p in out.iterdir() if ".partial" in p.name]


def test_the_local_pool_matches_single_runs_and_reports_the_bad_videos(batch, singles, tmp_path):
    out = tmp_path / "out"
    seen = []
    rows = nrdepth.reconstruct_many(batch / "videos", out, batch / "model.safetensors", device="cpu", workers=2, threads=1,
                                    progress=lambda done, total, row: seen.append((done, total)))
    check_batch(rows, out, singles)
    assert seen == [(0, 5)] + [(k, 5) for k in range(1, 6)]
    # A rerun finds every good folder complete and tries the bad ones again.
    again = nrdepth.reconstruct_many([str(batch / "videos" / "*.npy"), batch / "videos" / "c.mp4"], out, batch / "model.safetensors",
                                     device="cpu", workers=2, threads=1)
    assert {Path(r.output).name: r.status for r in again} == {"a": "skipped", "b": "skipped", "short": "failed", "c": "skipped"}


def test_a_ray_cluster_started_here_gives_the_same_folders(batch, singles, tmp_path):
    ray = pytest.importorskip("ray")
    ray.init(num_cpus=2, include_dashboard=False, logging_level="ERROR", log_to_driver=False)
    try:
        rows = nrdepth.reconstruct_many(batch / "videos", tmp_path / "out", batch / "model.safetensors", device="cpu", engine="ray", threads=1)
    finally:
        ray.shutdown()
    check_batch(rows, tmp_path / "out", singles)


def test_a_batch_killed_in_the_middle_redoes_only_the_unfinished_videos(batch, singles, tmp_path):
    out = tmp_path / "out"
    argv = [sys.executable, "-m", "nrdepth", "reconstruct-many", str(batch / "videos"), "-o", str(out), "--model", str(batch / "model.safetensors"),
            "--device", "cpu", "--workers", "1", "--threads", "1", "--quiet"]
    process = subprocess.Popen(argv, start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.time() + 120
    while not (out / "a" / "depth.npz").exists() and time.time() < deadline:
        time.sleep(0.05)
    os.killpg(process.pid, signal.SIGKILL)  # the batch and its workers, as a crash or the OOM killer would
    process.wait()
    assert (out / "a" / "depth.npz").exists()
    finished = {p.name: p.stat().st_mtime_ns for p in out.iterdir() if p.is_dir() and not p.name.startswith(".")}
    result = subprocess.run(argv, capture_output=True, text=True, timeout=300)
    assert result.returncode == 1, result.stderr[-2000:]  # two videos cannot be read
    rows = {Path(r["output"]).name: r for r in summary(out)}
    for name in GOOD:
        assert rows[name]["status"] == ("skipped" if name in finished else "done")
        assert (out / name / "depth.npz").read_bytes() == (singles[name] / "depth.npz").read_bytes()
    for name, mtime in finished.items():
        assert (out / name).stat().st_mtime_ns == mtime  # left as it was
    assert not [p.name for p in out.iterdir() if ".partial" in p.name]
    assert "failed: " in result.stderr and result.stdout.startswith(f"wrote {out / SUMMARY}: 5 videos, {3 - len(finished)} done, {len(finished)} complete before, 2 failed")


def test_inputs_are_named_and_listed_once_each(batch, tmp_path, capsys):
    listing = tmp_path / "list.txt"
    listing.write_text(f"# the good ones\n{batch / 'videos' / 'a.npy'}\n\n{batch / 'videos' / 'b.npy'}\n")
    (tmp_path / "x").mkdir()
    np.save(tmp_path / "x" / "a.npy", drifting(4, 3))
    pairs = list_videos([listing, batch / "videos" / "a.npy", tmp_path / "x" / "a.npy"], tmp_path / "out")
    assert [(v.name, f.name) for v, f in pairs] == [("a.npy", "a_1"), ("b.npy", "b"), ("a.npy", "a_2")]
    assert main(["reconstruct-many", str(tmp_path / "none*.mp4"), "-o", str(tmp_path / "out")]) == 2
    assert capsys.readouterr().err.strip().endswith("inputs: the pattern " + str(tmp_path / "none*.mp4") + " matches no video")
    with pytest.raises(ValueError, match="^engine:"):
        nrdepth.reconstruct_many(listing, tmp_path / "out", engine="dask")
    with pytest.raises(ValueError, match="^overwrite:"):
        nrdepth.reconstruct_many(listing, tmp_path / "out", overwrite=True)
    assert not (tmp_path / "out").exists()


def test_no_two_inputs_of_a_batch_ever_meet_in_one_folder(tmp_path):
    def made(*paths):
        for path in paths:
            path = tmp_path / path
            if path.suffix:
                path.parent.mkdir(parents=True, exist_ok=True)
                path.touch()
            else:  # an image folder
                path.mkdir(parents=True, exist_ok=True)
                (path / "0.png").touch()
        return [tmp_path / p for p in paths]

    for inputs in (["a/clip.npy", "b/clip.npy", "clip_1.npy"], ["clip", "clip.npy", "clip_npy.npy"]):
        videos = made(*inputs)
        names = [folder.name for _, folder in list_videos(videos, tmp_path / "out")]
        assert len({name.casefold() for name in names}) == len(names), names
        assert names == [folder.name for _, folder in list_videos(videos, tmp_path / "out")]  # the same inputs, the same folders
    assert [f.name for _, f in list_videos(made("a/clip.npy", "b/clip.npy", "clip_1.npy"), tmp_path / "out")] == ["clip_1_2", "clip_2", "clip_1"]
    rng = np.random.default_rng(0)
    stems = ["clip", "clip_1", "clip_2", "Clip", "clip_npy", "clip_mp4", "clip_1_2", "clip_images"]
    for trial in range(200):  # random sets of same stems, suffixes, folders and names that look like suffixed names
        root = f"fuzz{trial}"
        paths = {f"{root}/{rng.choice(['', 'a/', 'b/', 'a/b/'])}{rng.choice(stems)}{rng.choice(['.npy', '.mp4', '.avi', ''])}"
                 for _ in range(rng.integers(2, 9))}
        videos = made(*sorted(paths))
        rng.shuffle(videos)
        names = [folder.name.casefold() for _, folder in list_videos(videos, tmp_path / "out")]
        assert len(set(names)) == len(names), (videos, names)


def test_a_folder_an_earlier_batch_wrote_for_another_video_is_refused_naming_both(batch, tmp_path):
    out = tmp_path / "out"
    (tmp_path / "x").mkdir()
    np.save(tmp_path / "x" / "a.npy", drifting(4, 3))
    (out / "a").mkdir(parents=True)  # as an earlier batch of x/a.npy left it
    (out / SUMMARY).write_text(f"input,output,status\n{tmp_path / 'x' / 'a.npy'},{out / 'a'},done\n")
    with pytest.raises(ValueError, match=r"^inputs: .*a\.npy would be written to .*, which holds .*x/a\.npy from an earlier batch"):
        nrdepth.reconstruct_many(batch / "videos" / "a.npy", out)


def _children(pid: int) -> List[int]:
    """The live processes whose parent is ``pid`` (Linux's /proc)."""
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[1]) == pid and fields[0] != "Z":
                found.append(int(entry.name))
    return found


def _alive(pid: int) -> bool:
    try:
        return (Path("/proc") / str(pid) / "stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def _long_batch(batch: Path, tmp_path: Path) -> Path:
    """Four videos long enough that a batch of them is still under way when a test stops it."""
    videos = tmp_path / "long"
    videos.mkdir()
    for seed in range(4):
        np.save(videos / f"v{seed}.npy", drifting(64, seed, 96, 128))
    return videos


def _under_way(process: subprocess.Popen) -> List[int]:
    """The batch's processes once its two workers run (and, a moment later, its resource tracker)."""
    deadline, children = time.time() + 120, []
    while time.time() < deadline and len(children) < 2 and process.poll() is None:
        children = _children(process.pid)
        time.sleep(0.05)
    time.sleep(1.0)  # the workers under way
    assert process.poll() is None and len(children) >= 2, children
    return _children(process.pid)


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads the process table from /proc")
def test_a_batch_killed_by_kill_9_leaves_no_process_of_its_own_behind(batch, tmp_path):
    argv = [sys.executable, "-m", "nrdepth", "reconstruct-many", str(_long_batch(batch, tmp_path)), "-o", str(tmp_path / "out"), "--model",
            str(batch / "model.safetensors"), "--device", "cpu", "--workers", "2", "--threads", "1", "--quiet"]
    process = subprocess.Popen(argv, start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    workers = _under_way(process)
    process.kill()  # the batch alone, as a crash or the OOM killer would: not its process group
    process.wait()
    deadline = time.time() + 10
    while time.time() < deadline and any(_alive(pid) for pid in workers):
        time.sleep(0.2)
    left = [pid for pid in workers if _alive(pid)]
    try:
        assert not left, f"still alive 10 s after kill -9: {left}"
    finally:
        os.killpg(process.pid, signal.SIGKILL) if left else None


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads the process table from /proc")
def test_ctrl_c_in_a_batch_says_one_line_from_every_process(batch, tmp_path):
    argv = [sys.executable, "-m", "nrdepth", "reconstruct-many", str(_long_batch(batch, tmp_path)), "-o", str(tmp_path / "out"), "--model",
            str(batch / "model.safetensors"), "--device", "cpu", "--workers", "2", "--threads", "1"]
    # As from a terminal: a test run started in the background (nohup, CI) hands its children SIGINT ignored.
    process = subprocess.Popen(argv, start_new_session=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    _under_way(process)
    os.killpg(process.pid, signal.SIGINT)  # as a terminal's Ctrl-C: every process of the group
    out, err = process.communicate(timeout=120)
    assert process.returncode == 130, err[-2000:]
    assert "Traceback" not in err and "KeyboardInterrupt" not in err, err[-2000:]
    from nrdepth.io.folder import check_complete

    for folder in (tmp_path / "out").iterdir():  # a video finished before the Ctrl-C stands whole; none is left half done
        assert folder.name == SUMMARY or (folder.is_dir() and not folder.name.startswith(".") and check_complete(folder) > 0), folder.name


def test_a_ray_address_that_cannot_be_reached_fails_at_once_naming_it(batch, tmp_path):
    start = time.perf_counter()
    for address in ("127.0.0.1:1", "ray://127.0.0.1:1"):
        with pytest.raises(ValueError, match=f"^address: no Ray cluster answers at {address} "):
            nrdepth.reconstruct_many(batch / "videos" / "a.npy", tmp_path / "out", engine="ray", address=address)
    with pytest.raises(ValueError, match="^address: expected host:port"):
        nrdepth.reconstruct_many(batch / "videos" / "a.npy", tmp_path / "out", engine="ray", address="127.0.0.1:port")
    assert time.perf_counter() - start < 30 and not (tmp_path / "out").exists()
