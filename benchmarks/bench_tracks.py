"""How well points are followed through a video (issue 72), tracker by
tracker, on three kinds of truth:

- ``kinect_paper``: the 301 MDH points followed from the first frame with
  truth (8) through all 191 frames, their distance (px) from the truth's
  image positions in each of the 23 frames with truth; then again over
  the truth that looks like itself (:func:`truth_looks`): the truth is
  the Kinect's 3-D points projected, and where one lands a few pixels
  off the print's point (at the sheet's corners, mostly) its window no
  longer looks like its first frame's, so a tracker's distance from it
  is the truth's error;
- ``phisft_R1`` (no 2-D truth): points on the cloth (its silhouette, 4×4
  binned) followed to the last frame, then back to the first by the same
  tracker started afresh on every other frame in reverse (other frame
  pairs than the way there: the flow both ways would retrace its own
  steps exactly): the closed loop's distance (px) from where each began;
- generated long sheets (256² × ``--frames``, ``--phases`` bends, through
  pinholes of 40–80°, lit from below and from above (``--lights``),
  textured by ``--families``, any other generator field by ``--set``, seed
  ``isometric_generated.SEED`` from ``--start``): the mesh vertices nearest a
  400-point grid (over a backdrop, the grid's points on the sheet)
  followed from their true positions in the first frame,
  their distance (px) from the true ones (``nrdepth.image_points``) in every
  frame while in view;
- sheets rendered by Mitsuba 3's path tracer (``--rendered`` seeds, cached
  by ``bench_sheet_stage.py render``; noisy at 4 samples a pixel): a
  400-point grid over the sheet in the first frame (its mask shrunk by 4
  px), their distance (px) from where the scene's geometry puts them
  (``nrdepth.scores.rendered.true_tracks``) in every frame while seen.

Each line: median, 95th percentile and largest distance, the share of
point-frames lost (NaN), and the seconds; for the sheets, the videos'
95th percentiles' median. A tracker is ``key=value`` pairs joined by ``:``
(``track_points``' ``hold``, ``backward``, ``flow``, ``margin``, ``stride``, ``scale`` its ``flow_scale``; ``ncc`` and ``fb``: the held tracker's thresholds; an empty one
is its defaults).

    python benchmarks/bench_tracks.py [--trackers ",margin=48:hold=1"] [--videos 16] [--start 96] [--skip generated] [--lights below] [--set FIELD=V] [--rendered 0-23]
"""

from __future__ import annotations

import argparse
import sys
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator, Optional

import numpy as np

from nrdepth.isometric import track_points
from nrdepth.isometric.hold import HOLD_NCC

sys.path.insert(0, str(Path(__file__).parents[1] / "experiments"))


@contextmanager
def held_thresholds(fb: Optional[float] = None, ncc: Optional[float] = None) -> Iterator[None]:
    """The held tracker's thresholds set for the block where given (its way
    back ``hold.HOLD_FB``, px; its correlation ``hold.HOLD_NCC``): levers to
    read, not options."""
    from nrdepth.isometric import hold

    given = {name: value for name, value in (("HOLD_FB", fb), ("HOLD_NCC", ncc)) if value is not None}
    saved = {name: getattr(hold, name) for name in given}
    try:
        for name, value in given.items():
            setattr(hold, name, value)
        yield
    finally:
        for name, value in saved.items():
            setattr(hold, name, value)


def parse(tracker: str) -> dict:
    out = {}
    for item in filter(None, tracker.split(":")):
        key, _, value = item.partition("=")
        if key in ("hold", "backward"):
            out[key] = bool(int(value))
        elif key == "flow":
            out[key] = value
        elif key == "margin":
            out[key] = None if value == "none" else int(value)
        elif key == "stride":
            out[key] = int(value)
        elif key == "scale":
            out["flow_scale"] = float(value)
        elif key in ("ncc", "fb"):
            out[key] = float(value)
        else:
            raise SystemExit(f"--trackers: unknown key {key!r} (hold, backward, flow, margin, stride, scale, ncc, fb)")
    return out


def track(video, start: np.ndarray, tracker: str) -> np.ndarray:
    """``track_points`` with ``tracker``'s settings, its ``ncc`` and ``fb``
    the held tracker's thresholds during the call."""
    settings = parse(tracker)
    with held_thresholds(fb=settings.pop("fb", None), ncc=settings.pop("ncc", None)):
        return track_points(video, start, **settings)


def summary(errors: np.ndarray) -> str:
    """Median, 95th percentile, largest of the finite distances and the share of NaN."""
    seen = errors[np.isfinite(errors)]
    return (f"median {np.median(seen):.2f}, p95 {np.percentile(seen, 95):.2f}, max {seen.max():.1f} px, "
            f"lost {100 * (1 - seen.size / errors.size):.1f} %")


