"""The sheet stage's cost on ``kinect_paper`` (191 frames, 640×480), lever by
lever, with what each costs in accuracy: the stage's parts (the points
followed, the cone programs) timed for each setting given, the whole
sheet's error (mm, per-frame GBR) of the network's depth fused with each
setting's isometric depth (the Kinect's focal length, points over the
print, or with ``--box sheet`` over the whole sheet's box, half of it
background, as ``reconstruct(focal=..., sheet=...)`` runs it), and the rest of
the job (``reconstruct`` without ``focal``) timed in the same run, beside a
2048² sgemm measured before and after (machines here differ by 1.5×).

A setting is ``key=value`` pairs joined by ``:``: ``margin`` (the flow over
the points' box and this many pixels, or ``none``: the whole frame),
``flow`` (farneback, farneback2, dis), ``keyframes``, ``neighbours``, ``every`` (only every
n-th frame's program solved, the rest linear in time), ``points``, ``hold``
(1: each point found again by its look in the first frame), ``backward``
(0: the forward flow alone), ``drop`` (the share of points left out; 0 with
``backward=0`` unless held, where the flow's guess against the hold's
answer picks them), ``keep`` (with ``hold``: only the points held in at least
this share of their frames in view, ``isometric.point_held_shares``),
``each`` (``mdh_depths``' ``each_frame``: program, lengths, mirror),
``anchor`` (with ``each=lengths``, ``mdh_depths``' ``anchor``), ``fov``
(degrees: the camera a pinhole that sees this much across the frame's
longer side with its principal point at the frame's centre,
``nrdepth.Camera.guessed``, in place of the true one; ``strain``: the
focal length ``nrdepth.isometric.estimate_focal`` finds from the points
found in every frame), ``place`` (``track_grid``'s:
grid, or texture: where the first frame has texture to follow), ``inset``
(pixels: the points' region shrunk by this much first, so that no
point's window crosses its outline; :func:`inset_region`),
``whole`` (``experiments/sheet_levers.py`` only: the points over the
whole frame, not the sheet's true region), ``piece`` (``sheet_levers.py``
only: of the points read, the one piece that moves most,
``experiments/kinect_box_parts.moving_piece``), ``template`` (``mdh_depths``':
joint or refined), ``throughout`` (1: only the points found in every
frame, none that leaves the view or is lost), ``moving`` (1: of the points
read, only those that move at least the stage's ``MIN_MOTION`` from where
they start: none on a still background), ``relmove`` (with ``moving``: of
those, only the points that move at least this share of their median
motion too), ``trim`` (of the points read, those whose pairs
stretch in the keyframes' ``refined`` template more than this many times
the points' median left out, up to three times over: ``trim_strained``), ``jump``
(with ``trim``: also the points whose pairs' median depth step is more
than this many median template distances, ``unstrained_points``'
``jump``), ``fscale`` (the flow on frames
shrunk by this factor, ``track_points``' ``flow_scale``), ``fb`` (the
held tracker's way back, ``hold.HOLD_FB``, px; ``sheet_levers.py``
only: :func:`held_thresholds`), ``contrast``
(``experiments/sheet_levers.py`` only, 1: also ``estimate_focal``'s
contrast on the points read, recorded, not used), ``cevals`` (with
``contrast``: its refinements' evaluations, ``estimate_focal``'s
``evaluations``), ``csmooth`` and ``canchor`` (with ``contrast``: ``estimate_focal``'s
``smooth`` and ``anchor``), ``smooth`` (with ``throughout``: the points
read smoothed in time by a Gaussian of this many frames, before the
trim, the programs and the contrast), ``rsmooth`` (``sheet_levers.py``
only, with ``throughout``: the gates, the trim and the estimate read the
points as tracked, and only the shape that is fused is solved again, on
the points read smoothed in time by a Gaussian of this many frames, through
the camera the reading chose), ``onsheet``
(``sheet_levers.py`` only, 1: of the points read, those that start on the
sheet's true region: an oracle).
With ``hold``, where fewer of the point-frames in view are held than the
stage's ``MIN_HELD``, the stage steps aside, as it does in the job.
``--job true``: also the whole job with the sheet stage at its defaults
(``reconstruct(roi=..., focal=..., sheet=box)``), timed, with its log
line, its whole-sheet error and the seconds each of the stage's parts
takes (:func:`stage_parts`); ``--job guessed``: the same without the
focal length (the stage's guessed pinhole); ``--job focal``: the roi
and the true focal length, no box; ``--job default``: nothing
given but the roi (``reconstruct(roi=...)``, the stage by default);
``--job whole``: nothing given at all, the whole 640×480 frame, scored on
the sheet's points. The rest of the job is ``reconstruct(roi=...,
sheet_stage=False)``.

    python benchmarks/bench_sheet_stage.py [--threads 2] [--settings margin=none,margin=48,margin=48:keyframes=12:every=3]
"""

