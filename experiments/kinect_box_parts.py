"""Which of the points over ``kinect_paper``'s whole-sheet box (the roi a
user gives, ``KINECT_ROI``: the paper, its blank margins, the shirt, the
hands, the whiteboard) cost the sheet stage, and whether the one piece of
held points that moves most finds the paper.

The stage's points (400 over the box, drop 0.2, the flow over their box
and 48 px) are followed by the flow and, held to their look in the first
frame, by ``track_grid(hold=True)``; each is labelled by where it starts
in the first frame: on the paper (a quadrilateral drawn by hand round it,
the hands boxed out), on its print (one round the print), or off it. Each
subset is read as the stage reads its points (the Kinect's focal length,
``keyframes=12``, ``every=4``, ``each_frame="lengths"``) and fused with the
network's depth at 0.3, 0.1 and 0.05 of the box's shorter side: the whole
sheet's error in mm (per-frame GBR, ``kinect_score``). The hand-drawn
labels are a measurement's, not the job's; the last line is the job's
kind of reading: the held points kept (held in 0.8 of their frames in
view) that form one piece (neighbours within 1.5 grid spacings in the
first frame), the piece whose points move farthest in all.

    NRDEPTH_DATA=../shared/data/real python experiments/kinect_box_parts.py [--threads 2]
"""

from __future__ import annotations

import argparse

import numpy as np

PAPER = [(172, 80), (570, 108), (560, 370), (143, 368)]
PRINT = [(208, 92), (520, 104), (515, 368), (203, 348)]
HANDS = [[(60, 130), (170, 130), (170, 225), (60, 225)], [(555, 160), (640, 160), (640, 250), (555, 250)]]
"""The first frame's paper, its print and the hands (column, row), drawn by hand."""


def moving_piece(xy: np.ndarray, kept: np.ndarray, spacing: float) -> np.ndarray:
    """Of the points ``kept`` (n,) bool, those (n,) bool in the one piece (neighbours within 1.5 ``spacing`` in the first frame of
    ``xy`` (T, n, 2)) whose points move farthest from where they start, summed."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    index = np.flatnonzero(kept)
    pairs = np.array(sorted(cKDTree(xy[0, index]).query_pairs(1.5 * spacing)), dtype=int).reshape(-1, 2)
    _, label = connected_components(coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(index),) * 2), directed=False)
    farthest = np.fmax.reduce(np.linalg.norm(xy[:, index] - xy[:1, index], axis=2), axis=0, initial=0.0)
    piece = np.zeros(len(kept), bool)
    piece[index[label == np.argmax(np.bincount(label, weights=farthest))]] = True
    return piece


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--threads", type=int, default=2)
    args = parser.parse_args()

    import torch
    from matplotlib.path import Path

    import nrdepth
    from nrdepth import isometric
    from nrdepth.baselines.tracks import densify
    from nrdepth.reconstruct.sheet import KEEP_HELD
    from nrdepth.scores.real import KINECT_ROI, data_folder, kinect_score, kinect_truth, kinect_video

    torch.set_num_threads(args.threads)
    frames, truth = kinect_video(), kinect_truth()
    camera = nrdepth.Camera.from_matrix(np.load(data_folder("kinect_paper") / "gt_mdh.npz")["K"].astype(np.float64))
    x, y, w, h = KINECT_ROI
    box = np.zeros(frames.shape[1:], bool)
    box[y : y + h, x : x + w] = True
    network = nrdepth.reconstruct(frames, roi=KINECT_ROI, sheet_stage=False).astype(np.float64)
    print(f"network alone {kinect_score(network, truth):.2f} mm", flush=True)

    def read(name: str, xy: np.ndarray, keep: np.ndarray, paper: np.ndarray) -> None:
        depths = isometric.mdh_depths(xy[:, keep], camera, keyframes=12, every=4, each_frame="lengths")
        dense = densify(xy[:, keep] - np.array([x, y]), depths, network.shape)
        mm = [kinect_score(isometric.fuse(network, dense, scale * min(w, h)), truth) for scale in (0.3, 0.1, 0.05)]
        print(f"{name:44s} {keep.sum():4d} points ({paper[keep].sum()} on the paper): " + " / ".join(f"{m:.2f}" for m in mm)
              + " mm at 0.3 / 0.1 / 0.05", flush=True)

    for hold in (False, True):
        xy = isometric.track_grid(frames, box, points=400, drop=isometric.DROP, margin=48, hold=hold)
        hands = np.logical_or.reduce([Path(hand).contains_points(xy[0]) for hand in HANDS])
        paper = Path(PAPER).contains_points(xy[0]) & ~hands
        printed = Path(PRINT).contains_points(xy[0]) & paper
        if not hold:
            for name, keep in (("flow: all", np.ones(len(paper), bool)), ("flow: on the paper", paper), ("flow: on its print", printed),
                               ("flow: on its blank margins", paper & ~printed), ("flow: all but the margins", ~(paper & ~printed))):
                read(name, xy, keep, paper)
            continue
        kept = isometric.point_held_shares(xy, frames.shape[1:]) >= KEEP_HELD
        print(f"held: {isometric.held_share(xy, frames.shape[1:]):.2f} of the box's point-frames held", flush=True)
        for name, keep in (("held, kept", kept), ("held, kept, on the paper", kept & paper), ("held, kept, on its print", kept & printed),
                           ("held, kept, the piece that moves most", moving_piece(xy, kept, float(np.sqrt(box.sum() / 400))))):
            read(name, xy, keep, paper)


if __name__ == "__main__":
    main()