def kinect(trackers: list) -> None:
    from nrdepth.scores.real import kinect_truth, kinect_video

    frames, truth = kinect_video(), kinect_truth()
    first, uv = truth["frames"][0], truth["uv"].transpose(0, 2, 1)  # (23, 301, 2)
    looks = truth_looks(frames[truth["frames"]], uv)[1:] >= HOLD_NCC
    for name in trackers:
        start = time.perf_counter()
        xy = track(frames[first:], uv[0], name)
        seconds = time.perf_counter() - start
        errors = np.linalg.norm(xy[truth["frames"] - first] - uv, axis=2)[1:]
        print(f"kinect_paper {name or 'default':32s} {summary(errors)}; {seconds:.1f} s", flush=True)
        print(f"  where the truth looks like itself ({looks.sum()} of {looks.size}) {summary(errors[looks])}", flush=True)


def truth_looks(frames: np.ndarray, uv: np.ndarray, neighbours: int = 12) -> np.ndarray:
    """(K, n): how much each truth point (``uv`` (K, n, 2) in ``frames`` (K,
    H, W)) looks in each frame as it does in the first: the zero-mean
    normalised correlation of its window there with its first frame's
    window mapped by the affine map that takes its ``neighbours`` nearest
    truth points (and itself) from the first frame to that frame, on frames
    with their local mean and contrast taken out, as the held tracker
    compares (``nrdepth.isometric.hold``: its window, contrast and
    threshold :data:`HOLD_NCC`). 1 in the first frame."""
    import cv2
    from scipy.ndimage import map_coordinates
    from scipy.spatial import cKDTree

    from nrdepth.isometric.hold import HOLD_WINDOW, _normalised

    offsets = np.stack(np.meshgrid(*2 * [np.arange(HOLD_WINDOW) - (HOLD_WINDOW - 1) / 2], indexing="xy"), axis=-1).reshape(-1, 2)  # (w², 2) as (x, y)
    _, near = cKDTree(uv[0]).query(uv[0], k=neighbours + 1)  # (n, neighbours + 1), itself first

    def windows(frame: np.ndarray, at: np.ndarray) -> np.ndarray:  # (n, w²) zero mean, unit norm; at (n, w², 2)
        w = map_coordinates(_normalised(cv2, frame).astype(np.float32), [at[..., 1].ravel(), at[..., 0].ravel()], order=1, mode="nearest")
        w = w.reshape(at.shape[:2]) - w.reshape(at.shape[:2]).mean(axis=1, keepdims=True)
        return w / (np.linalg.norm(w, axis=1, keepdims=True) + 1e-6)

    first = windows(frames[0], uv[0][:, None] + offsets[None])
    source = np.concatenate([uv[0][near] - uv[0][:, None], np.ones(near.shape + (1,))], axis=2)  # (n, m, 3): offsets from the point, 1
    looks = np.ones(uv.shape[:2])
    for k in range(1, len(frames)):
        affine = np.stack([np.linalg.lstsq(a, b, rcond=None)[0] for a, b in zip(source, uv[k][near])])  # (n, 3, 2): [A; t]
        mapped = uv[k][:, None] + offsets[None] @ affine[:, :2]  # the first frame's window, mapped about the truth
        looks[k] = (first * windows(frames[k], mapped)).sum(axis=1)
    return looks


def phisft(trackers: list) -> None:
    from scipy.ndimage import binary_erosion

    from nrdepth.isometric import start_grid
    from nrdepth.scores.real import data_folder

    gray = np.load(data_folder("phisft_R1") / "derived_q4.npz")["gray"]
    cloth = binary_erosion(gray[0] > 0, iterations=4)  # off the silhouette's edge, where the window sees the background
    grid = start_grid(cloth, gray.shape[1:], points=400)
    # Back by every other frame: frame pairs the way there never used, or the flow both ways would undo its own steps exactly.
    returning = np.r_[np.arange(len(gray) - 1, 0, -2), 0]
    for name in trackers:
        start = time.perf_counter()
        there = track(gray, grid, name)[-1]
        kept = np.isfinite(there).all(axis=1)
        back = np.full_like(grid, np.nan)
        back[kept] = track(gray[returning], there[kept], name)[-1]
        seconds = time.perf_counter() - start
        print(f"phisft_R1 closed loop {name or 'default':26s} {summary(np.linalg.norm(back - grid, axis=1))}; {seconds:.1f} s", flush=True)


