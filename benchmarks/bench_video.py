"""The main job at video scale: the tiled fine pass against the patch-by-patch
one, in one run, on this machine's threads.

1. Cost. For a generated 256×256×16 video and the real ``kinect_paper``
   (640×480×191, whole frame), each fine pass in a fresh process: wall time,
   peak RSS, and where the time goes (coarse pass, network, cutting and
   resizing windows, stitch); the ratio of the two; the network work per
   output voxel (64×64×16 patch-equivalents computed divided by those the
   video holds) and the network's achieved GFLOP/s beside a torch sgemm
   measured in the same run.
2. The tiled field against one untiled pass over the same frames (the
   tiles' seams): the largest and mean difference, in standard deviations
   of the field.
3. Accuracy, paired per video: MAE-SN per frame and from the first frame of
   ``--videos`` generated 256×256×16 videos inside the training ranges and
   as many outside them (``nrdepth.scores.generated.out_of_range``), a fresh seed,
   reconstructed both ways; the mean paired difference ± its standard error.
4. The real videos both ways: ``phisft_R1`` (MAE-SN, ``bench_real.phisft``'s
   crop) and ``kinect_paper`` on its sparse ground truth (mm, the whole
   sheet).
5. ``--resolution``: the working resolution (``max_side``) on both real
   videos, with the time each costs: ``phisft_R1``'s crop taken from the
   full frames binned 2×2 (216×216, ``nrdepth.scores.real.phisft_at_bin``) and
   ``kinect_paper``'s sheet (528×416), each reconstructed at several
   working sizes and scored at its own grid, beside the plane.
6. ``--long``: video files through ``nrdepth.reconstruct_file`` (what
   ``nrdepth reconstruct`` runs), each in a process of its own: the whole
   ``kinect_paper`` (640×480×191) and a 1920×1080×300 H.264 file of a
   textured surface rippling under a moving light (written first), at the
   default working size (``--native``: also at their own), on ``--device``:
   time, frames a second, peak RSS.
7. ``--only rate [--device cuda]``: frames a second of ``nrdepth.reconstruct``
   on arrays in memory at 640×480 and 1920×1080 (needs neither PyAV nor the
   data: what a lent GPU machine can run; ``tools/gpu_run.sh video``).

    python benchmarks/bench_video.py [--videos 32] [--seed 4000001] [--threads 2] [--skip-accuracy] [--resolution] [--long [--native] [--device cuda]]
    python benchmarks/bench_video.py --only rate --device cuda
"""

from __future__ import annotations

import argparse
import inspect
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import torch

import nrdepth
from nrdepth.reconstruct.stitch import PATCH
from nrdepth.reconstruct import MARGIN, TILE, coarse_depth, field_frames, field_windows, inference_model, patch_depths, tile_plan
from nrdepth.reconstruct.stitch import COARSE_WEIGHT, TEMPORAL_WEIGHT, make_stitcher

from nrdepth.scores.real import DATA, KINECT_ROI, kinect_score, kinect_truth
from nrdepth.scores.generated import out_of_range

PATCH_VOXELS = int(np.prod(PATCH))


def load(name: str) -> np.ndarray:
    if name == "generated":
        from nrdepth.learning.evaluate import TEST_SEED

        return nrdepth.generate_clips(1, seed=TEST_SEED, config=nrdepth.GeneratorConfig(size=256)).video[0]
    from nrdepth.io import read_video

    return read_video(DATA / "kinect_paper").frames


def peak_mb() -> float:
    """The peak RSS in MB of this process's own memory (VmHWM). Not getrusage's ru_maxrss: Linux carries that
    across fork and exec, so a job would report its parent's size when the parent was larger."""
    with open("/proc/self/status") as status:
        return next(int(line.split()[1]) for line in status if line.startswith("VmHWM")) / 1024


PEAK_MB = inspect.getsource(peak_mb)
"""``peak_mb``'s source, for the jobs' own processes."""


def flops_per_voxel(net: torch.nn.Module) -> float:
    from torch.utils.flop_counter import FlopCounterMode

    with torch.inference_mode(), FlopCounterMode(display=False) as counter:
        net(torch.rand(1, 1, *PATCH))
    return counter.get_total_flops() / PATCH_VOXELS


