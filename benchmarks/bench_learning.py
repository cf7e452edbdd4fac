"""Cost of each network architecture, measured in one run: FLOPs per
64×64×16 patch (forward, counted by torch's FlopCounterMode), training
samples/s (forward, loss, backward, Adam step) and inference patches/s, on the
CPU and on CUDA when there is one, each beside its ratio to the paper's
``UNet3D(base=16)`` measured in the same run. The clip generator's rate is
printed too: online training needs it to keep up.

    python benchmarks/bench_learning.py [--batch 4] [--steps 5] [--loss aligned_both_signed]
    python benchmarks/bench_learning.py --arch unet2p1d:width=32 --arch unet3d:base=8
"""

from __future__ import annotations

import argparse
import time
from typing import Callable, Dict, List, Tuple

import torch
from torch.utils.flop_counter import FlopCounterMode

import nrdepth
from nrdepth.learning.losses import get_loss
from nrdepth.model import build_model, count_parameters

REFERENCE = ("unet3d", {"base": 16})


def rate(fn: Callable[[], None], items: int, repeats: int) -> float:
    fn()  # warm-up
    start = time.perf_counter()
    for _ in range(repeats):
        fn()
    return items * repeats / (time.perf_counter() - start)


def forward_flops(model: torch.nn.Module) -> int:
    with torch.no_grad(), FlopCounterMode(display=False) as counter:
        model(torch.zeros(1, 1, 16, 64, 64))
    return counter.get_total_flops()


def parse_arch(text: str) -> Tuple[str, Dict[str, int]]:
    name, _, rest = text.partition(":")
    config = {k: int(v) for k, v in (item.split("=") for item in rest.split(",") if item)}
    return name, config


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--batch", type=int, default=4)
    parser.add_argument("--steps", type=int, default=5)
    parser.add_argument("--loss", default="aligned_both_signed")
    parser.add_argument("--arch", action="append", default=None, help="NAME[:key=value,...] (repeatable; default: unet2p1d)")
    args = parser.parse_args()
    archs: List[Tuple[str, Dict[str, int]]] = [REFERENCE] + [parse_arch(a) for a in (args.arch or ["unet2p1d"])]

    clips = nrdepth.generate_clips(args.batch, seed=0)
    generator = rate(lambda: nrdepth.generate_clips(args.batch, seed=1), args.batch, args.steps)
    video = torch.from_numpy(clips.video).float().div(255).unsqueeze(1)
    target = torch.nn.functional.avg_pool2d(torch.from_numpy(clips.depth), 2)
    loss_fn = get_loss(args.loss)
    devices = ["cpu"] + (["cuda"] if torch.cuda.is_available() else [])
    print(f"batch {args.batch} of 16×64×64, loss {args.loss}, torch threads {torch.get_num_threads()}; clip generator {generator:.1f} clips/s")
    print(f"{'architecture':54s}{'params':>10s}{'GFLOP/patch':>13s}{'device':>8s}{'train/s':>10s}{'×ref':>7s}{'infer/s':>10s}{'×ref':>7s}")
    for device in devices:
        reference: Dict[str, float] = {}
        for name, config in archs:
            torch.manual_seed(0)
            model = build_model(name, **config)
            flops = forward_flops(model)
            model = model.to(device)
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

            train_rate, infer_rate = rate(step, args.batch, args.steps), rate(infer, args.batch, args.steps)
            if not reference:
                reference = {"train": train_rate, "infer": infer_rate}
            label = f"{name}({', '.join(f'{k}={v}' for k, v in model.config.items())})"
            print(f"{label:54s}{count_parameters(model):>10,}{flops / 1e9:>13.2f}{device:>8s}{train_rate:>10.2f}{train_rate / reference['train']:>6.1f}×"
                  f"{infer_rate:>10.2f}{infer_rate / reference['infer']:>6.1f}×")


if __name__ == "__main__":
    main()
