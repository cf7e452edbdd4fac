"""Which pass sets the stitched score: the coarse pass or the patches?

`reconstruct` reads a video twice: once whole, resized to 64×64 (the
coarse pass), and in 64×64×16 patches at full resolution, which the
default stitch aligns to the coarse pass and to each other. This script
stitches every model's coarse pass with every model's patches on
`bench_reconstruct.py`'s generated 256×256×16 videos (inside and outside
the training ranges; the default stitch) and prints MAE-SN per frame / from
the first frame, each pairing paired against the first model's own
(mean difference over the videos ± its standard error). On the real cloth
the same table is `real_scales.py --cross`.

    python experiments/coarse_or_patches.py MODEL MODEL [...] [--videos 8] [--seed S]    # 'default' is the shipped model
"""

from __future__ import annotations

import argparse

import numpy as np
import torch

import nrdepth

from nrdepth.scores.generated import out_of_range
from nrdepth.learning.evaluate import TEST_SEED
from nrdepth.reconstruct import coarse_depth, inference_model, patch_depths


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("models", nargs="+", help="model.safetensors or run folder; 'default' for the shipped model")
    parser.add_argument("--videos", type=int, default=8, help="videos inside and outside the ranges each")
    parser.add_argument("--seed", type=int, default=TEST_SEED)
    args = parser.parse_args()
    if len(args.models) < 2:
        parser.error("name two or more models")
    device = torch.device("cpu")
    nets = [inference_model(None if m == "default" else m, device) for m in args.models]
    base = nrdepth.GeneratorConfig(size=256)
    print(f"stitched MAE-SN per frame / from the 1st frame, {args.videos} videos (seed {args.seed}); coarse pass of model c, patches of model p")
    for i, m in enumerate(args.models):
        print(f"  model {i}: {m}")
    for name, config in (("inside the training ranges", base), ("outside them", out_of_range(base))):
        clips = nrdepth.generate_clips(args.videos, seed=args.seed, config=config)
        scores = {}
        for video, truth in zip(clips.video, clips.depth):
            layout = nrdepth.patch_layout(video.shape)
            coarse = [coarse_depth(video, net, 8, device) for net in nets]
            patches = [np.concatenate([d for _, d in patch_depths(video, net, layout, 8, device)]) for net in nets]
            for c in range(len(nets)):
                for p in range(len(nets)):
                    depth = nrdepth.stitch(patches[p], coarse[c], layout)
                    scores.setdefault((c, p), []).append([nrdepth.mae_sn(depth, truth, a) for a in ("frame", "first")])
        print(name)
        reference = np.array(scores[0, 0])
        for (c, p), values in scores.items():
            v = np.array(values)
            d = v - reference
            se = d.std(0, ddof=1) / np.sqrt(len(d))
            print(f"  c {c}, p {p}: {v[:, 0].mean():.4f} / {v[:, 1].mean():.4f}   against c 0, p 0: "
                  f"{d[:, 0].mean():+.4f} ± {se[0]:.4f} / {d[:, 1].mean():+.4f} ± {se[1]:.4f}")


if __name__ == "__main__":
    main()