def sgemm_rate(n: int = 2048, repeats: int = 5) -> float:
    a, b = torch.rand(n, n), torch.rand(n, n)
    torch.mm(a, b)
    start = time.perf_counter()
    for _ in range(repeats):
        torch.mm(a, b)
    return 2 * n**3 * repeats / (time.perf_counter() - start) / 1e9


def job(name: str, fine: str) -> dict:
    """Reconstructions of video ``name`` through ``fine``, in a process of
    their own (for its peak RSS): the first (cold: the network's kernels
    are set up for each new shape) and, for videos of a few seconds, a
    second one (warm), timed by stage."""
    video = load(name)
    net = inference_model(None, torch.device("cpu"))
    first = run(video, net, fine)
    if first["total"] > 20:
        return first
    return {**run(video, net, fine), "cold": first["total"]}


def run(video: np.ndarray, net: torch.nn.Module, fine: str) -> dict:
    """One reconstruction, timed by stage."""
    dev = torch.device("cpu")
    layout = nrdepth.patch_layout(video.shape)
    seconds = {}
    start = time.perf_counter()
    coarse = coarse_depth(video, net, 8, dev)
    seconds["coarse pass"] = time.perf_counter() - start
    stitcher = make_stitcher(coarse, layout.patch, "joint", COARSE_WEIGHT, "hann", TEMPORAL_WEIGHT)
    del coarse
    network = {"seconds": 0.0}

    def timed(spans):
        while True:
            t0 = time.perf_counter()
            item = next(spans, None)
            network["seconds"] += time.perf_counter() - t0
            if item is None:
                return
            yield item

    if fine == "field":
        windows = field_windows(layout, timed(field_frames(video, net, dev)))
        computed = sum(np.prod([b - a for a, b in tile]) for tile in tile_plan(video.shape, net))
    else:
        windows = patch_depths(video, net, layout, 8, dev)
        computed = len(layout.origins) * PATCH_VOXELS
    cut = stitch = 0.0
    while True:
        t0 = time.perf_counter()
        try:
            origins, depth = next(windows)
        except StopIteration:
            break
        t1 = time.perf_counter()
        stitcher.add(depth, origins)
        cut, stitch = cut + t1 - t0, stitch + time.perf_counter() - t1
    t0 = time.perf_counter()
    stitcher.finish()
    stitch += time.perf_counter() - t0
    if fine == "field":
        seconds["network"] = network["seconds"]
        seconds["cutting, resizing"] = cut - network["seconds"]
    else:
        seconds["network, cutting, resizing"] = cut
    seconds["stitch"] = stitch
    total = time.perf_counter() - start
    return {"seconds": seconds, "total": total, "peak_mb": peak_mb(),
            "work": computed / video.size, "shape": list(video.shape), "network_voxels": float(computed)}


def cost(threads: int) -> None:
    net = inference_model(None, torch.device("cpu"))
    per_voxel = flops_per_voxel(net)
    sgemm = sgemm_rate()
    print(f"network: {per_voxel * PATCH_VOXELS / 1e9:.2f} GFLOP a 64×64×16 patch; torch sgemm on {threads} threads: {sgemm:.1f} GFLOP/s")
    for name in ("generated", "kinect_paper"):
        runs = {}
        for fine in ("patches", "field"):
            out = subprocess.run([sys.executable, __file__, "--job", name, fine, "--threads", str(threads)], check=True, capture_output=True, text=True)
            runs[fine] = json.loads(out.stdout.strip().splitlines()[-1])
        t, h, w = runs["field"]["shape"]
        print(f"\n{name}, {w}×{h}×{t}:")
        print(f"  {'fine pass':10s}{'time s':>9s}{'peak MB':>10s}{'work/voxel':>12s}   where the time goes")
        for fine, r in runs.items():
            parts = ", ".join(f"{k} {v:.1f}" for k, v in r["seconds"].items())
            cold = f" (first run in the process: {r['cold']:.1f} s)" if "cold" in r else ""
            print(f"  {fine:10s}{r['total']:>9.1f}{r['peak_mb']:>10.0f}{r['work']:>12.2f}   {parts}{cold}")
        f = runs["field"]
        rate = f["network_voxels"] * per_voxel / f["seconds"]["network"] / 1e9
        print(f"  ratio patches/field: time {runs['patches']['total'] / f['total']:.2f}×, network work {runs['patches']['work'] / f['work']:.2f}×; "
              f"field network {rate:.1f} GFLOP/s = {100 * rate / sgemm:.0f} % of sgemm")


