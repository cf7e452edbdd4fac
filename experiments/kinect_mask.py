"""Would a segmentation of the sheet help on ``kinect_paper``? The person
behind the sheet and the hands holding it move on their own, which is where
``reconstruct(mask=...)`` should help (docs/stitching.md). Here the mask is
an oracle's: the convex hull of the ground truth's 301 points, interpolated
linearly between the 23 frames that have them (the nearest outside them),
widened by ``--margin`` pixels to reach the sheet's border. Both readings
are scored alike, on those points (``nrdepth.scores.real.kinect_score``), for the
whole sheet (``nrdepth.scores.real.KINECT_ROI``).

    python experiments/kinect_mask.py [MODEL ...] [--margin 15]     # 'default' (or nothing) is the shipped model
"""

from __future__ import annotations

import argparse

import numpy as np

from nrdepth.scores.real import DATA, KINECT_ROI, kinect_references, kinect_score, kinect_truth

import nrdepth  # noqa: E402
from nrdepth.io import read_video  # noqa: E402


def hull_masks(truth: dict, frames: int, shape: tuple, margin: int) -> np.ndarray:
    """bool (T, H, W): the points' convex hull in every frame, widened by ``margin`` pixels."""
    from matplotlib.path import Path
    from scipy.ndimage import distance_transform_edt
    from scipy.spatial import ConvexHull

    t = np.arange(frames)
    uv = truth["uv"]  # (23, 2, 301)
    at = np.stack([[np.interp(t, truth["frames"], uv[:, c, p]) for p in range(uv.shape[2])] for c in range(2)])  # (2, 301, T)
    rows, cols = np.mgrid[0 : shape[0], 0 : shape[1]]
    pixels = np.stack([cols.ravel(), rows.ravel()], axis=1)
    masks = np.empty((frames, *shape), bool)
    for k in range(frames):
        points = at[:, :, k].T  # (301, 2) as (u, v)
        hull = points[ConvexHull(points).vertices]
        inside = Path(hull).contains_points(pixels).reshape(shape)
        masks[k] = distance_transform_edt(~inside) <= margin
    return masks


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("models", nargs="*", default=["default"])
    parser.add_argument("--margin", type=int, default=15)
    args = parser.parse_args()
    frames = read_video(DATA / "kinect_paper").frames
    truth = kinect_truth()
    x, y, w, h = KINECT_ROI
    video = frames[:, y : y + h, x : x + w]
    masks = hull_masks(truth, len(frames), frames.shape[1:], args.margin)[:, y : y + h, x : x + w]
    base = kinect_references(truth, KINECT_ROI)
    print(f"kinect_paper, the whole sheet ({w}×{h} at x {x}, y {y}); the mask covers {masks.mean() * 100:.0f} % of it; "
          f"plane {base['plane']:.2f} mm, fixed bowl {base['bowl']:.2f}, best quadratic (oracle) {base['quadratic']:.2f}")
    print(f"{'model':58s}{'mask':>7s}{'mm':>8s}{'sign':>7s}")
    for model in args.models:
        for name, mask in (("none", None), ("hull", masks)):
            depth = nrdepth.reconstruct(video, None if model == "default" else model, mask=mask, sheet_stage=False)
            print(f"{model[-58:]:58s}{name:>7s}{kinect_score(depth, truth):>8.2f}{100 * kinect_score(depth, truth, signs=True):>6.0f}%")


if __name__ == "__main__":
    main()
