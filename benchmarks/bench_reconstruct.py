"""Reconstruction of whole videos: time and accuracy.

1. Time to reconstruct a 256×256×16 video, split into the network half
   (coarse pass + every patch, with resizing) and the Rust half (stitching,
   temporal alignment), on the CPU and on CUDA when present.
2. The stitched MAE-SN of generated 256×256×16 videos drawn inside the
   training ranges and, as in the paper's second experiment, outside them
   (stronger, more flexible, more folded, faster surfaces), both alignments,
   beside the flat baseline, with and without temporal alignment (the
   paper's method is without).

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
from nrdepth.stitch import predict_patches, stitch, temporal_align
from nrdepth.train import load_model


def out_of_range(config: nrdepth.GeneratorConfig) -> nrdepth.GeneratorConfig:
    """Each of the four shape parameters drawn above its training range:
    from the training maximum to 1.6× it (constraint is left alone: it only
    confines motion to the centre)."""
    s = config.surface
    beyond = {k: (getattr(s, k)[1], 1.6 * getattr(s, k)[1]) for k in ("intensity", "folding", "flexibility", "speed")}
    return dataclasses.replace(config, surface=dataclasses.replace(s, **beyond))


def timing(model, device: str, repeats: int) -> None:
    video = nrdepth.generate_clips(1, seed=TEST_SEED, config=nrdepth.GeneratorConfig(size=256)).video[0]
    frames = video.astype(np.float32) / 255
    net = load_model(model, device=device)
    dev = torch.device(device)
    best = {"network": np.inf, "stitch": np.inf, "temporal": np.inf}
    predict_patches(frames, net, 8, dev)  # warm-up
    for _ in range(repeats):
        t0 = time.perf_counter()
        patches, coarse, layout = predict_patches(frames, net, 8, dev)
        if device.startswith("cuda"):
            torch.cuda.synchronize()
        t1 = time.perf_counter()
        stitched = stitch(patches, coarse, layout)
        t2 = time.perf_counter()
        temporal_align(stitched)
        t3 = time.perf_counter()
        for k, v in zip(best, (t1 - t0, t2 - t1, t3 - t2)):
            best[k] = min(best[k], v)
    total = sum(best.values())
    print(f"256×256×16 on {device} ({len(layout.origins)} patches + {-(-len(frames) // 16)} coarse window(s), torch threads "
          f"{torch.get_num_threads()}), best of {repeats}: total {total:.2f} s = network {best['network']:.2f} s "
          f"+ stitching {best['stitch'] * 1e3:.0f} ms + temporal alignment {best['temporal'] * 1e3:.0f} ms")


def accuracy(model, videos: int, device: str) -> None:
    base = nrdepth.GeneratorConfig(size=256)
    print(f"MAE-SN over {videos} generated 256×256×16 videos (seed {TEST_SEED}), mean ± std")
    print(f"{'':34s}{'per frame':>18s}{'from 1st frame':>18s}")
    for name, config in (("inside training ranges", base), ("outside training ranges", out_of_range(base))):
        clips = nrdepth.generate_clips(videos, seed=TEST_SEED, config=config)
        rows = {"nrdepth (temporal alignment)": [], "paper's stitching (no temporal)": [], "flat baseline": []}
        for video, truth in zip(clips.video, clips.depth):
            raw = nrdepth.reconstruct(video, model, device=device, temporal=False)
            for key, depth in (("nrdepth (temporal alignment)", temporal_align(raw)), ("paper's stitching (no temporal)", raw)):
                rows[key].append([nrdepth.mae_sn(depth, truth, a) for a in ("frame", "first")])
            rows["flat baseline"].append([nrdepth.flat_baseline(truth, a) for a in ("frame", "first")])
        print(name)
        for key, values in rows.items():
            v = np.array(values)
            print(f"  {key:32s}{v[:, 0].mean():>9.4f} ± {v[:, 0].std():.4f}{v[:, 1].mean():>9.4f} ± {v[:, 1].std():.4f}")


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
