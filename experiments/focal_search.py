"""The focal length from the video (issue 71, step 1): does the focal
length under which an inextensible reading keeps the pairs' lengths most
constant find the camera's?

For each video: ``track_grid``'s points (400, drop 0.2, as the sheet stage
follows them), ``--keyframes`` frames spread over the video, and for each
candidate focal length (``--candidates`` of them, log-spaced over
horizontal fields of view 20°–110°, the principal point at the frame's
centre, as a user without a calibration has it) the keyframes' depths by
``mdh_depths`` (``--template``: the joint cone program, or refined so that
each pair keeps one length), then each pair's length in every keyframe.
The criterion: the pairs' coefficient of variation over the keyframes
(standard deviation over mean), averaged over the pairs.

The rule, fixed before any figure was read: the estimate is the candidate
with the least criterion, refined by a parabola through it and its two
neighbours in log focal length; it is judged by the share of the
generated sheets (the selection set: ``--videos`` long sheets through
pinholes of 40–80°, lit from below and from above, a seed no other run
draws) within 25 % of the truth, and the real videos (``kinect_paper``,
its sheet's box; ``phisft_R1``, the cloth, full frames) are checks.

    python experiments/focal_search.py [--videos 16] [--frames 64] [--phases 4] [--template joint] [--hold [--keep 0.8]] [--start 0] [--families print] [--set FIELD=V] [--real [--kinect-box print]]
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

from nrdepth import Camera, generate_clips, isometric
from nrdepth.scores.generated import SHEET_FAMILIES
from nrdepth.isometric import held_share
from nrdepth.reconstruct.sheet import FLOW_MARGIN
from nrdepth.scores.real import DATA, FOCAL, KINECT_INNER, KINECT_ROI

MIN_HELD = 0.8
"""The stage's held gate on the point-frames when this was read (since: the points read, ``sheet.MIN_READ``)."""

sys.path.insert(0, str(Path(__file__).parent))
from isometric_generated import LIGHTS, camera, long_sheets, setting  # noqa: E402

SEED = 7171
"""A seed no training run or other benchmark draws from."""


def candidates(width: int, count: int) -> np.ndarray:
    """Focal lengths (pixels) of horizontal fields of view 110° down to 20°, log-spaced."""
    wide, narrow = (width / 2) / math.tan(math.radians(55)), (width / 2) / math.tan(math.radians(10))
    return np.geomspace(wide, narrow, count)


def length_variation(xy: np.ndarray, frame: tuple, focals: np.ndarray, keyframes: int, template: str) -> np.ndarray:
    """The criterion (module docstring) at each focal length."""
    keys = np.unique(np.rint(np.linspace(0, len(xy) - 1, keyframes)).astype(int))
    tracks = xy[keys]
    tracks = tracks[:, np.isfinite(tracks).all(axis=(0, 2))]  # points in view in every keyframe
    pairs = isometric.neighbour_pairs(tracks[0])
    centre = ((frame[1] - 1) / 2, (frame[0] - 1) / 2)
    out = []
    for focal in focals:
        cam = Camera(float(focal), centre)
        depths = isometric.mdh_depths(tracks, cam, pairs=pairs, keyframes=len(keys), template=template)
        points = cam.rays(tracks) * depths[..., None]
        lengths = np.linalg.norm(points[:, pairs[:, 0]] - points[:, pairs[:, 1]], axis=2)  # (K, E)
        out.append(float(np.mean(lengths.std(axis=0) / lengths.mean(axis=0))))
    return np.array(out)


def estimate(focals: np.ndarray, criterion: np.ndarray) -> float:
    """The least criterion's focal length, refined by a parabola in log focal length."""
    k = int(np.argmin(criterion))
    if k in (0, len(focals) - 1):
        return float(focals[k])
    x = np.log(focals[k - 1 : k + 2])
    a, b, _ = np.polyfit(x, criterion[k - 1 : k + 2], 2)
    return float(np.exp(-b / (2 * a))) if a > 0 else float(focals[k])


def kinect(box: tuple = KINECT_ROI) -> tuple:
    from nrdepth.io import read_video

    frames = read_video(DATA / "kinect_paper").frames
    K = np.load(DATA / "kinect_paper" / "gt_mdh.npz")["K"]
    x, y, w, h = box
    box = np.zeros(frames.shape[1:], bool)
    box[y : y + h, x : x + w] = True
    return frames, box, float(K[0, 0])


def phisft() -> tuple:
    from scipy.ndimage import binary_erosion

    from nrdepth.io import read_video

    frames = read_video(DATA / "phisft_R1" / "rgbs").frames
    return frames, binary_erosion(frames[0] > 10, iterations=8), FOCAL[0]


