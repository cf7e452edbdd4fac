"""Reconstruction of whole videos: time and accuracy.

1. Time to reconstruct a 256×256×16 video, split into the network half
   (coarse pass + every patch, with cutting and resizing) and the Rust half
   (alignment and overlap-add, temporal alignment), on the CPU and on CUDA
   when present. The shipped model unless --model.
2. The stitched MAE-SN of generated 256×256×16 videos drawn inside the
   training ranges and, as in the paper's second experiment, outside them
   (stronger, more flexible, more folded, faster surfaces), both alignments,
   beside the flat baseline, without temporal alignment (the default, and
   the paper's method) and with it; and the stitched relief's contrast at the
   32-pixel patch period (``nrdepth.grid_contrast``: seams), beside the truth's.

    python benchmarks/bench_reconstruct.py [--model PATH] [--videos 8] [--repeats 3]
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np
import torch

import nrdepth
from nrdepth.evaluate import TEST_SEED
from nrdepth import _core
from nrdepth.stitch import coarse_depth, inference_model, patch_depths, temporal_align


def out_of_range(config: nrdepth.GeneratorConfig) -> nrdepth.GeneratorConfig:
    """Each of the four shape parameters drawn above its training range:
    from the training maximum to 1.6× it (constraint is left alone: it only
    confines motion to the centre)."""
    s = config.surface
    beyond = {k: (getattr(s, k)[1], 1.6 * getattr(s, k)[1]) for k in ("intensity", "folding", "flexibility", "speed")}
    return dataclasses.replace(config, surface=dataclasses.replace(s, **beyond))


def timing(model, device: str, repeats: int) -> None:
    video = nrdepth.generate_clips(1, seed=TEST_SEED, config=nrdepth.GeneratorConfig(size=256)).video[0]
    dev = torch.device(device)
    net = inference_model(model, dev)
    layout = nrdepth.patch_layout(video.shape)

    def run() -> dict:
        seconds = {"network": 0.0, "stitch": 0.0, "temporal": 0.0}
        start = time.perf_counter()
        stitcher = _core.Stitcher(coarse_depth(video, net, 8, dev), layout.patch)
        chunks = patch_depths(video, net, layout, 8, dev)
        while True:
            try:
                origins, depth = next(chunks)
            except StopIteration:
                break
            middle = time.perf_counter()
            seconds["network"] += middle - start
            stitcher.add(depth, origins)
            start = time.perf_counter()
            seconds["stitch"] += start - middle
        seconds["network"] += time.perf_counter() - start
        stitched = stitcher.finish()
        start = time.perf_counter()
        temporal_align(stitched)
        seconds["temporal"] = time.perf_counter() - start
        return seconds

    run()  # warm-up
    best = min((run() for _ in range(repeats)), key=lambda s: sum(s.values()))
    print(f"256×256×16 on {device} ({len(layout.origins)} patches + {-(-len(video) // 16)} coarse window(s), torch threads "
          f"{torch.get_num_threads()}), best of {repeats}: total {sum(best.values()):.2f} s = network {best['network']:.2f} s "
          f"+ stitching {best['stitch'] * 1e3:.0f} ms + temporal alignment {best['temporal'] * 1e3:.0f} ms")


def accuracy(model, videos: int, device: str) -> None:
    base = nrdepth.GeneratorConfig(size=256)
    print(f"MAE-SN over {videos} generated 256×256×16 videos (seed {TEST_SEED}), mean ± std")
    print(f"{'':34s}{'per frame':>18s}{'from 1st frame':>18s}")
    for name, config in (("inside training ranges", base), ("outside training ranges", out_of_range(base))):
        clips = nrdepth.generate_clips(videos, seed=TEST_SEED, config=config)
        rows = {"nrdepth (default, as the paper)": [], "with temporal_align": [], "flat baseline": []}
        grid = []
        for video, truth in zip(clips.video, clips.depth):
            raw = nrdepth.reconstruct(video, model, device=device, temporal=False)
            grid.append((nrdepth.grid_contrast(raw), nrdepth.grid_contrast(truth)))
            for key, depth in (("nrdepth (default, as the paper)", raw), ("with temporal_align", temporal_align(raw))):
                rows[key].append([nrdepth.mae_sn(depth, truth, a) for a in ("frame", "first")])
            rows["flat baseline"].append([nrdepth.flat_baseline(truth, a) for a in ("frame", "first")])
        print(name)
        for key, values in rows.items():
            v = np.array(values)
            print(f"  {key:32s}{v[:, 0].mean():>9.4f} ± {v[:, 0].std():.4f}{v[:, 1].mean():>9.4f} ± {v[:, 1].std():.4f}")
        g = np.array(grid)
        print(f"  contrast at the 32-pixel patch period: reconstruction {g[:, 0].mean():.3f} ± {g[:, 0].std():.3f}, truth {g[:, 1].mean():.3f} "
              f"± {g[:, 1].std():.3f} (about 1 without a grid; seams show above the truth's, missing grid frequencies below)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--model", default=None, help="model.safetensors or run folder (default: the shipped model)")
    parser.add_argument("--videos", type=int, default=8)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    devices = ["cpu"] + (["cuda"] if torch.cuda.is_available() else [])
    for device in devices:
        timing(args.model, device, args.repeats)
    accuracy(args.model, args.videos, devices[-1])


if __name__ == "__main__":
    main()