from __future__ import annotations

import argparse
import time
from contextlib import contextmanager
from typing import Iterator, Optional

import numpy as np


def sgemm() -> float:
    import torch

    a = torch.randn(2048, 2048)
    a @ a
    start, n = time.perf_counter(), 0
    while time.perf_counter() - start < 1.0:
        a @ a
        n += 1
    return 2 * 2048**3 * n / (time.perf_counter() - start) / 1e9


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


def parse(setting: str) -> dict:
    from nrdepth.isometric import DROP

    out = {"margin": None, "flow": "farneback", "keyframes": 24, "neighbours": 20, "every": 1, "points": 400, "hold": 0, "backward": 1, "drop": DROP, "keep": 0.0, "each": "program", "anchor": 0.0, "fov": None, "place": "grid", "inset": 0, "whole": 0, "piece": 0, "template": "joint", "throughout": 0, "moving": 0, "fscale": 1.0, "contrast": 0, "cevals": 100, "csmooth": 0.0, "canchor": 0.0, "onsheet": 0, "relmove": 0.0, "trim": 0.0, "fb": None, "estimate": 0, "stride": 1, "smooth": 0.0, "rsmooth": 0.0, "jump": 0.0}
    for item in filter(None, setting.split(":")):
        key, _, value = item.partition("=")
        if key not in out:
            raise SystemExit(f"--settings: unknown lever {key!r} (known: {', '.join(out)})")
        out[key] = value if key in ("flow", "each", "place", "template") or (key == "fov" and value in ("strain", "held")) else \
            float(value) if key in ("drop", "keep", "anchor", "fov", "fscale", "relmove", "trim", "fb", "csmooth", "canchor", "smooth", "rsmooth", "jump") else (None if value == "none" else int(value))
    if out["keep"] and not out["hold"]:
        raise SystemExit(f"--settings {setting!r}: keep needs hold=1")
    if out["stride"] < 1:
        raise SystemExit(f"--settings {setting!r}: stride is an int >= 1")
    if out["template"] not in ("joint", "refined"):
        raise SystemExit(f"--settings {setting!r}: template is joint or refined")
    if out["anchor"] and out["each"] != "lengths":
        raise SystemExit(f"--settings {setting!r}: anchor needs each=lengths")
    if out["fov"] not in (None, "strain", "held") and not 0 < out["fov"] < 180:
        raise SystemExit(f"--settings {setting!r}: fov is the degrees a pinhole sees across the frame's longer side, in (0, 180), strain or held")
    if out["trim"] and not out["throughout"]:
        raise SystemExit(f"--settings {setting!r}: trim needs throughout=1 (points in every frame)")
    if out["jump"] and not out["trim"]:
        raise SystemExit(f"--settings {setting!r}: jump needs trim (it is the trim's)")
    if (out["smooth"] or out["rsmooth"]) and not out["throughout"]:
        raise SystemExit(f"--settings {setting!r}: smooth and rsmooth need throughout=1 (points in every frame)")
    if out["estimate"] and not out["contrast"]:
        raise SystemExit(f"--settings {setting!r}: estimate needs contrast=1 (the estimate is the contrast's)")
    if not out["backward"] and out["drop"] and not out["hold"]:
        raise SystemExit(f"--settings {setting!r}: drop needs the flow both ways or the hold: give drop=0 with backward=0 and hold=0")
    return out