def read(name: str, video: np.ndarray, mask, truth: float, args) -> float:
    start = time.perf_counter()
    xy = isometric.track_grid(video, mask, drop=isometric.DROP, hold=args.hold, margin=FLOW_MARGIN)
    tracked = time.perf_counter() - start
    if args.hold and held_share(xy, video.shape[1:]) < MIN_HELD:
        print(f"{name}: the stage steps aside ({held_share(xy, video.shape[1:]):.2f} of the point-frames held)", flush=True)
        return math.nan
    if args.keep:  # after the gate, as the stage keeps them
        xy = xy[:, isometric.point_held_shares(xy, video.shape[1:]) >= args.keep]
    focals = candidates(video.shape[2], args.candidates)
    criterion = length_variation(xy, video.shape[1:], focals, args.keyframes, args.template)
    guess = estimate(focals, criterion)
    print(f"{name}: truth {truth:.1f} px, estimate {guess:.1f} px ({guess / truth:.2f}×); criterion "
          + " ".join(f"{f / truth:.2f}:{c:.4f}" for f, c in zip(focals, criterion))
          + f"  ({tracked:.0f} s tracking, {time.perf_counter() - start - tracked:.0f} s search)", flush=True)
    return guess / truth


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--videos", type=int, default=16, help="generated sheets for each light")
    parser.add_argument("--frames", type=int, default=64)
    parser.add_argument("--phases", type=int, default=4, help="spans of each video, each bending the sheet a new way")
    parser.add_argument("--keyframes", type=int, default=8)
    parser.add_argument("--candidates", type=int, default=9)
    parser.add_argument("--template", choices=("joint", "refined"), default="joint")
    parser.add_argument("--real", action="store_true", help="the real videos only")
    parser.add_argument("--hold", action="store_true", help="the points held to the first frame (track_grid's hold); a generated sheet "
                        "whose points are held in fewer point-frames than the sheet stage's MIN_HELD is left out, as the stage leaves it")
    parser.add_argument("--keep", type=float, default=0.0, help="with --hold: only the points held in at least this share of their "
                        "frames in view (isometric.point_held_shares), after the stage's gate, as the stage keeps them")
    parser.add_argument("--start", type=int, default=0, help="the first sheet's index in the seed's draws")
    parser.add_argument("--families", default=None, help="the generated sheets' texture families (comma-separated; default: every sheet family)")
    parser.add_argument("--set", action="append", default=[], metavar="FIELD=V[,V]", type=setting,
                        help="a GeneratorConfig field of the generated sheets, one value or lo,hi (e.g. the paper-like sheets' "
                        "backdrop_probability=1; over a backdrop the points start on the sheet), repeatable")
    parser.add_argument("--kinect-box", choices=("sheet", "print"), default="sheet",
                        help="with --real: kinect_paper's points over the whole sheet's box (KINECT_ROI, with background) or the print's (KINECT_INNER)")
    args = parser.parse_args()
    if args.keep and not args.hold:
        parser.error("--keep: needs --hold")
    if args.real:
        boxes = {"sheet": KINECT_ROI, "print": KINECT_INNER}
        for name, (video, mask, truth) in ((f"kinect_paper ({args.kinect_box})", kinect(boxes[args.kinect_box])), ("phisft_R1", phisft())):
            read(name, video, mask, truth, args)
        return
    ratios = []
    for light in LIGHTS:
        config = long_sheets(args.frames, args.phases, SHEET_FAMILIES if args.families is None else args.families.split(","), light, args.set)
        clips = generate_clips(args.videos, seed=SEED, config=config, start=args.start)
        for k, (video, depth, params) in enumerate(zip(clips.video, clips.depth, clips.params)):
            sheet = np.isfinite(depth[0])  # over a backdrop the points start on the sheet, as reconstruct(sheet=mask) puts them
            ratios.append(read(f"sheet {args.start + k} lit from {light}", video, None if sheet.all() else sheet, camera(params, config.size)[0], args))
    ratios = np.array(ratios)
    if np.isnan(ratios).any():
        print(f"{int(np.isnan(ratios).sum())} of {len(ratios)} sheets left out: the stage steps aside on them")
        ratios = ratios[np.isfinite(ratios)]
    within = np.abs(np.log(ratios)) <= math.log(1.25)
    print(f"{len(ratios)} sheets: estimate within 25 % of the truth on {100 * within.mean():.0f} %; ratio median {np.median(ratios):.2f}, "
          f"quartiles {np.percentile(ratios, 25):.2f}–{np.percentile(ratios, 75):.2f}; too short by more than 25 % on "
          f"{100 * np.mean(ratios < 0.8):.0f} %")


if __name__ == "__main__":
    main()
