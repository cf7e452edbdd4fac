"""Many videos at once: ``nrdepth reconstruct-many`` through its local pool
and through Ray on this machine, against a shell loop of single
``nrdepth reconstruct`` runs, in one run: videos a minute for each.

The videos: ``--copies`` copies of a ``--frames``-frame cut of
``kinect_paper`` (640×480, H.264), each reconstructed with the shipped
model on the CPU. A torch sgemm of 2048² matrices is measured in the same
run and printed beside the times (machines differ by 1.5×).

    python benchmarks/bench_batch.py            # 8 copies of 640×480×64
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import torch

from nrdepth.io import write_mp4
from nrdepth.scores.real import kinect_video

sys.path.insert(0, str(Path(__file__).parent))
from bench_video import sgemm_rate  # noqa: E402


def timed(argv: list) -> float:
    start = time.perf_counter()
    subprocess.run(argv, check=False, stdout=subprocess.DEVNULL)
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--copies", type=int, default=8)
    parser.add_argument("--frames", type=int, default=64)
    parser.add_argument("--engines", default="loop,local,ray", help="which of loop, local, ray")
    parser.add_argument("--workers", type=int, default=None, help="local: reconstruct-many's --workers (default: its own)")
    parser.add_argument("--threads", type=int, default=None, help="local and ray: reconstruct-many's --threads (default: its own)")
    args = parser.parse_args()
    cores = os.cpu_count() or 1
    print(f"{args.copies} copies of kinect_paper's first {args.frames} frames (640×480 H.264), {cores} cores, "
          f"torch sgemm {sgemm_rate():.0f} GFLOP/s")
    with tempfile.TemporaryDirectory() as scratch:
        root = Path(scratch)
        frames = kinect_video()[: args.frames]
        (root / "in").mkdir()
        write_mp4(root / "in" / "clip_0.mp4", np.repeat(frames[..., None], 3, axis=-1))
        for k in range(1, args.copies):
            shutil.copy(root / "in" / "clip_0.mp4", root / "in" / f"clip_{k}.mp4")
        nrdepth = [sys.executable, "-m", "nrdepth"]
        ray_split = ["--threads", str(args.threads)] if args.threads else []  # Ray has no --workers: its cluster's CPUs decide
        split = (["--workers", str(args.workers)] if args.workers else []) + ray_split
        runs = {
            "loop": lambda: sum(timed(nrdepth + ["reconstruct", str(v), "-o", str(root / "loop" / v.stem), "--device", "cpu", "--quiet"])
                                for v in sorted((root / "in").iterdir())),
            "local": lambda: timed(nrdepth + ["reconstruct-many", str(root / "in"), "-o", str(root / "local"), "--device", "cpu", "--quiet", *split]),
            "ray": lambda: timed(nrdepth + ["reconstruct-many", str(root / "in"), "-o", str(root / "ray"), "--device", "cpu", "--quiet",
                                            "--engine", "ray", *ray_split]),
        }
        what = {"loop": f"a shell loop of nrdepth reconstruct ({torch.get_num_threads()} torch threads each)",
                "local": f"reconstruct-many, local pool ({' '.join(split) or 'its defaults'})",
                "ray": f"reconstruct-many --engine ray, a Ray cluster started here ({' '.join(ray_split) or 'its defaults'})"}
        seconds = {}
        for engine in args.engines.split(","):
            seconds[engine] = runs[engine]()
            made = len(list((root / engine).glob("*/depth.npz")))
            line = f"{what[engine]:78s} {seconds[engine]:7.1f} s  {60 * made / seconds[engine]:5.2f} videos/min"
            if made != args.copies:
                line += f"  ({made} of {args.copies} written)"
            if "loop" in seconds and engine != "loop":
                line += f"  {seconds['loop'] / seconds[engine]:.2f}× the loop's rate"
            print(line, flush=True)
    print(f"torch sgemm after: {sgemm_rate():.0f} GFLOP/s")


if __name__ == "__main__":
    main()
