"""Does reading the real bending paper at other working sizes, or averaging
several, bring its large-scale shape? ``reconstruct`` at each ``max_side``
(the default 480 and smaller, where one patch sees more of the sheet), and
averages of several, each aligned to the default reading by one GBR (one
relief scale for the video, each frame's plane its own), scored in mm on
``gt_mdh.npz`` for the whole sheet and the crop inside it.

    python experiments/kinect_scales.py [MODEL]      # 'default' (or nothing) is the shipped model
"""

from __future__ import annotations

import argparse

import numpy as np
import torch

from nrdepth.scores.real import DATA, KINECT_INNER, KINECT_ROI, kinect_score, kinect_truth

import nrdepth  # noqa: E402
from nrdepth.reconstruct import MAX_SIDE, inference_model  # noqa: E402
from nrdepth.io import read_video  # noqa: E402

SIDES = (96, 128, 192, 256, MAX_SIDE)
AVERAGES = ((128, MAX_SIDE), (96, 128, 192), SIDES)


def aligned_to(depth: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """``depth`` (T, H, W) with each frame's plane replaced by the
    reference's and its relief scaled by the one least-squares factor for
    the video: the GBR, up to which both are defined, that brings it closest."""
    t, h, w = depth.shape
    y, x = np.mgrid[0:h, 0:w]
    design = np.stack([x.ravel(), y.ravel(), np.ones(h * w)], 1).astype(np.float64)
    pseudo = np.linalg.pinv(design)
    def split(video):
        frames = video.reshape(t, -1).astype(np.float64)
        plane = (design @ (pseudo @ frames.T)).T
        return frames - plane, plane
    relief, _ = split(depth)
    reference_relief, reference_plane = split(reference)
    scale = (relief * reference_relief).sum() / (relief * relief).sum()
    return (scale * relief + reference_plane).reshape(t, h, w)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("model", nargs="?", default="default", help="model.safetensors or run folder; 'default' for the shipped model")
    args = parser.parse_args()
    truth, frames = kinect_truth(), read_video(DATA / "kinect_paper").frames
    net = inference_model(None if args.model == "default" else args.model, torch.device("cpu"))
    print("kinect_paper, MAE on the sparse truth (mm), by working size (max_side) and averages of several")
    for label, region in (("whole sheet", KINECT_ROI), ("inside", KINECT_INNER)):
        x, y, w, h = region
        video = frames[:, y : y + h, x : x + w]
        depths = {side: nrdepth.reconstruct(video, net, max_side=side, sheet_stage=False) for side in SIDES}
        row = [f"{side}: {kinect_score(depths[side], truth, region):.2f}" for side in SIDES]
        row += [f"mean of {'+'.join(map(str, sides))}: {kinect_score(np.mean([aligned_to(depths[s], depths[MAX_SIDE]) for s in sides], 0), truth, region):.2f}"
                for sides in AVERAGES]
        print(f"{label}: " + ", ".join(row), flush=True)


if __name__ == "__main__":
    main()