def seams() -> None:
    video = load("kinect_paper")[:64]
    dev = torch.device("cpu")
    net = inference_model(None, dev)
    untiled = np.concatenate([d for _, d in field_frames(video, net, dev, video.shape, (0, 0, 0))])
    tiled = np.concatenate([d for _, d in field_frames(video, net, dev)])
    diff = np.abs(tiled - untiled) / untiled.std()
    print(f"\nseams: kinect_paper's first 64 frames, tiles {TILE} with margins {MARGIN} against one untiled pass: "
          f"max {diff.max():.4f}, mean {diff.mean():.5f}, 99.9th percentile {np.quantile(diff, 0.999):.4f} (standard deviations of the field)")


def paired(label: str, a: list, b: list) -> str:
    d = np.asarray(b) - np.asarray(a)
    return f"{label} {np.mean(a):.4f} → {np.mean(b):.4f} ({np.mean(d):+.4f} ± {np.std(d, ddof=1) / np.sqrt(len(d)):.4f})"


def accuracy(videos: int, seed: int) -> None:
    net = inference_model(None, torch.device("cpu"))
    base = nrdepth.GeneratorConfig(size=256)
    print(f"\naccuracy, {videos} + {videos} generated 256×256×16 videos (seed {seed}), MAE-SN patches → field (paired difference ± s.e.):")
    for label, config in (("inside", base), ("outside", out_of_range(base))):
        clips = nrdepth.generate_clips(videos, seed=seed, config=config)
        scores = {fine: {"frame": [], "first": []} for fine in ("patches", "field")}
        flat = {"frame": [], "first": []}
        for video, truth in zip(clips.video, clips.depth):
            for fine in scores:
                depth = nrdepth.reconstruct(video, net, device="cpu", fine=fine)
                for align in ("frame", "first"):
                    scores[fine][align].append(nrdepth.mae_sn(depth, truth, align))
            for align in flat:
                flat[align].append(nrdepth.flat_baseline(truth, align))
        print(f"  {label:8s}" + "; ".join(paired(a, scores["patches"][a], scores["field"][a]) for a in ("frame", "first"))
              + f"; flat {np.mean(flat['frame']):.4f} / {np.mean(flat['first']):.4f}")


def real() -> None:
    from nrdepth.scores.metrics import flat_baseline as flat, mae_sn
    from nrdepth.io import read_video

    net = inference_model(None, torch.device("cpu"))
    data = np.load(DATA / "phisft_R1" / "derived_q4.npz")
    video, truth = data["gray"][:, 110:218, 106:214], data["depth"][:, 110:218, 106:214]
    mask = np.isfinite(truth)
    print("\nphisft_R1 (108×108 crop of the 270×480 grid), MAE-SN per frame / from the first frame:")
    for fine in ("patches", "field"):
        depth = nrdepth.reconstruct(video, net, device="cpu", fine=fine)
        print(f"  {fine:8s}{mae_sn(depth, truth, 'frame', mask=mask):.4f} / {mae_sn(depth, truth, 'first', mask=mask):.4f}")
    print(f"  {'plane':8s}{flat(truth, 'frame', mask=mask):.4f} / {flat(truth, 'first', mask=mask):.4f}")
    x, y, w, h = KINECT_ROI
    frames = read_video(DATA / "kinect_paper").frames[:, y : y + h, x : x + w]
    gt = kinect_truth()
    print(f"kinect_paper (the sheet, {w}×{h}×{len(frames)}), MAE on the sparse ground truth, mm:")
    for fine in ("patches", "field"):
        print(f"  {fine:8s}{kinect_score(nrdepth.reconstruct(frames, net, device='cpu', fine=fine), gt):.2f}")


