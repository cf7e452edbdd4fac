"""The main job's fine pass (``nrdepth.reconstruct.fine.field_frames``, the
shipped network over ``kinect_paper``'s roi in tiles) with its sums written
over each layer's new output (``nrdepth.model.unet2p1d.WRITE_OVER``, the
default) against every sum a new tensor, the reference, in the same run:
seconds each, rounds alternating, their medians and ratio, whether the
two depths are the same bytes, and a 2048² sgemm before and after.

    python benchmarks/bench_inference.py [--frames 64] [--rounds 3] [--threads 2]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from bench_video import sgemm_rate  # noqa: E402

KINECT = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "real" / "kinect_paper"
ROI = (64, 24, 528, 416)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=64, help="kinect_paper's first frames")
    parser.add_argument("--rounds", type=int, default=3, help="alternating rounds of each")
    parser.add_argument("--threads", type=int, default=2, help="torch's threads")
    args = parser.parse_args()

    import torch

    from nrdepth.io import open_video
    from nrdepth.model import unet2p1d
    from nrdepth.reconstruct.fine import field_frames
    from nrdepth.reconstruct.network import inference_model

    torch.set_num_threads(args.threads)
    x, y, w, h = ROI
    video = np.concatenate(list(open_video(KINECT, "input", slice(0, args.frames), ROI).chunks(16)))
    if video.ndim == 4:
        video = video[..., 0]
    net, device = inference_model(None, torch.device("cpu")), torch.device("cpu")
    statistic = (float(video.mean() / 255), float(video.std() / 255))

    def depth() -> np.ndarray:
        return np.concatenate([d for _, d in field_frames(video, net, device, statistic=statistic)])

    print(f"sgemm 2048²: {sgemm_rate():.0f} GFLOP/s, {args.threads} threads; {len(video)} frames of {w}×{h}")
    depth()  # untimed: the first tiles' kernels chosen
    seconds = {True: [], False: []}
    outputs = {}
    for _ in range(args.rounds):
        for write_over in (False, True):
            unet2p1d.WRITE_OVER = write_over
            start = time.perf_counter()
            outputs[write_over] = depth()
            seconds[write_over].append(time.perf_counter() - start)
    unet2p1d.WRITE_OVER = True
    new, over = (statistics.median(seconds[k]) for k in (False, True))
    print(f"every sum a new tensor (reference): {new:.2f} s (rounds {', '.join(f'{s:.2f}' for s in seconds[False])})")
    print(f"sums written over (default):       {over:.2f} s (rounds {', '.join(f'{s:.2f}' for s in seconds[True])}); "
          f"{new / over:.2f}× faster; the same bytes: {outputs[True].tobytes() == outputs[False].tobytes()}")
    print(f"sgemm 2048²: {sgemm_rate():.0f} GFLOP/s")


if __name__ == "__main__":
    main()