def pinhole(fov, camera, xy: np.ndarray, frame: tuple):
    """The camera a setting reads through: ``camera`` (the true one) where
    ``fov`` is None, the pinhole seeing ``fov`` degrees across the
    frame's longer side (``nrdepth.Camera.guessed``), or with ``fov``
    "strain" the focal length its points in every frame give
    (``nrdepth.isometric.estimate_focal``), the principal point at the
    frame's centre."""
    import nrdepth
    from nrdepth import isometric

    if fov is None:
        return camera
    if fov == "strain":
        return nrdepth.Camera(isometric.estimate_focal(xy[:, np.isfinite(xy).all(axis=(0, 2))], frame).focal).at(frame)
    return nrdepth.Camera.guessed(frame, view=fov)


def inset_region(region, inset: int):
    """``region`` (bool (H, W), or None: the whole frame, left whole) shrunk by ``inset`` pixels (a square's erosion)."""
    from scipy.ndimage import binary_erosion

    return region if region is None or not inset else binary_erosion(region, np.ones((2 * inset + 1,) * 2, bool))


def shortfall(xy: np.ndarray, depths: np.ndarray, camera, distances: np.ndarray, lever: dict) -> float:
    """How far the pairs fall short of their template distances in the
    program's depths: the mean over the pairs in view in the solved frames
    (the keyframes and every ``lever["every"]``-th) of
    1 − ‖Z_i r_i − Z_j r_j‖ / D_ij (0: every pair at its length, as on an
    inextensible sheet read through the right camera; the maximum-depth
    program never stretches a pair). ``depths`` (T, n) and ``distances``
    from ``mdh_depths(..., with_distances=True)`` with its default pairs."""
    from nrdepth import isometric
    from nrdepth.isometric.mdh import keyframe_indices, solved_frames

    solved = solved_frames(len(xy), keyframe_indices(len(xy), lever["keyframes"]), lever["every"])
    pairs = isometric.neighbour_pairs(xy[0], lever["neighbours"])
    xy, depths = xy[solved], depths[solved]
    points = camera.rays(xy) * depths[..., None]
    lengths = np.linalg.norm(points[:, pairs[:, 0]] - points[:, pairs[:, 1]], axis=2)
    return float(np.nanmean(1 - lengths / distances))


def strain(xy: np.ndarray, depths: np.ndarray, camera, distances: np.ndarray, lever: dict) -> float:
    """:func:`nrdepth.isometric.template_strain` of the setting's keyframes and
    pairs. Arguments as :func:`shortfall`'s."""
    from nrdepth import isometric

    return isometric.template_strain(xy, depths, camera, distances, lever["keyframes"], lever["neighbours"])


def keep_held(xy: np.ndarray, shape: tuple, lever: dict) -> np.ndarray:
    """The tracks of the points held in at least ``lever["keep"]`` of their
    frames in view; with ``lever["throughout"]``, of those only the points
    held in every frame; with ``lever["moving"]``, of those only the points
    that move at least the stage's ``MIN_MOTION`` from where they start (with
    ``lever["relmove"]``, at least that share of the median such point's motion
    too: a still backdrop's points by the sheet's edge move a little); with
    ``lever["smooth"]``, those smoothed in time by a Gaussian of that many frames."""
    from nrdepth import isometric
    from nrdepth.reconstruct.sheet import MIN_MOTION

    xy = xy[:, isometric.point_held_shares(xy, shape) >= lever["keep"]] if lever["keep"] else xy
    xy = xy[:, np.isfinite(xy).all(axis=(0, 2))] if lever["throughout"] else xy
    xy = xy[:, isometric.moving_points(xy, MIN_MOTION, lever["relmove"])] if lever["moving"] else xy
    if lever.get("smooth"):  # in time, before the trim, the programs and the contrast read them
        from scipy.ndimage import gaussian_filter1d

        xy = gaussian_filter1d(xy, lever["smooth"], axis=0, mode="nearest")
    return xy


def trim_strained(xy: np.ndarray, camera, lever: dict) -> np.ndarray:
    """The tracks ``xy`` (T, n, 2), finite in every frame, less the points
    whose pairs stray from their lengths more than ``lever["trim"]`` times
    the points' median (``nrdepth.isometric.unstrained_points`` over
    ``lever["keyframes"]`` and ``lever["neighbours"]``; with ``lever["jump"]``,
    its ``jump``)."""
    from nrdepth import isometric

    return xy[:, isometric.unstrained_points(xy, camera, lever["keyframes"], lever["neighbours"], lever["trim"], jump=lever.get("jump") or None)]


