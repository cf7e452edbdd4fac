"""Where a model's error on ``phisft_R1`` (the real cloth) comes from. Its
crop (``nrdepth.scores.real.CROP``) shows the cloth's hem and left edge over the data
set's black background, about 5 % of the crop at frame 0 and a quarter by
the end; the score counts only the cloth's pixels with ground truth.

For each model, MAE-SN per frame and from the first frame of:

- the stitched depth, as ``reconstruct`` gives it;
- the coarse pass alone (the crop resized to 64×64, the reading every window
  is aligned to);
- the first-frame figure split by time (frames 0–16, 17–33, 34–49), beside
  the background's share of the crop and the flat plane's figure;
- "own τ": frame 0's GBR with each frame's own depth offset
  (``align="first_offset"``): what is left once the cloth's motion along
  the optical axis is given, which no orthographic frame shows (the
  training target leaves it out: ``--target observable``);
- the per-frame error split into the cloth's border (within
  ``nrdepth.scores.real.PHISFT_BORDER`` pixels of the background) and its inside;
- "own plane": frame 0's relief scale λ kept, each frame's plane (α, β, τ)
  fitted anew: what is left when only the plane's motion is given.

The truth's mean depth is printed too: the cloth recedes over the video.

    python experiments/cloth_anatomy.py [MODEL ...]      # 'default' (or nothing) is the shipped model
    python experiments/cloth_anatomy.py --fill 128 ...    # the background painted gray 128 first
"""

from __future__ import annotations

import argparse

import numpy as np
import torch

from nrdepth.scores.real import CROP, DATA, PHISFT_BORDER, phisft_regions, region_errors, scaled_error

import nrdepth  # noqa: E402
from nrdepth.scores.metrics import gbr_align, gbr_fit, mae_sn  # noqa: E402
from nrdepth.reconstruct import coarse_depth, inference_model  # noqa: E402

THIRDS = (slice(0, 17), slice(17, 34), slice(34, 50))


def by_third(aligned: np.ndarray, truth: np.ndarray, mask: np.ndarray) -> list:
    """MAE-SN of an aligned depth over the whole video, then over each third of it."""
    per_frame = [e[m].mean() for e, m in zip(scaled_error(aligned, truth), mask)]
    return [float(np.mean(per_frame))] + [float(np.mean(per_frame[s])) for s in THIRDS]


def thirds(values: list) -> str:
    return f"{values[0]:.3f} (by third {' / '.join(f'{v:.3f}' for v in values[1:])})"


def own_plane(depth: np.ndarray, truth: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Each frame of ``depth`` times frame 0's least-squares λ, plus the
    plane (α x + β y + τ) that fits that frame's remainder best."""
    scale = gbr_fit(depth[0] / np.abs(depth).max(), truth[0], mask[0])[2] / np.abs(depth).max()
    h, w = depth.shape[1:]
    y, x = np.mgrid[0:h, 0:w]
    plane = np.column_stack([x.ravel(), y.ravel(), np.ones(h * w)])
    out = []
    for p, g, m in zip(depth, truth, mask):
        relief = scale * p
        coef = np.linalg.lstsq(plane[m.ravel()], (g - relief)[m], rcond=None)[0]
        out.append(relief + (plane @ coef).reshape(h, w))
    return np.stack(out)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("models", nargs="*", default=["default"], help="model.safetensors or run folder; 'default' for the shipped model")
    parser.add_argument("--fill", type=int, default=None, help="paint the background (gray 0) this gray level before reconstructing")
    args = parser.parse_args()
    data = np.load(DATA / "phisft_R1" / "derived_q4.npz")
    top, bottom, left, right = CROP
    video, truth = data["gray"][:, top:bottom, left:right], data["depth"][:, top:bottom, left:right]
    mask = np.isfinite(truth)
    regions = phisft_regions(video, truth)
    background = [(video[s] == 0).mean() for s in THIRDS]
    if args.fill is not None:
        video = np.where(video == 0, np.uint8(args.fill), video)
    print("phisft_R1, MAE-SN: per frame; from the first frame; with each frame's own τ; with each frame's own plane")
    print("background share of the crop by third: " + " / ".join(f"{100 * b:.0f} %" for b in background))
    flat = [mae_sn(np.zeros_like(truth), truth, a, mask=mask) for a in ("frame", "first", "first_offset")]
    flat_first = by_third(gbr_align(np.zeros_like(truth), truth, "first", mask=mask), truth, mask)
    print("the truth's median depth every 7th frame (m): " + " ".join(f"{np.nanmedian(f):.3f}" for f in truth[::7]))
    flat_regions = region_errors(np.zeros_like(truth), truth, regions)
    print(f"border: pixels within {PHISFT_BORDER} px of the background, {100 * regions['border'].sum() / mask.sum():.0f} % of the scored ones")
    print(f"flat plane: {flat[0]:.4f} (border {flat_regions['border']:.3f} inside {flat_regions['inside']:.3f}), "
          f"from the first frame {thirds(flat_first)}, own τ {flat[2]:.4f}")
    cpu = torch.device("cpu")
    for name in args.models:
        net = inference_model(None if name == "default" else name, cpu)
        readings = {"stitched": nrdepth.reconstruct(video, net, sheet_stage=False), "coarse": coarse_depth(video, net, 8, cpu)}
        row = []
        for label, depth in readings.items():
            frame, first, offset = (mae_sn(depth, truth, a, mask=mask) for a in ("frame", "first", "first_offset"))
            first_thirds = by_third(gbr_align(depth, truth, "first", mask=mask), truth, mask)
            given = by_third(own_plane(depth, truth, mask), truth, mask)
            split = region_errors(depth, truth, regions)
            row.append(f"{label} {frame:.4f} (border {split['border']:.3f} inside {split['inside']:.3f}), from the first frame "
                       f"{thirds(first_thirds)}, own τ {offset:.4f}, own plane {thirds(given)}")
        print(f"{name}: " + "; ".join(row), flush=True)


if __name__ == "__main__":
    main()
