"""Does a light from below cost a backdrops-trained model at a sheet's
border on generated clips, as turning ``phisft_R1`` suggests for the real
cloth (docs/findings.md)? Clips that all show the sheet's border over a
background (``backdrop_probability=1``), lit from above (±70° about
image-up, the default) and from below (the same about image-down), read by
each model; MAE-SN per frame over the sheet, split into its border (within
3 output pixels of the background) and its inside, and each model paired
against the first on the same clips (mean difference ± its standard error).

``--black`` makes every background flat black, as the cloth's matte is.

    python experiments/border_light.py MODEL MODEL [...] [--clips 128] [--black]     # 'default' is the shipped model
"""

from __future__ import annotations

import argparse
import math

import numpy as np
import torch
from scipy.ndimage import distance_transform_edt

import nrdepth
from nrdepth.learning.evaluate import TEST_SEED
from nrdepth.scores.metrics import gbr_align, mae_sn, sign_rates
from nrdepth.model import DEFAULT_MODEL
from nrdepth.model.io import load_model, predict_depth

BORDER = 3
"""Output pixels (half the clip's resolution) from the background that count as the border."""


def scores(net, video: np.ndarray, truth: np.ndarray, on: np.ndarray, border: np.ndarray) -> np.ndarray:
    """Per clip: MAE-SN per frame, its border and inside parts, the share of frames with the right sign."""
    rows = []
    for p, g, m, b in zip(predict_depth(net, video, 8), truth, on, border):
        g = np.where(m, g, np.nan)
        spread = np.array([f[k].std() for f, k in zip(g, m)])[:, None, None]
        error = np.abs(gbr_align(p, g, "frame", mask=m) - g) / spread
        rows.append((mae_sn(p, g, "frame", mask=m), error[b].mean(), error[m & ~b].mean(), sign_rates(p, g, mask=m)["sign_correct"]))
    return np.array(rows)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("models", nargs="+", help="model.safetensors or run folder; 'default' for the shipped model")
    parser.add_argument("--clips", type=int, default=128)
    parser.add_argument("--black", action="store_true", help="flat black backgrounds")
    args = parser.parse_args()
    nets = {m: load_model(DEFAULT_MODEL if m == "default" else m, device="cpu") for m in args.models}
    half_width = math.radians(70)
    for side, centre in (("above", 0.0), ("below", math.pi)):
        black = {"backdrop_flat_probability": 1.0, "backdrop_brightness": (0.0, 0.0)} if args.black else {}
        config = nrdepth.GeneratorConfig(backdrop_probability=1.0, light_azimuth=(centre - half_width, centre + half_width), **black)
        clips = nrdepth.generate_clips(args.clips, seed=TEST_SEED, config=config)
        pool = lambda a: torch.nn.functional.avg_pool2d(torch.from_numpy(a).float(), 2).numpy()  # noqa: E731
        truth = pool(np.nan_to_num(clips.depth, nan=0.0))
        on = pool(np.isfinite(clips.depth).astype(np.float32)) == 1.0  # output pixels wholly on the sheet
        border = np.stack([[distance_transform_edt(frame) <= BORDER for frame in clip] for clip in on]) & on
        table = {m: scores(net, clips.video, truth, on, border) for m, net in nets.items()}
        print(f"{args.clips} clips with a border{' over black' if args.black else ''}, lit from {side}:        frame  border  inside  sign right   paired with {args.models[0]}: frame, border")
        for m, rows in table.items():
            d = rows - table[args.models[0]]
            se = d.std(axis=0, ddof=1) / math.sqrt(len(d))
            print(f"  {m[-40:]:40s}{rows[:, 0].mean():8.4f}{rows[:, 1].mean():8.4f}{rows[:, 2].mean():8.4f}{rows[:, 3].mean():8.2f}   "
                  f"{d[:, 0].mean():+.4f} ± {se[0]:.4f}, {d[:, 1].mean():+.4f} ± {se[1]:.4f}", flush=True)


if __name__ == "__main__":
    main()
