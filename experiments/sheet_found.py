"""Does holding points to the first frame find the sheet in the video
(issue 71, the sheet found in the video)? On ``kinect_paper``, points on
a grid over the whole sheet's box (``KINECT_ROI``: the paper, its white
margin, the shirt, the hands and the wall) are held to their look in the
first frame (``track_grid(hold=True)``, every point kept), and each
point's share of frames held is compared between the points on the print
(inside the hull of the truth's 301 points in the first frame with truth)
and the rest. ``--picture``: the first frame with each point coloured
from red (never held) to green (always).

    python experiments/sheet_found.py [--picture docs/reconstruction/sheet_found.jpg]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--picture", type=Path, default=None)
    args = parser.parse_args()
    import cv2
    from matplotlib.path import Path as Polygon

    from nrdepth import isometric
    from nrdepth.reconstruct.sheet import FLOW_MARGIN

    MIN_HELD = 0.8  # the stage's held gate on the point-frames when this was read (since: the points read, sheet.MIN_READ)
    from nrdepth.scores.real import KINECT_ROI, kinect_truth, kinect_video

    frames, truth = kinect_video(), kinect_truth()
    x, y, w, h = KINECT_ROI
    box = np.zeros(frames.shape[1:], bool)
    box[y : y + h, x : x + w] = True
    xy = isometric.track_grid(frames, box, points=400, hold=True, margin=FLOW_MARGIN)
    share = np.isfinite(xy[1:]).all(axis=2).mean(axis=0)
    hull = cv2.convexHull(truth["uv"][0].T.astype(np.float32)).reshape(-1, 2)
    on_print = Polygon(hull).contains_points(xy[0])
    for name, where in (("on the print", on_print), ("elsewhere", ~on_print)):
        print(f"{where.sum()} points {name}: held in a median {np.median(share[where]):.2f} of the frames, "
              f"{100 * (share[where] >= MIN_HELD).mean():.0f} % of them in at least {MIN_HELD:g}")
    if args.picture is not None:
        picture = cv2.cvtColor(frames[0], cv2.COLOR_GRAY2BGR)
        for point, held in zip(xy[0], share):
            cv2.circle(picture, (int(round(point[0])), int(round(point[1]))), 3, (0, int(255 * held), int(255 * (1 - held))), -1)
        cv2.imwrite(str(args.picture), picture)
        print(f"wrote {args.picture}")


if __name__ == "__main__":
    main()
