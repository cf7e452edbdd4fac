"""What limits the maximum-depth heuristic on ``kinect_paper``: the prior or
the tracks? The truth's own 301 points (``gt_mdh.npz``), their depths by
``nrdepth.isometric.mdh_depths`` (every frame solved together, 10
neighbours), scored as ``bench_real.py`` scores a depth (mm after each
frame's GBR) at the truth's points:

- at the truth's image positions (the Kinect's points projected: no
  tracking error), in its 23 frames;
- at positions followed from frame 8 by Lucas–Kanade (``track_video``'s
  settings) and by Farneback flow (``nrdepth.isometric``'s), over frames
  8–112, where Lucas–Kanade keeps them all (it loses them after 120);
  with each tracker's median distance from the truth's positions, to frame 184;
- followed from frame 8 to the end by ``track_points``'s flow both ways
  (``isometric_depth``'s tracker), every frame read with 24 keyframes as
  ``isometric_depth`` reads them, scored in the 23 frames with truth;
  ``--drop``: also without each share of the points whose two flows
  disagree most over the video (``track_grid``'s ``drop``), scored at the
  points kept, beside the truth's positions of those points.

``--template``: ``mdh_depths``'s template distances, each read in turn
(``joint``, ``refined``), with each of ``--each-frame`` (``mdh_depths``'s
``each_frame``: ``program``, ``lengths``, ``mirror``; ``--anchor`` its
``anchor``, for ``lengths``). ``--noise``: also at the truth's positions plus
independent Gaussian noise of each standard deviation given (pixels, seed
0): noise of no spatial pattern, beside a tracker's drift.

    python experiments/isometric_tracks.py [--template joint,refined] [--each-frame program,lengths,mirror] [--anchor 10] [--noise 0.25,0.5,1] [--drop 0,0.1,0.2]
"""

from __future__ import annotations


import numpy as np

from nrdepth.scores.real import DATA, kinect_truth

from nrdepth.isometric import least_disagreeing, mdh_depths, track_points  # noqa: E402
from nrdepth.io import read_video  # noqa: E402

NEIGHBOURS = 10


def score(depths: np.ndarray, uv: np.ndarray, z: np.ndarray) -> float:
    """Mean over frames of the mean absolute error after a·u + b·v + λ·depth + t."""
    errors = []
    for d, p, target in zip(depths, uv, z):
        a = np.column_stack([p, d, np.ones(len(d))])
        errors.append(np.abs(a @ np.linalg.lstsq(a, target, rcond=None)[0] - target).mean())
    return float(np.mean(errors))


def follow(frames: np.ndarray, start: np.ndarray, first: int, last: int, tracker: str) -> dict:
    """Positions {frame: (n, 2)} of points at ``start`` in frame ``first``, followed to ``last``."""
    import cv2
    from scipy.ndimage import map_coordinates

    positions, where = {first: start.astype(np.float64)}, start.astype(np.float64)
    lk = dict(winSize=(21, 21), maxLevel=3, criteria=(cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 50, 0.01))
    for t in range(first + 1, last + 1):
        if tracker == "Lucas–Kanade":
            ahead, _, _ = cv2.calcOpticalFlowPyrLK(frames[t - 1], frames[t], where.astype(np.float32).reshape(-1, 1, 2), None, **lk)
            where = ahead.reshape(-1, 2).astype(np.float64)
        else:
            flow = cv2.calcOpticalFlowFarneback(frames[t - 1], frames[t], None, 0.5, 5, 21, 5, 7, 1.5, 0)
            where = where + np.stack([map_coordinates(flow[..., c], [where[:, 1], where[:, 0]], order=1, mode="nearest") for c in (0, 1)], axis=1)
        positions[t] = where
    return positions