def resolution() -> None:
    from nrdepth.scores.metrics import flat_baseline as flat, mae_sn, sparse_baselines
    from nrdepth.io import read_video

    from nrdepth.scores.real import phisft_at_bin

    net = inference_model(None, torch.device("cpu"))
    video, truth = phisft_at_bin(2)
    mask = np.isfinite(truth)
    print(f"\nworking resolution, phisft_R1 (the crop from the full frames binned 2×2: {video.shape[2]}×{video.shape[1]}×{len(video)}), "
          f"MAE-SN per frame / from the first frame (plane {flat(truth, 'frame', mask=mask):.4f} / {flat(truth, 'first', mask=mask):.4f}):")
    for side in (216, 162, 108, 72):
        start = time.perf_counter()
        depth = nrdepth.reconstruct(video, net, device="cpu", max_side=side)
        seconds = time.perf_counter() - start
        print(f"  max_side {side:4d}: {mae_sn(depth, truth, 'frame', mask=mask):.4f} / {mae_sn(depth, truth, 'first', mask=mask):.4f}   {seconds:.1f} s")
    x, y, w, h = KINECT_ROI
    frames = read_video(DATA / "kinect_paper").frames[:, y : y + h, x : x + w]
    gt = kinect_truth()
    base = sparse_baselines(gt["uv"], gt["z"])
    print(f"kinect_paper (the sheet, {w}×{h}×{len(frames)}), mm on the sparse ground truth (plane {base['plane']:.2f}, fixed bowl {base['bowl']:.2f}):")
    for side in (528, 384, 264, 192, 128):
        start = time.perf_counter()
        depth = nrdepth.reconstruct(frames, net, device="cpu", max_side=side)
        seconds = time.perf_counter() - start
        print(f"  max_side {side:4d}: {kinect_score(depth, gt):.2f}   {seconds:.1f} s")


def rippling_frames(frames: int = 300, size: tuple = (1080, 1920)):
    """A textured surface rippling under a moving light: uint8 gray frames (H, W), one at a time."""
    h, w = size
    y, x = np.mgrid[0:h, 0:w].astype(np.float32) / w
    texture = 0.5 + 0.25 * np.sin(90 * x + 40 * np.sin(7 * y)) * np.cos(70 * y)
    for t in range(frames):
        phase = 2 * np.pi * t / frames
        zx = np.cos(9 * x + phase) * np.sin(5 * y)  # the relief's slopes
        zy = -np.sin(9 * x + phase) * np.cos(5 * y)
        light = np.clip(0.6 + 0.4 * (np.cos(phase) * zx + np.sin(phase) * zy - 0.3 * zy), 0, 1)
        yield np.rint(255 * np.clip(texture * light, 0, 1)).astype(np.uint8)


def write_long_video(path: Path, frames: int = 300, size: tuple = (1080, 1920)) -> None:
    """:func:`rippling_frames` as an H.264 file."""
    from nrdepth.io import Mp4Writer

    with Mp4Writer(path, size[0], size[1], 30.0) as writer:
        for frame in rippling_frames(frames, size):
            writer.write(np.repeat(frame[None, ..., None], 3, axis=-1))


def rate(device: str) -> None:
    """Frames a second of ``nrdepth.reconstruct`` on arrays in memory (no
    PyAV or data needed: what a lent GPU machine can run), 640×480 and
    1920×1080, at the default working size and at the videos' own."""
    from nrdepth.reconstruct import MAX_SIDE

    net = inference_model(None, torch.device(device))
    nrdepth.reconstruct(np.stack(list(rippling_frames(16, (256, 256)))), net, device=device)  # kernels set up
    print(f"\nnrdepth.reconstruct on {device}, arrays in memory (rippling_frames), frames a second:")
    for frames, size in ((192, (480, 640)), (300, (1080, 1920))):
        video = np.stack(list(rippling_frames(frames, size)))
        for side in (MAX_SIDE, None):
            if device == "cuda":
                torch.cuda.synchronize()
            start = time.perf_counter()
            nrdepth.reconstruct(video, net, device=device, max_side=side)
            seconds = time.perf_counter() - start
            print(f"  {size[1]}×{size[0]}×{frames}, max_side {side or 'own'}: {seconds:.1f} s, {frames / seconds:.1f} frames/s")


def file_job(source: Path, out: Path, threads: int, device: str, max_side: int) -> tuple:
    """``nrdepth.reconstruct_file`` in a process of its own, its heap kept as
    the ``nrdepth`` command keeps it: (seconds, peak RSS in MB, frames)."""
    code = PEAK_MB + ("import sys, time, torch; torch.set_num_threads(int(sys.argv[3])); import nrdepth; nrdepth.memory.keep_freed_memory(); "
                      "start = time.perf_counter(); nrdepth.reconstruct_file(sys.argv[1], sys.argv[2], device=sys.argv[4], max_side=int(sys.argv[5]) or None); "
                      "print(time.perf_counter() - start, peak_mb())")
    run = subprocess.run([sys.executable, "-c", code, str(source), str(out), str(threads), device, str(max_side)], check=True, capture_output=True, text=True)
    seconds, peak = (float(v) for v in run.stdout.split()[-2:])
    with np.load(out / "depth.npz") as saved:
        frames = saved["depth"].shape[0]
    return seconds, peak, frames