def box_check(frames: np.ndarray, box: np.ndarray) -> None:
    """Every point (drop 0) followed over the whole frame and over its box and 48 px: how far apart, and the time of each."""
    from nrdepth import isometric

    start = time.perf_counter()
    whole = isometric.track_grid(frames, box, points=400)
    middle = time.perf_counter()
    boxed = isometric.track_grid(frames, box, points=400, margin=48)
    end = time.perf_counter()
    shift = np.linalg.norm(boxed - whole, axis=2)
    print(f"the flow over the points' box and 48 px moves their tracks by a median {np.nanmedian(shift):.4f} px (95th percentile "
          f"{np.nanpercentile(shift, 95):.3f}, largest {np.nanmax(shift):.2f}) in {end - middle:.1f} s against {middle - start:.1f} s", flush=True)


def stage_parts(sheet) -> dict:
    """The seconds the sheet stage's parts take, summed as they run: its
    module's functions wrapped in timers (the stage's own names for them)."""
    import functools

    names = {"track_grid": "points followed", "unstrained_points": "trim", "mdh_depths": "programs", "estimate_focal": "contrast",
             "densify": "fusion: interpolation", "fuse": "fusion: fits and blurs"}
    seconds = dict.fromkeys(names.values(), 0.0)
    for function, name in names.items():
        def timed(*args, _run=getattr(sheet, function), _name=name, **kwargs):
            start = time.perf_counter()
            try:
                return _run(*args, **kwargs)
            finally:
                seconds[_name] += time.perf_counter() - start

        setattr(sheet, function, functools.wraps(getattr(sheet, function))(timed))
    return seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--settings", default="margin=none,margin=48", help="comma-separated settings (module docstring); \"\": none, the job alone")
    parser.add_argument("--scales", default=None, help="comma-separated fusion scales (fractions of the roi's shorter side) each "
                        "setting's whole sheet is read at (default: the stage's)")
    parser.add_argument("--box", choices=("print", "sheet"), default="print",
                        help="the points over the print (KINECT_INNER) or the whole sheet's box (KINECT_ROI)")
    parser.add_argument("--min-held", type=float, default=None, help="the held gate on the point-frames (default: the stage's MIN_HELD; 0: none)")
    parser.add_argument("--no-box-check", action="store_true", help="skip following every point with and without the box first")
    parser.add_argument("--job", choices=("true", "guessed", "focal", "default", "whole"), default=None,
                        help="also the whole job with the sheet stage at its defaults: through the true camera or the guessed one over the box, "
                        "the roi and the true focal length, nothing given but the roi, or nothing at all (module docstring)")
    args = parser.parse_args()
    for setting in filter(None, args.settings.split(",")):  # before the network's minutes
        if any(parse(setting)[key] for key in ("whole", "piece", "contrast", "onsheet", "estimate", "csmooth", "canchor")) or parse(setting)["cevals"] != 100:  # read by sheet_levers alone
            raise SystemExit(f"--settings {setting!r}: whole, piece, contrast, cevals, csmooth, canchor, estimate and onsheet are experiments/sheet_levers.py's levers; "
                             "the box here is --box")

    import cv2
    import torch

    import nrdepth
    from nrdepth import isometric
    from nrdepth.baselines.tracks import densify
    from nrdepth.reconstruct.options import ISOMETRIC_SCALE
    from nrdepth.reconstruct.sheet import MIN_HELD
    from nrdepth.scores.real import KINECT_INNER, KINECT_ROI, data_folder, kinect_references, kinect_score, kinect_truth, kinect_video

    torch.set_num_threads(args.threads)
    cv2.setNumThreads(args.threads)
    print(f"sgemm 2048²: {sgemm():.0f} GFLOP/s, {args.threads} threads", flush=True)
    frames = kinect_video()
    K = np.load(data_folder("kinect_paper") / "gt_mdh.npz")["K"].astype(np.float64)
    camera = nrdepth.Camera.from_matrix(K)
    truth = kinect_truth()
    x, y, w, h = KINECT_INNER if args.box == "print" else KINECT_ROI
    box = np.zeros(frames.shape[1:], bool)
    box[y : y + h, x : x + w] = True
    rx, ry, rw, rh = KINECT_ROI
    start = time.perf_counter()
    network = nrdepth.reconstruct(frames, roi=KINECT_ROI, sheet_stage=False).astype(np.float64)
    rest = time.perf_counter() - start
    print(f"the rest of the job (reconstruct, roi, no focal): {rest:.1f} s; network alone {kinect_score(network, truth):.2f} mm, "
          f"fixed bowl {kinect_references(truth, KINECT_ROI)['bowl']:.2f} mm", flush=True)
    if not args.no_box_check:
        box_check(frames, box)
    if args.job:
        import importlib
        import warnings

        api = importlib.import_module("nrdepth.reconstruct.api")  # nrdepth.reconstruct is also the function
        decisions, decide = [], api.sheet_depth
        api.sheet_depth = lambda *a, **k: decisions.append(decide(*a, **k)) or decisions[-1]  # the stage's decision, to print
        parts = stage_parts(importlib.import_module("nrdepth.reconstruct.sheet"))
        start = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # a fallback is printed below
            given = {"true": dict(roi=KINECT_ROI, focal=camera, sheet=(x, y, w, h)), "guessed": dict(roi=KINECT_ROI, sheet=(x, y, w, h)),
                     "focal": dict(roi=KINECT_ROI, focal=camera), "default": dict(roi=KINECT_ROI), "whole": {}}[args.job]
            job = nrdepth.reconstruct(frames, **given).astype(np.float64)
        whole = time.perf_counter() - start
        read = given.get("roi", (0, 0, frames.shape[2], frames.shape[1]))
        print(f"the job with the sheet stage's defaults ({args.job}): {whole:.1f} s (the stage {whole - rest:.1f} s, {(whole - rest) / rest:.2f}× the rest"
              f"{'' if 'roi' in given else ', the rest over the roi'}): {kinect_score(job, truth, roi=read):.2f} mm (the fixed bowl over the same frame "
              f"{kinect_references(truth, read)['bowl']:.2f} mm); {decisions[0].line()}", flush=True)
        print("  inside the stage (its reading in a thread of its own beside the network's passes, then the fusion): " + ", ".join(f"{name} {seconds:.1f} s" for name, seconds in parts.items()), flush=True)
    for setting in filter(None, args.settings.split(",")):
        lever = parse(setting)
        start = time.perf_counter()
        xy = isometric.track_grid(frames, inset_region(box, lever["inset"]), points=lever["points"], drop=lever["drop"], flow=lever["flow"], margin=lever["margin"],
                                  hold=bool(lever["hold"]), backward=bool(lever["backward"]), place=lever["place"], flow_scale=lever["fscale"],
                                  stride=lever["stride"])
        held = isometric.held_share(xy, frames.shape[1:]) if lever["hold"] else 1.0
        if held < (MIN_HELD if args.min_held is None else args.min_held):  # the stage's gate, before keep: it steps aside, the sheet reads as the network
            print(f"{setting:40s} points {time.perf_counter() - start:5.1f} s: steps aside ({held:.2f} of the point-frames held); "
                  f"the network's {kinect_score(network, truth):.2f} mm", flush=True)
            continue
        xy = keep_held(xy, frames.shape[1:], lever)
        tracked = time.perf_counter()
        through = pinhole(lever["fov"], camera, xy, frames.shape[1:])
        xy = trim_strained(xy, through, lever) if lever["trim"] else xy
        depths = isometric.mdh_depths(xy, through, keyframes=lever["keyframes"], neighbours=lever["neighbours"], every=lever["every"],
                                       each_frame=lever["each"], anchor=lever["anchor"], template=lever["template"])
        solved = time.perf_counter()
        dense = densify(xy - np.array([rx, ry]), depths, network.shape)
        scales = [ISOMETRIC_SCALE] if args.scales is None else [float(v) for v in args.scales.split(",")]
        mm = [kinect_score(isometric.fuse(network, dense, scale * min(rw, rh)), truth) for scale in scales]
        print(f"{setting:40s} points {tracked - start:5.1f} s, programs {solved - tracked:5.1f} s, stage {solved - start:5.1f} s "
              f"({(solved - start) / rest:.2f}× the rest): " + ", ".join(f"{m:.3f} mm at {scale:g}" for m, scale in zip(mm, scales)), flush=True)
    print(f"sgemm 2048²: {sgemm():.0f} GFLOP/s", flush=True)


if __name__ == "__main__":
    main()