def main() -> None:
    import argparse

    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--template", type=lambda text: text.split(","), default=["joint"], help="mdh_depths's template distances, each read in turn")
    parser.add_argument("--drop", type=lambda text: [float(v) for v in text.split(",")], default=[0.0],
                        help="shares of the points whose flows both ways disagree most, left out of the last reading (track_grid's drop)")
    parser.add_argument("--each-frame", type=lambda text: text.split(","), default=["program"],
                        help="mdh_depths's each_frame (program, lengths, mirror), each read in turn with each template")
    parser.add_argument("--noise", type=lambda text: [float(v) for v in text.split(",")], default=[], help="standard deviations in pixels")
    parser.add_argument("--anchor", type=float, default=0.0, help="mdh_depths's anchor (with each frame lengths: each refined depth pulled "
                        "towards the program's)")
    args = parser.parse_args()
    truth = kinect_truth()
    K = np.load(DATA / "kinect_paper" / "gt_mdh.npz")["K"].astype(np.float64)
    focal, centre = (K[0, 0], K[1, 1]), (K[0, 2], K[1, 2])
    uv = truth["uv"].transpose(0, 2, 1)  # (23, 301, 2)
    frames_with_truth = list(truth["frames"])
    readings = [(template, each) for template in args.template for each in args.each_frame]
    names = {reading: reading[0] if args.each_frame == ["program"] else "{}, each frame {}".format(*reading) for reading in readings}
    read = lambda xy, keyframes, reading: mdh_depths(xy, focal, centre, neighbours=NEIGHBOURS, keyframes=keyframes, template=reading[0],  # noqa: E731
                                                     each_frame=reading[1], anchor=args.anchor if reading[1] == "lengths" else 0.0)
    for reading in readings:
        print(f"{names[reading]}: the truth's image positions, {len(uv)} frames: {score(read(uv, len(uv), reading), uv, truth['z']):.2f} mm")
    for sigma in args.noise:
        noisy = uv + np.random.default_rng(0).normal(0, sigma, uv.shape)
        print(f"the truth's positions plus noise of {sigma:g} px: " + ", ".join(f"{names[reading]} {score(read(noisy, len(uv), reading), uv, truth['z']):.2f} mm" for reading in readings))
    video = read_video(DATA / "kinect_paper").frames
    span = [i for i, f in enumerate(frames_with_truth) if f <= 112]
    for tracker in ("Lucas–Kanade", "Farneback"):
        positions = follow(video, uv[0], frames_with_truth[0], frames_with_truth[-1], tracker)
        later = {f: np.median(np.linalg.norm(positions[f] - uv[i], axis=1)) for i, f in enumerate(frames_with_truth) if f > 112}
        print(f"{tracker}: median distance from the truth's positions after frame 112: " + ", ".join(f"{f}: {d:.1f}" for f, d in later.items()) + " px")
        tracked = np.stack([positions[frames_with_truth[i]] for i in span])
        drift = np.median(np.linalg.norm(tracked - uv[span], axis=2), axis=1)
        for reading in readings:
            print(f"{names[reading]}, {tracker}, frames {frames_with_truth[span[0]]}–{frames_with_truth[span[-1]]} ({len(span)} with truth): "
                  f"{score(read(tracked, len(span), reading), uv[span], truth['z'][span]):.2f} mm (the truth's positions: "
                  f"{score(read(uv[span], len(span), reading), uv[span], truth['z'][span]):.2f}); "
                  f"median drift from the truth's positions {drift.mean():.2f} px over the frames, {drift[-1]:.2f} at the last")
    followed, disagreement = track_points(video[frames_with_truth[0] :], uv[0], disagreement=True)
    seen = np.array(frames_with_truth) - frames_with_truth[0]
    for drop in args.drop:
        kept = least_disagreeing(disagreement, drop)  # track_grid's drop
        drift = np.median(np.linalg.norm(followed[seen][:, kept] - uv[:, kept], axis=2), axis=1)
        for reading in readings:
            print(f"{names[reading]}, the flow both ways, frames {frames_with_truth[0]}–{len(video) - 1}, 24 keyframes, {len(kept)} points (drop {drop:g}): "
                  f"{score(read(followed[:, kept], 24, reading)[seen], uv[:, kept], truth['z'][:, kept]):.2f} mm "
                  f"(at the truth's positions: {score(read(uv[:, kept], len(uv), reading), uv[:, kept], truth['z'][:, kept]):.2f}); "
                  f"median drift {drift.mean():.2f} px over the 23 frames, {drift[-1]:.2f} at the last", flush=True)


if __name__ == "__main__":
    main()