def generated(trackers: list, videos: int, start: int, frames: int, phases: int, families: tuple, lights: list, sets: list) -> None:
    from isometric_generated import SEED, in_view, long_sheets, true_tracks

    from nrdepth import generate_clips

    per_video = {name: [] for name in trackers}
    pooled = {name: [] for name in trackers}
    seconds = {name: 0.0 for name in trackers}
    for light in lights:
        config = long_sheets(frames, phases, families, light, sets)
        clips = generate_clips(videos, seed=SEED, config=config, start=start, vertices=True)
        for k, (video, depth, params) in enumerate(zip(clips.video, clips.depth, clips.params)):
            sheet = np.isfinite(depth[0])  # over a backdrop, the points start on the sheet
            truth, _ = true_tracks(clips.vertices[k], params, config.size, region=None if sheet.all() else sheet)
            visible = in_view(truth, config.size)
            for name in trackers:
                begin = time.perf_counter()
                xy = track(video, truth[0], name)
                seconds[name] += time.perf_counter() - begin
                errors = np.where(visible, np.linalg.norm(xy - truth, axis=2), np.inf)[1:]
                errors = errors[np.isfinite(errors) | np.isnan(errors)]  # in view: a distance, or NaN where the tracker lost it
                per_video[name].append(np.nanpercentile(errors, 95))
                pooled[name].append(errors)
            print(f"  {light} {start + k}: " + ", ".join(f"{name or 'default'} p95 {per_video[name][-1]:.2f}" for name in trackers), flush=True)
    for name in trackers:
        print(f"generated sheets ({len(lights) * videos}) {name or 'default':22s} {summary(np.concatenate(pooled[name]))}; the videos' p95s' median "
              f"{np.median(per_video[name]):.2f} px; {seconds[name]:.1f} s", flush=True)


def rendered(trackers: list, seeds: list) -> None:
    import cv2

    from nrdepth.isometric import start_grid
    from nrdepth.scores.rendered import load_video, scene_of, true_tracks

    per_video = {name: [] for name in trackers}
    pooled = {name: [] for name in trackers}
    seconds = {name: 0.0 for name in trackers}
    for seed in seeds:
        data = load_video(seed)
        video = data["video"]
        scene = scene_of(seed, frames=len(video), size=video.shape[1:])
        on_sheet = cv2.erode(data["sheet"][0].astype(np.uint8), np.ones((9, 9), np.uint8)).astype(bool)
        start = start_grid(on_sheet, video.shape[1:], 400)
        truth = true_tracks(scene, start, data["depth"])
        for name in trackers:
            begin = time.perf_counter()
            xy = track(video, start, name)
            seconds[name] += time.perf_counter() - begin
            errors = np.where(np.isfinite(truth[..., 0]), np.linalg.norm(xy - truth, axis=2), np.inf)[1:]
            errors = errors[np.isfinite(errors) | np.isnan(errors)]  # seen: a distance, or NaN where the tracker lost it
            per_video[name].append(np.nanpercentile(errors, 95))
            pooled[name].append(errors)
        print(f"  rendered {seed}: " + ", ".join(f"{name or 'default'} p95 {per_video[name][-1]:.2f} lost "
                                                 f"{100 * np.isnan(pooled[name][-1]).mean():.0f} %" for name in trackers), flush=True)
    for name in trackers:
        print(f"rendered sheets ({len(seeds)}) {name or 'default':22s} {summary(np.concatenate(pooled[name]))}; the videos' p95s' median "
              f"{np.median(per_video[name]):.2f} px; {seconds[name]:.1f} s", flush=True)


def main() -> None:
    from isometric_generated import setting

    from nrdepth.scores.generated import SHEET_FAMILIES

    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--trackers", default=",margin=48:hold=1", help="comma-separated trackers (module docstring)")
    parser.add_argument("--videos", type=int, default=16, help="generated sheets per light")
    parser.add_argument("--start", type=int, default=96, help="the first sheet's index in the held-out seed's draws")
    parser.add_argument("--frames", type=int, default=64)
    parser.add_argument("--phases", type=int, default=4)
    parser.add_argument("--threads", type=int, default=1, help="OpenCV's threads")
    parser.add_argument("--families", default=",".join(SHEET_FAMILIES), help="the generated sheets' texture families (comma-separated)")
    parser.add_argument("--skip", default="", help="comma-separated: kinect, phisft, generated")
    parser.add_argument("--rendered", default="", help="rendered sheets' seeds (bench_sheet_stage.py's 0-23,40 form; default: none)")
    parser.add_argument("--lights", default="below,above", help="the generated sheets lit from below, above, or both (each its own --videos)")
    parser.add_argument("--set", action="append", default=[], metavar="FIELD=V[,V]", type=setting,
                        help="a GeneratorConfig field of the generated sheets, one value or lo,hi (e.g. the paper-like sheets' "
                        "backdrop_probability=1; over a backdrop the points start on the sheet), repeatable")
    args = parser.parse_args()
    import cv2

    cv2.setNumThreads(args.threads)
    trackers = args.trackers.split(",")
    skip = set(filter(None, args.skip.split(",")))
    if "kinect" not in skip:
        kinect(trackers)
    if "phisft" not in skip:
        phisft(trackers)
    if "generated" not in skip:
        generated(trackers, args.videos, args.start, args.frames, args.phases, tuple(args.families.split(",")), args.lights.split(","), args.set)
    if args.rendered:
        from bench_sheet_stage import seeds_of

        rendered(trackers, seeds_of(args.rendered))


if __name__ == "__main__":
    main()
