"""Cheaper predictions for the held tracker (issue 71's cost): does the
sheet stage need Farneback's flow both ways at full size, or do its held
points, found again by their look in the first frame
(:mod:`nrdepth.isometric.hold`), follow the paper as well from a cheaper
guess?

``--predict``:

- ``none``: no flow; each point predicted where it was in the frame
  before (a flow that returns zeros, forward alone, no drop);
- ``quarter``: Farneback forward alone on frames shrunk to a quarter
  (``flow_scale=0.25``, no drop);
- ``today``: the stage's own (Farneback both ways, the drop).

``--passes`` (default 2): the hold run this many times a frame, the points
not found predicted again by the warp of those found
(:func:`hold_again`): a video moves little between frames, and the warp
of the points found carries the rest within Lucas–Kanade's reach.

Then either the points over ``kinect_paper``'s whole frame (400 asked
for), counted as the default reads them (held in every frame, and in
80 % of their frames in view), with their seconds and CPU-seconds; or,
with ``--run SCRIPT ARGS…``, that script run with the stage's held
points (and ``track_points``' held trackers) followed so, e.g. the job's
checks and the tracks of issue 72:

    python experiments/cheap_hold.py --predict none
    python experiments/cheap_hold.py --predict none --run benchmarks/bench_sheet_stage.py --no-box-check --job whole --settings ""
    python experiments/cheap_hold.py --predict quarter --passes 1 --run benchmarks/bench_tracks.py --trackers margin=48:hold=1:backward=0:scale=0.25 --skip phisft,generated

``--jitter SD``: in place of a cheaper tracker, the stage's own held tracks
each displaced by Gaussian noise of SD px (``--seeds`` seeds, the tracks
followed once), and the default job read over ``kinect_paper``'s roi and
its whole frame for each: how much the job's checks move when the tracks
move by a fraction of their own error, and the points read stay the same.
"""

from __future__ import annotations

import argparse
import functools
import importlib
import resource
import runpy
import sys
import time
import warnings

import numpy as np

import nrdepth
import nrdepth.isometric.points as points
from nrdepth.isometric import DROP, point_held_shares, track_grid
from nrdepth.isometric.hold import Anchor

SETTINGS = {"none": dict(backward=False, drop=0.0), "quarter": dict(flow_scale=0.25, backward=False, drop=0.0), "today": {}}


def hold_again(passes: int):
    """An :class:`~nrdepth.isometric.hold.Anchor` whose ``hold`` runs ``passes`` times a frame, each pass's points not
    found predicted again by the warp of those found."""

    class Again(Anchor):
        def hold(self, frame, predicted):
            position, held, carried = super().hold(frame, predicted)
            for _ in range(passes - 1):
                if np.count_nonzero(held) < 3 or held.all():  # nothing to carry the rest, or nothing left to find
                    break
                again = np.where(held[:, None], position, self.to_points @ position[self.fitted] + self.point_offset)
                position, held, carried = super().hold(frame, again)
            return position, held, carried

    return Again


def install(predict: str, passes: int) -> None:
    """Every held tracker of ``track_points`` (and the stage's ``track_grid``) predicted by ``predict``, held in ``passes``."""
    points.Anchor = hold_again(passes)
    if predict == "none":
        points._flow = lambda cv2, name, window, scale=1.0: (lambda a, b: np.zeros((*a.shape, 2), np.float32))  # noqa: E731
    sheet = importlib.import_module("nrdepth.reconstruct.sheet")
    stage = sheet.track_grid

    @functools.wraps(stage)
    def held_so(*args, **kwargs):
        if kwargs.get("hold"):
            kwargs.update(SETTINGS[predict])
        return stage(*args, **kwargs)

    sheet.track_grid = held_so


def cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def count(predict: str, passes: int) -> None:
    from nrdepth.scores.real import kinect_video

    frames = kinect_video()
    start, seconds = cpu(), time.perf_counter()
    xy = track_grid(frames, np.ones(frames.shape[1:], bool), points=400, margin=48, hold=True, **({"drop": DROP} | SETTINGS[predict]))
    seconds, start = time.perf_counter() - seconds, cpu() - start
    every = int(np.isfinite(xy).all(axis=(0, 2)).sum())
    often = int((point_held_shares(xy, frames.shape[1:]) >= 0.8).sum())
    print(f"kinect_paper's whole frame, {predict}, {passes} pass(es): {xy.shape[1]} points, held in every frame {every}, in 80 % of their "
          f"frames {often}, point-frames held {np.isfinite(xy[..., 0]).mean():.3f}; {seconds:.1f} s, {start:.1f} CPU-s")


def jitter(sd: float, seeds: int) -> None:
    """The default job over the roi and the whole frame, its held tracks displaced by N(0, sd) px, seed by seed."""
    from nrdepth.scores.real import KINECT_ROI, kinect_score, kinect_truth, kinect_video

    sheet, api = importlib.import_module("nrdepth.reconstruct.sheet"), importlib.import_module("nrdepth.reconstruct.api")
    stage, followed, seed = sheet.track_grid, {}, [None]
    decisions, decide = [], api.sheet_depth
    api.sheet_depth = lambda *a, **k: decisions.append(decide(*a, **k)) or decisions[-1]

    @functools.wraps(stage)
    def displaced(frames, region, **kwargs):
        key = (np.asarray(region).tobytes(), tuple(sorted(kwargs.items())))
        if key not in followed:  # each reading's tracks followed once
            followed[key] = stage(frames, region, **kwargs)
        xy = followed[key].copy()
        return xy if seed[0] is None else xy + np.random.default_rng(seed[0]).normal(0.0, sd, xy.shape)  # NaN stays NaN

    sheet.track_grid = displaced
    frames, truth = kinect_video(), kinect_truth()
    for job, given in (("roi", dict(roi=KINECT_ROI)), ("whole frame", {})):
        read = given.get("roi", (0, 0, frames.shape[2], frames.shape[1]))
        for seed[0] in [None, *range(seeds)]:
            decisions.clear()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                depth = nrdepth.reconstruct(frames, **given).astype(np.float64)
            d = decisions[0]
            print(f"{job}, {'as tracked' if seed[0] is None else f'seed {seed[0]}'}: {kinect_score(depth, truth, roi=read):.2f} mm "
                  f"({d.points} points, contrast {d.contrast:.2f}, estimate {d.focal_estimate:.1f} px)", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--predict", choices=sorted(SETTINGS), default="none")
    parser.add_argument("--passes", type=int, default=2)
    parser.add_argument("--jitter", type=float, default=None, metavar="SD", help="px: the stage's own tracks displaced, in place of a tracker")
    parser.add_argument("--seeds", type=int, default=6)
    parser.add_argument("--run", nargs=argparse.REMAINDER, default=None, metavar="SCRIPT ARGS", help="a script to run with the tracker in place")
    args = parser.parse_args()
    if args.jitter is not None:
        return jitter(args.jitter, args.seeds)
    install(args.predict, args.passes)
    if args.run:
        sys.argv = args.run
        runpy.run_path(args.run[0], run_name="__main__")
    else:
        count(args.predict, args.passes)


if __name__ == "__main__":
    main()
