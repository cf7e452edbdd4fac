"""Does the background corrupt the stitcher's alignments on ``phisft_R1``?
Its crop (``nrdepth.scores.real.CROP``) shows the cloth's hem over the data set's
black matte, and what separates checkpoints per frame is the cloth's border
(docs/campaign.md). ``reconstruct(mask=...)`` leaves pixels off the surface
out of every alignment; here the mask is the cloth as the frames show it
(gray > 0, no ground truth used). Both readings are scored on the same
pixels: MAE-SN per frame and from the first frame, and the per-frame error
split into the border (within ``nrdepth.scores.real.PHISFT_BORDER`` pixels of the
matte) and the inside.

    python experiments/cloth_mask.py [MODEL ...]      # 'default' (or nothing) is the shipped model
"""

from __future__ import annotations

import sys

import numpy as np

from nrdepth.scores.real import CROP, DATA, phisft_regions, region_errors

import nrdepth  # noqa: E402
from nrdepth.scores.metrics import flat_baseline, mae_sn  # noqa: E402


def main() -> None:
    data = np.load(DATA / "phisft_R1" / "derived_q4.npz")
    top, bottom, left, right = CROP
    video, truth = data["gray"][:, top:bottom, left:right], data["depth"][:, top:bottom, left:right]
    scored = np.isfinite(truth)
    cloth = video > 0
    assert not (scored & ~cloth).any(), "every scored pixel is on the cloth, so both readings are scored alike"
    regions = phisft_regions(video, truth)
    print(f"plane: per frame {flat_baseline(truth, 'frame', mask=scored):.4f}, from the first frame {flat_baseline(truth, 'first', mask=scored):.4f}; "
          f"the cloth covers {cloth.mean() * 100:.1f} % of the crop")
    print(f"{'model':58s}{'mask':>7s}{'frame':>8s}{'first':>8s}{'border':>8s}{'inside':>8s}")
    for model in sys.argv[1:] or ["default"]:
        for name, mask in (("none", None), ("cloth", cloth)):
            depth = nrdepth.reconstruct(video, None if model == "default" else model, mask=mask, sheet_stage=False)
            r = region_errors(depth, truth, regions)
            print(f"{model[-58:]:58s}{name:>7s}{mae_sn(depth, truth, 'frame', mask=scored):>8.4f}{mae_sn(depth, truth, 'first', mask=scored):>8.4f}"
                  f"{r['border']:>8.4f}{r['inside']:>8.4f}")


if __name__ == "__main__":
    main()
