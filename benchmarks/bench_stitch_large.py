"""Time and peak memory of stitching a large video, for each stitch: the
paper's (each patch aligned to the coarse depth on its own, triangle
windows), the default (joint alignment with its temporal tie, Hann windows)
and the default untied (ν = 0).

The patches stand in for a network's: one smooth random 16×64×64 block,
shifted and offset per patch, so that neighbouring patches disagree and the
ties are mostly strong. They arrive as `reconstruct` gives them: time-major,
64 at a time. Each stitch runs in a fresh process, so its peak resident
memory (the video, its coarse depth and the patches held) is its own.
Ratios are to the paper's stitch, measured in the same run.

    python benchmarks/bench_stitch_large.py [--shape 48,720,1280] [--threads N]
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import time

import numpy as np

STITCHES = {"paper": ("coarse", "triangle", 0.0), "default": ("joint", "hann", None), "untied": ("joint", "hann", 0.0)}


def run(stitch: str, shape: tuple) -> None:
    """Stitch in this process; print seconds and peak RSS in GB."""
    from scipy.ndimage import gaussian_filter

    from nrdepth.reconstruct.stitch import COARSE_WEIGHT, TEMPORAL_WEIGHT, make_stitcher, patch_layout

    alignment, window, nu = STITCHES[stitch]
    layout = patch_layout(shape)
    rng = np.random.default_rng(0)
    coarse = gaussian_filter(rng.standard_normal(shape, dtype=np.float32), (1, 8, 8))
    block = gaussian_filter(rng.standard_normal((32, 96, 96), dtype=np.float32), (2, 6, 6), mode="wrap")
    origins = np.asarray(layout.origins)
    start = time.perf_counter()
    stitcher = make_stitcher(coarse, layout.patch, alignment, COARSE_WEIGHT, window, TEMPORAL_WEIGHT if nu is None else nu)
    for i in range(0, len(origins), 64):
        chunk = origins[i : i + 64]
        shifts = [((t // 8 * 3) % 16, (y // 32 * 7) % 32, (x // 32 * 11) % 32) for t, y, x in chunk]
        patches = np.stack([block[a : a + 16, b : b + 64, c : c + 64] + 0.01 * t for (a, b, c), t in zip(shifts, chunk[:, 0])])
        stitcher.add(np.ascontiguousarray(patches, dtype=np.float32), chunk)
    stitcher.finish()
    print(f"{time.perf_counter() - start} {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--shape", default="48,720,1280", help="T,H,W of the video (default 48,720,1280)")
    parser.add_argument("--threads", type=int, default=None, help="RAYON_NUM_THREADS for the stitcher (default: all cores)")
    parser.add_argument("--run", choices=tuple(STITCHES), help=argparse.SUPPRESS)
    args = parser.parse_args()
    try:
        shape = tuple(int(v) for v in args.shape.split(","))
    except ValueError:
        shape = ()
    if len(shape) != 3 or min(shape) < 1:
        parser.error(f"--shape: expected T,H,W (positive integers), got {args.shape!r}")
    if args.threads is not None and args.threads < 1:
        parser.error(f"--threads: expected a positive integer, got {args.threads}")
    if args.run:
        run(args.run, shape)
        return
    env = dict(os.environ, **({"RAYON_NUM_THREADS": str(args.threads)} if args.threads else {}))
    from nrdepth.reconstruct.stitch import patch_layout

    print(f"stitching a {shape[2]}×{shape[1]}×{shape[0]} video from {len(patch_layout(shape).origins)} patches of 16×64×64, "
          f"{args.threads or os.cpu_count()} thread(s); each stitch in its own process")
    results = {}
    for stitch in STITCHES:
        out = subprocess.run([sys.executable, __file__, "--shape", args.shape, "--run", stitch], env=env, check=True, capture_output=True, text=True)
        seconds, gb = (float(v) for v in out.stdout.split())
        results[stitch] = seconds, gb
        paper = results["paper"]
        print(f"  {stitch:8s} {seconds:7.1f} s ({seconds / paper[0]:.2f}× the paper's)   peak memory {gb:5.2f} GB ({gb / paper[1]:.2f}×)", flush=True)


if __name__ == "__main__":
    main()