def memory_job(source: Path, threads: int, device: str) -> tuple:
    """``nrdepth.reconstruct`` of a video read into memory first, in a process of its own, its heap kept as the
    ``nrdepth`` command keeps it: (seconds, peak RSS in MB, frames)."""
    code = PEAK_MB + ("import sys, time, torch; torch.set_num_threads(int(sys.argv[2])); import nrdepth; nrdepth.memory.keep_freed_memory(); "
                      "from nrdepth.io import read_video; "
                      "video = read_video(sys.argv[1]).frames; start = time.perf_counter(); nrdepth.reconstruct(video, device=sys.argv[3]); "
                      "print(time.perf_counter() - start, peak_mb(), len(video))")
    run = subprocess.run([sys.executable, "-c", code, str(source), str(threads), device], check=True, capture_output=True, text=True)
    seconds, peak, frames = (float(v) for v in run.stdout.split()[-3:])
    return seconds, peak, int(frames)


def long(threads: int, device: str, native: bool) -> None:
    import tempfile

    from nrdepth.reconstruct import MAX_SIDE

    print(f"torch sgemm 2048² on {threads} threads: {sgemm_rate():.1f} GFLOP/s (this machine's speed, beside every time below)")
    seconds, peak, frames = memory_job(DATA / "kinect_paper", threads, device)
    print(f"kinect_paper 640×480×191 in memory (nrdepth.reconstruct, no files written), max_side {MAX_SIDE}: {seconds:.1f} s "
          f"({frames / seconds:.2f} frames/s), peak RSS {peak:.0f} MB")
    with tempfile.TemporaryDirectory() as scratch:
        path = Path(scratch) / "long.mp4"
        start = time.perf_counter()
        write_long_video(path)
        print(f"\nvideo files through nrdepth.reconstruct_file on {device} (the default working size, max_side {MAX_SIDE}, and with 0 the video's own); "
              f"the 1920×1080×300 H.264 file written in {time.perf_counter() - start:.0f} s:")
        sides = (MAX_SIDE, 0) if native else (MAX_SIDE,)
        for label, source in (("kinect_paper 640×480×191", DATA / "kinect_paper"), ("1920×1080×300", path)):
            for side in sides:
                out = Path(scratch) / f"out_{side}"
                seconds, peak, frames = file_job(source, out, threads, device, side)
                size = sum(p.stat().st_size for p in out.iterdir()) / 1e6
                page = (out / "viewer.html").stat().st_size / 1e6
                print(f"  {label}, max_side {side or 'own'}: {seconds:.1f} s ({frames / seconds:.2f} frames/s), peak RSS {peak:.0f} MB, "
                      f"output {size:.0f} MB (viewer.html {page:.1f} MB)")
                import shutil

                shutil.rmtree(out)
    print(f"torch sgemm 2048² on {threads} threads, again: {sgemm_rate():.1f} GFLOP/s (whether the machine's speed held through the run)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--videos", type=int, default=32, help="generated videos inside and as many outside the training ranges")
    parser.add_argument("--seed", type=int, default=4000001, help="generator seed of the scored videos (fresh: not the validation or held-out seeds)")
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--skip-accuracy", action="store_true", help="cost and seams only")
    parser.add_argument("--resolution", action="store_true", help="also the working resolution on both real videos")
    parser.add_argument("--long", action="store_true", help="also a 1920×1080×300 video through reconstruct_file")
    parser.add_argument("--only", choices=("resolution", "long", "rate"), default=None, help="run only that part (rate: frames a second on arrays, for a GPU)")
    parser.add_argument("--native", action="store_true", help="--long also at the videos' own size")
    parser.add_argument("--device", default="cpu", help="--long's and rate's device (cpu, cuda)")
    parser.add_argument("--job", nargs=2, metavar=("VIDEO", "FINE"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    if args.job:
        print(json.dumps(job(*args.job)))
        return
    if args.only is None:
        cost(args.threads)
        seams()
        if not args.skip_accuracy:
            real()
            accuracy(args.videos, args.seed)
    if args.resolution or args.only == "resolution":
        resolution()
    if args.long or args.only == "long":
        long(args.threads, args.device, args.native)
    if args.only == "rate":
        rate(args.device)


if __name__ == "__main__":
    main()
