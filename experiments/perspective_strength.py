"""How strongly perspective shows on the real paper and on generated
sheets: per frame, the sheet's depth range (5th to 95th percentile) and
its lateral extent (the wider of x and y, the same percentiles), each over
its median distance from the camera; the median over frames, then over
sheets. A sheet that spans little of its distance in depth and across is
seen nearly orthographically, and its reading would bear a wrong focal
length lightly (docs/campaign.md, "What comes next").

kinect_paper: the 301 truth points of its 23 frames through the Kinect's
camera (528 px, centre 320, 240). Generated: ``sheet_levers.py``'s
paper-like sheets (``--set`` as its ``$P``), every 4th frame's depth over
the sheet through the clip's own pinhole.

    python experiments/perspective_strength.py [--videos 8] [--start 480]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from nrdepth import generate_clips
from nrdepth.scores.real import kinect_truth

sys.path.insert(0, str(Path(__file__).parent))
from isometric_generated import SEED, camera, long_sheets, setting  # noqa: E402

PAPER_LIKE = ("backdrop_probability=1", "backdrop_flat_probability=0", "sheet_bend_angle=-3,3", "sheet_bends=2,3", "sheet_relief=0,0")


def spans(z: np.ndarray, x: np.ndarray, y: np.ndarray) -> tuple:
    """(depth range, lateral extent), each over the median distance, of points at depths ``z`` and places ``x``, ``y``."""
    width = lambda v: np.percentile(v, 95) - np.percentile(v, 5)  # noqa: E731
    distance = np.median(z)
    return width(z) / distance, max(width(x), width(y)) / distance


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--videos", type=int, default=8, help="generated sheets per light")
    parser.add_argument("--start", type=int, default=480)
    args = parser.parse_args()
    truth, focal, (cx, cy) = kinect_truth(), 528.0, (320.0, 240.0)
    z, (u, v) = truth["z"], truth["uv"].transpose(1, 0, 2)
    paper = np.median([spans(z[t], (u[t] - cx) * z[t] / focal, (v[t] - cy) * z[t] / focal) for t in range(len(z))], axis=0)
    print(f"kinect_paper: depth range {paper[0]:.3f} of its distance, lateral extent {paper[1]:.3f}")
    sheets = []
    for light in ("below", "above"):
        clips = generate_clips(args.videos, seed=SEED, config=long_sheets(64, 4, ["print"], light, [setting(s) for s in PAPER_LIKE]), start=args.start)
        for depth, params in zip(clips.depth, clips.params):
            f, (px, py) = camera(params, depth.shape[1])
            frames = []
            for d in depth[::4]:
                rows, cols = np.nonzero(np.isfinite(d))
                Z = d[rows, cols]
                frames.append(spans(Z, (cols - px) * Z / f, (rows - py) * Z / f))
            sheets.append(np.median(frames, axis=0))
    sheets = np.array(sheets)
    for k, name in enumerate(("depth range", "lateral extent")):
        print(f"{len(sheets)} generated paper-like sheets (clips {args.start}–{args.start + args.videos - 1}, both lights): {name} "
              f"{np.median(sheets[:, k]):.3f} of their distance (10th–90th percentile {np.percentile(sheets[:, k], 10):.3f}–"
              f"{np.percentile(sheets[:, k], 90):.3f})")


if __name__ == "__main__":
    main()
