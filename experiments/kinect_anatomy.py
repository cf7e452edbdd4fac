"""Where a model's error on ``kinect_paper`` (the real bending sheet, sparse
truth in mm) comes from: for the whole sheet (``nrdepth.scores.real.KINECT_ROI``) and
a crop inside it (``KINECT_INNER``), the stitched depth as ``reconstruct``
gives it, the coarse pass alone (the crop resized to 64×64, the reading
every window is aligned to), and each frame of the stitched depth replaced
by its least-squares quadratic in x, y (its large-scale shape alone; the
truth's own best quadratic scores 2.84 and 2.73 mm).

    python experiments/kinect_anatomy.py [MODEL ...]      # 'default' (or nothing) is the shipped model
"""

from __future__ import annotations

import argparse

import numpy as np
import torch

from nrdepth.scores.real import DATA, KINECT_INNER, KINECT_ROI, kinect_score, kinect_truth

import nrdepth  # noqa: E402
from nrdepth.reconstruct import coarse_depth, inference_model  # noqa: E402
from nrdepth.io import read_video  # noqa: E402


def quadratic(depth: np.ndarray) -> np.ndarray:
    """Each frame of ``depth`` (T, H, W) replaced by its least-squares quadratic in x, y."""
    t, h, w = depth.shape
    y, x = np.mgrid[0:h, 0:w].astype(np.float64) / max(h, w)
    design = np.stack([np.ones(h * w), x.ravel(), y.ravel(), x.ravel() ** 2, (x * y).ravel(), y.ravel() ** 2], 1)
    coef = np.linalg.lstsq(design, depth.reshape(t, -1).T.astype(np.float64), rcond=None)[0]
    return (design @ coef).T.reshape(t, h, w)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("models", nargs="*", default=["default"], help="model.safetensors or run folder; 'default' for the shipped model")
    args = parser.parse_args()
    truth = kinect_truth()
    frames = read_video(DATA / "kinect_paper").frames
    cpu = torch.device("cpu")
    print("kinect_paper, MAE on the sparse truth (mm): stitched / coarse pass alone / the stitched depth's quadratic part")
    for name in args.models:
        net = inference_model(None if name == "default" else name, cpu)
        row = []
        for label, region in (("whole sheet", KINECT_ROI), ("inside", KINECT_INNER)):
            x, y, w, h = region
            video = frames[:, y : y + h, x : x + w]
            stitched = nrdepth.reconstruct(video, net, sheet_stage=False)
            coarse = coarse_depth(video, net, 8, cpu)
            row.append(f"{label} {kinect_score(stitched, truth, region):.2f} / {kinect_score(coarse, truth, region):.2f} / "
                       f"{kinect_score(quadratic(stitched), truth, region):.2f}")
        print(f"{name}: " + ", ".join(row), flush=True)


if __name__ == "__main__":
    main()
