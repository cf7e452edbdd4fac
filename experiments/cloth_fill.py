"""Does the black matte around ``phisft_R1``'s cloth mislead the network?
Its hem is where checkpoints differ (docs/findings.md), and a border over a
background is what the training clips rarely show. Here the pixels off the
cloth (gray 0; no ground truth used) are filled before the network sees
them, and the depth is scored on the same pixels as always:

- ``black``: the frames as they are;
- ``nearest``: each pixel off the cloth takes its nearest cloth pixel's gray;
- ``smooth``: a smooth continuation (normalised convolution, coarse to
  fine: the local mean of the cloth, no texture, no step).

Each filled video is read with and without ``mask=`` (the cloth) for the
alignments. MAE-SN per frame and from the first frame, and per frame split
into the border and the inside (``nrdepth.scores.real.phisft_regions``).

    python experiments/cloth_fill.py [MODEL ...]      # 'default' (or nothing) is the shipped model
"""

from __future__ import annotations

import sys

import numpy as np
from scipy.ndimage import distance_transform_edt, gaussian_filter

from nrdepth.scores.real import phisft_at_bin, phisft_regions, region_errors

import nrdepth  # noqa: E402
from nrdepth.scores.metrics import flat_baseline, mae_sn  # noqa: E402


def fill_nearest(frame: np.ndarray, on: np.ndarray) -> np.ndarray:
    rows, cols = distance_transform_edt(~on, return_distances=False, return_indices=True)
    return frame[rows, cols]


def fill_smooth(frame: np.ndarray, on: np.ndarray) -> np.ndarray:
    """Off-cloth pixels from the cloth's normalised Gaussian means, the
    finest scale that reaches them winning (sigma 2, 4, ... 64 px)."""
    out = frame.astype(np.float64)
    todo = ~on
    weight = on.astype(np.float64)
    for sigma in (2, 4, 8, 16, 32, 64):
        mass = gaussian_filter(weight, sigma)
        mean = gaussian_filter(frame * weight, sigma) / np.maximum(mass, 1e-12)
        take = todo & (mass > 1e-3)
        out[take] = mean[take]
        todo &= ~take
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)


def main() -> None:
    video, truth = phisft_at_bin(4)
    scored = np.isfinite(truth)
    cloth = video > 0
    regions = phisft_regions(video, truth)
    print(f"plane: per frame {flat_baseline(truth, 'frame', mask=scored):.4f}, from the first frame {flat_baseline(truth, 'first', mask=scored):.4f}")
    fills = {
        "black": video,
        "nearest": np.stack([fill_nearest(f, m) for f, m in zip(video, cloth)]),
        "smooth": np.stack([fill_smooth(f, m) for f, m in zip(video, cloth)]),
    }
    print(f"{'model':40s}{'fill':>8s}{'mask':>6s}{'frame':>8s}{'first':>8s}{'border':>8s}{'inside':>8s}")
    for model in sys.argv[1:] or ["default"]:
        for fill, frames in fills.items():
            for masked in (False, True):
                depth = nrdepth.reconstruct(frames, None if model == "default" else model, mask=cloth if masked else None, sheet_stage=False)
                r = region_errors(depth, truth, regions)
                print(f"{model[-40:]:40s}{fill:>8s}{'cloth' if masked else 'none':>6s}{mae_sn(depth, truth, 'frame', mask=scored):>8.4f}"
                      f"{mae_sn(depth, truth, 'first', mask=scored):>8.4f}{r['border']:>8.4f}{r['inside']:>8.4f}", flush=True)


if __name__ == "__main__":
    main()
