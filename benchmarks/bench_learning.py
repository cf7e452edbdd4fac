"""Training samples/s and inference patches/s of the default network, on the
CPU and (when one is present) on CUDA, with the clip generator's rate
measured in the same run for reference (online training needs the generator
to keep up).

    python benchmarks/bench_learning.py [--batch 4] [--steps 5] [--base 16]
"""

from __future__ import annotations

import argparse
import time

import torch

import nrdepth
from nrdepth.losses import get_loss
from nrdepth.model import UNet3D, count_parameters


def rate(fn, items: int, repeats: int) -> float:
    fn()  # warm-up
    start = time.perf_counter()
    for _ in range(repeats):
        fn()
    return items * repeats / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--batch", type=int, default=4)
    parser.add_argument("--steps", type=int, default=5)
    parser.add_argument("--base", type=int, default=16)
    parser.add_argument("--loss", default="gbr")
    args = parser.parse_args()

    clips = nrdepth.generate_clips(args.batch, seed=0)
    generator = rate(lambda: nrdepth.generate_clips(args.batch, seed=1), args.batch, args.steps)
    video = torch.from_numpy(clips.video).float().div(255).unsqueeze(1)
    target = torch.nn.functional.avg_pool2d(torch.from_numpy(clips.depth), 2)
    loss_fn = get_loss(args.loss)
    devices = ["cpu"] + (["cuda"] if torch.cuda.is_available() else [])
    print(f"UNet3D(base={args.base}): {count_parameters(UNet3D(args.base)):,} parameters; batch {args.batch} of 16×64×64; torch threads {torch.get_num_threads()}")
    print(f"{'clip generator':28s}{generator:10.1f} clips/s")
    for device in devices:
        model = UNet3D(args.base).to(device)
        optimiser = torch.optim.Adam(model.parameters(), 1e-3)
        v, t = video.to(device), target.to(device)

        def step() -> None:
            optimiser.zero_grad()
            loss_fn(model(v)[:, 0], t).backward()
            optimiser.step()
            if device == "cuda":
                torch.cuda.synchronize()

        @torch.no_grad()
        def infer() -> None:
            model(v)
            if device == "cuda":
                torch.cuda.synchronize()

        print(f"{'training (' + device + ')':28s}{rate(step, args.batch, args.steps):10.2f} samples/s")
        print(f"{'inference (' + device + ')':28s}{rate(infer, args.batch, args.steps):10.2f} patches/s")


if __name__ == "__main__":
    main()
