"""The sheet stage's speed levers on generated long sheets (issue 71): does a
cheaper setting of the stage read the sheets as the default does?

Each video (``--videos`` per light, lit from below and from above; 256² ×
``--frames`` in ``--phases`` bends; through a pinhole of 40–80°; a seed
and ``--start`` no earlier run read) is read by the network once, then by
each ``--settings`` of the sheet stage with the camera's true focal length,
the stage's defaults otherwise (``reconstruct(focal=...)``'s points, drop
and scale): per-frame MAE-SN of each, and its seconds for the points and
the programs. A setting is ``key=value`` pairs joined by ``:``, as in
``benchmarks/bench_sheet_stage.py`` (``margin``, ``flow``, ``keyframes``,
``neighbours``, ``points``, ``hold``, ``backward``, ``drop``, ``keep``, ``each``, ``anchor``, ``fov``: a guessed
pinhole in place of the true camera (``strain``: the focal length from the points' strain; ``held``: the one an
earlier held setting's ``strain`` found, else the guess), ``smooth``: the points read smoothed in time first, ``rsmooth``: only the shape fused read from them smoothed, the gates as tracked, ``place``: the points where the first
frame has texture, ``inset``: the sheet's region shrunk first, ``moving``: of the points read, those that move (``relmove``: at least this share of their median motion too), ``trim``: of those,
the points whose pairs stretch least (``bench_sheet_stage.trim_strained``), ``fscale``: the flow on frames shrunk by this factor, ``stride``: only every n-th frame tracked, ``fb``: the held tracker's way back (px), ``contrast``: ``estimate_focal``'s contrast on the points read, recorded with its strains over the grid (``cevals``: its refinements' evaluations; ``csmooth``: its tracks smoothed in time over this many frames first; ``canchor``: its refinements pulled towards their cone programs' depths by this weight; ``estimate``: then the programs solved again through the focal length it picks, the figures before, strain and contrast, left as they were; ``estimate=2``: only where the least strain lies two steps inside the grid), ``onsheet``: of the points read, those
that start on the sheet (an oracle: what the points off it cost), ``whole``: the points over
the whole frame, backdrop and all, not over the sheet, ``piece``: of the points read, the one
piece that moves most, as ``experiments/kinect_box_parts.py`` finds the paper); the first is the reference, each
other is paired against it. Each setting's ``shortfall`` is recorded too:
how far its program's pairs fall short of their template distances
(``bench_sheet_stage.shortfall``; with ``each=program``), a candidate
for the gate that says whether the pairs' lengths hold, and its ``strain``
(``bench_sheet_stage.strain``): how far its pairs stray from their
lengths in the keyframes, after ``refined`` what the sheet's stretch leaves. With ``--set
sheet_probability=0`` the videos are not sheets but the generator's
coloured-noise surfaces (``--set camera_fov=0,0``: seen orthographically,
where only ``fov`` settings can run). ``--scales``: each also fused at each scale. ``--truth``: the first setting's programs also read the sheet's true
tracks (the mesh's vertices nearest the points' grid, where a tracker
could still hold them: ``isometric_generated.true_tracks``), named
``truth``: what the tracker costs. ``--at-truth``: each setting's programs
also read its own points at their true image positions, NaN where its
tracks are (named ``NAME@truth``: what its points' errors cost, apart from
which points it reads and where it loses them), and the truth at the
stage's grid over the sheet (``grid@truth``: every point the tracker
starts from, in view). ``--sparse``: every reading also scored as
``kinect_paper``'s sparse truth scores it, at the points a held tracker
holds, their true positions and depths (``NAME sparse``). ``--families``: the sheets' texture
families. ``--set``: any other ``GeneratorConfig`` field of the sheets
(e.g. the paper-like sheets' ``backdrop_probability=1``; over a backdrop
the points go over the sheet in the first frame, where its truth is, as
``reconstruct(sheet=mask)`` puts them, and every figure is over the
sheet's pixels; ``--moving-backdrop``: the backdrop replaced by moving,
deforming coloured-noise surfaces, as a shirt moves behind a held sheet). ``--every``: each setting also with only every
n-th frame's program solved, the rest linear in time (``mdh_depths``'s
``every``; read off the setting's own every-frame depths, which it
solves alike in those frames, so it costs nothing more here). The rule that reads this is in
docs/campaign.md ("The sheet stage's cost").

    python experiments/sheet_levers.py [--videos 16] [--start 64] [--settings ",keyframes=12"] [--every 1,2,3,4] [--lights below,above] [--families print] [--truth] [--csv out.csv]
    python experiments/paired.py A.csv "keyframes=12 per frame" A.csv "default per frame"   # two runs' CSVs: concatenate them first
"""

from __future__ import annotations

import argparse
import csv
import math
import sys
import time
from pathlib import Path

import numpy as np
from scipy.ndimage import gaussian_filter1d

import nrdepth
from nrdepth import GeneratorConfig, generate_clips, isometric
from nrdepth.baselines.tracks import densify
from nrdepth.isometric import held_share
from nrdepth.isometric.mdh import _between, keyframe_indices, solved_frames
from nrdepth.reconstruct.options import ISOMETRIC_SCALE
from nrdepth.reconstruct.sheet import FLOW_MARGIN, KEEP_HELD
from nrdepth.scores.generated import SHEET_FAMILIES
from nrdepth.scores.metrics import dense_baselines, mae_sn, sparse_baselines, sparse_mae

sys.path.insert(0, str(Path(__file__).parent))
sys.path.insert(0, str(Path(__file__).parents[1] / "benchmarks"))
from bench_sheet_stage import held_thresholds, inset_region, keep_held, parse, pinhole, shortfall, strain, trim_strained  # noqa: E402
from isometric_generated import LIGHTS, SEED, camera, in_view, long_sheets, setting, true_tracks  # noqa: E402
from kinect_box_parts import moving_piece  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--videos", type=int, default=16, help="videos per light")
    parser.add_argument("--start", type=int, default=64, help="the first video's index in the held-out seed's draws")
    parser.add_argument("--frames", type=int, default=64)
    parser.add_argument("--phases", type=int, default=4)
    parser.add_argument("--settings", default=",margin=48", help="comma-separated settings; the first (default: the stage's defaults) is the reference")
    parser.add_argument("--every", default="1", help="comma-separated: each setting with only every n-th frame's program solved")
    parser.add_argument("--margin-check", type=int, default=None,
                        help="also follow the reference's points with the flow over their box and this margin: how far (px) its tracks move")
    parser.add_argument("--margin-only", action="store_true", help="with --margin-check: that check alone (no network, no programs)")
    parser.add_argument("--scales", default=str(ISOMETRIC_SCALE), help="comma-separated fusion scales (fractions of the frame's side): each "
                        "setting fused at each; the first is the setting's own name")
    parser.add_argument("--min-held", type=float, default=0.0, help="a setting's points held (hold=1) in fewer than this share of the "
                        "point-frames in view (isometric.held_share), or too few in a frame for the programs: the stage steps aside, "
                        "the sheet reads as the network")
    parser.add_argument("--sparse", action="store_true", help="also every reading scored as kinect_paper's truth scores it (NAME sparse): "
                        "at sparse points a tracker holds (the points over the sheet held to their first look, held in 0.8 of their "
                        "frames: as the data set's points are those its tracker held), at their true positions and depths where held, "
                        "each frame's GBR MAE (sparse_mae) in the sheet's units; beside it the network's, the plane's and the bowl's")
    parser.add_argument("--families", default=",".join(SHEET_FAMILIES), help="the sheets' texture families (comma-separated)")
    parser.add_argument("--truth", action="store_true", help="also the first setting's programs on the sheet's true tracks (named truth)")
    parser.add_argument("--at-truth", action="store_true", help="also each setting's points at their true positions (NAME@truth) and the "
                        "stage's grid over the sheet at its true positions (grid@truth)")
    parser.add_argument("--set", action="append", default=[], metavar="FIELD=V[,V]", type=setting,
                        help="a GeneratorConfig field of the sheets, one value or lo,hi (e.g. backdrop_probability=1), repeatable")
    parser.add_argument("--moving-backdrop", action="store_true",
                        help="over a backdrop: every pixel off the sheet (NaN depth) replaced by a clip of the generator's own coloured-noise "
                             "surfaces, which move and deform (seed SEED + 1, the same index), as a person's shirt and hands move behind a "
                             "held sheet; the sheet's anti-aliased edge keeps the still backdrop's share")
    parser.add_argument("--lights", default="below,above", help="the sheets lit from below, above, or both (each its own --videos)")
    parser.add_argument("--csv", type=Path, default=None, help="each video's row, written as it is read; a CSV already there is resumed "
                        "(its rows kept, its videos not read again)")
    args = parser.parse_args()
    settings = args.settings.split(",")
    levers = [parse(s) for s in settings]
    if any(lever["every"] != 1 for lever in levers):
        parser.error("--settings: give every as --every (each setting is read at each)")
    everies = [int(n) for n in args.every.split(",")]
    scales = [float(v) for v in args.scales.split(",")]
    every_label = lambda name, n: name if n == 1 else (f"{name}:every={n}" if name != "default" else f"every={n}")  # noqa: E731
    label = lambda name, n, scale=scales[0]: every_label(name, n) + ("" if scale == scales[0] else f":scale={scale:g}")  # noqa: E731
    own = list(zip(settings, levers))
    if args.truth:  # the reference's programs on the true tracks
        settings, levers = settings + ["truth"], levers + [dict(levers[0], truth=True, hold=0, keep=0.0)]
    if args.at_truth:  # each setting's own points, then the grid over the sheet, at their true positions
        settings, levers = (settings + [f"{s or 'default'}@truth" for s, _ in own] + ["grid@truth"],
                            levers + [dict(lever, at_truth=True) for _, lever in own] + [dict(levers[0], grid_truth=True, hold=0, keep=0.0)])
    names = [label(s or "default", n, scale) for s in settings for n in everies for scale in scales]
    rows = []
    if args.csv is not None and args.csv.exists():  # a stopped run's rows: kept, their videos skipped
        with open(args.csv, newline="") as file:
            rows = [{k: (v if k == "light" or k.endswith(" strains") else int(v) if k == "clip" else float(v)) for k, v in row.items()} for row in csv.DictReader(file)]
    done = {(row["light"], row["clip"]) for row in rows}
    for light in LIGHTS:
        if light not in args.lights.split(","):
            continue
        config = long_sheets(args.frames, args.phases, args.families.split(","), light, args.set)
        clips = generate_clips(args.videos, seed=SEED, config=config, start=args.start, vertices=args.truth or args.at_truth or args.sparse)
        behind = generate_clips(args.videos, seed=SEED + 1, config=GeneratorConfig(frames=args.frames, size=config.size), start=args.start).video \
            if args.moving_backdrop else None
        for k, (video, truth, params) in enumerate(zip(clips.video, clips.depth, clips.params)):
            if (light, args.start + k) in done:
                continue
            if args.margin_only:
                rows.append({"light": light, "clip": args.start + k, **margin_shift(video, levers[0], args.margin_check)})
                print(f"{light} {args.start + k}: the box moves the tracks by a median {rows[-1]['margin shift median px']:.4f} px, at most {rows[-1]['margin shift max px']:.3f}", flush=True)
                continue
            true_camera = nrdepth.Camera(*camera(params, config.size)) if params.get("pinhole") is not None else None
            on = np.isfinite(truth)  # NaN off the sheet over a backdrop
            if behind is not None:
                video = np.where(on, video, behind[k])
            network = nrdepth.reconstruct(video, sheet_stage=False).astype(np.float64)
            region = None if on.all() else on[0]
            row = {"light": light, "clip": args.start + k, "network per frame": mae_sn(network, truth, mask=on)}
            base = dense_baselines(truth, on)
            row["plane per frame"], row["bowl per frame"] = base["plane"], base["bowl"]
            score = sparse_scorer(video, region, clips.vertices[k], params, config.size, row, network) if args.sparse else None
            tracks, programs, held_focal = {}, {}, None  # held_focal: the camera a held setting's fov=strain found, for fov=held
            for name, lever in zip([s or "default" for s in settings], levers):
                start = time.perf_counter()
                key = (lever["flow"], lever["margin"], lever["points"], lever["hold"], lever["backward"], lever["drop"], lever["place"], lever["inset"],
                       lever["whole"], lever["fscale"], lever["fb"], lever["stride"])  # keep, each: after the tracks
                if lever.get("truth"):
                    truth_xy, _ = true_tracks(clips.vertices[k], params, config.size, points=lever["points"])
                    tracks[key + ("truth",)] = np.where(in_view(truth_xy, config.size)[..., None], truth_xy, np.nan)
                    key += ("truth",)
                elif lever.get("grid_truth"):  # the stage's grid over the sheet, at the true positions
                    grid = isometric.start_grid(region, video.shape[1:], lever["points"])
                    truth_xy = truth_at(grid, clips.vertices[k], params, config.size)
                    tracks[key + ("grid truth",)] = np.where(in_view(truth_xy, config.size)[..., None], truth_xy, np.nan)
                    key += ("grid truth",)
                elif key not in tracks:
                    with held_thresholds(fb=lever["fb"]):
                        tracks[key] = isometric.track_grid(video, None if lever["whole"] else inset_region(region, lever["inset"]), points=lever["points"],
                                                           drop=lever["drop"], flow=lever["flow"], margin=lever["margin"], hold=bool(lever["hold"]),
                                                           backward=bool(lever["backward"]), place=lever["place"], flow_scale=lever["fscale"],
                                                           stride=lever["stride"])
                held = held_share(tracks[key], video.shape[1:]) if lever["hold"] else 1.0  # before keep, as the stage gates
                xy = keep_held(tracks[key], video.shape[1:], lever)
                if lever["onsheet"]:  # an oracle: the points that start off the sheet left out
                    start_px = np.clip(np.rint(np.nan_to_num(xy[0], nan=-1)).astype(int), 0, [video.shape[2] - 1, video.shape[1] - 1])
                    xy = xy[:, np.isfinite(xy[0]).all(axis=1) & on[0][start_px[:, 1], start_px[:, 0]]]
                if lever.get("at_truth"):  # the same points, lost where they are, at their true positions
                    xy = np.where(np.isfinite(xy), truth_at(xy[0], clips.vertices[k], params, config.size), np.nan)
                if lever["piece"]:  # of the points read, the one piece that moves most (kinect_box_parts)
                    area = video.shape[1] * video.shape[2] if lever["whole"] or region is None else region.sum()
                    xy = xy[:, moving_piece(xy, np.ones(xy.shape[1], bool), float(np.sqrt(area / lever["points"])))]
                tracked = time.perf_counter()
                row[f"{name} held"] = held
                first_px = np.clip(np.rint(xy[0]).astype(int), 0, [video.shape[2] - 1, video.shape[1] - 1])  # how many points are read, and the share of them that start on the sheet
                row[f"{name} points"], row[f"{name} on sheet"] = xy.shape[1], float(np.mean(on[0][first_px[:, 1], first_px[:, 0]]))
                try:
                    if held < args.min_held:
                        raise ValueError(f"{held:.2f} of the point-frames held")
                    if lever["fov"] == "held":  # the held points' estimate, where a held setting before found one; the guess elsewhere
                        through = held_focal or nrdepth.Camera.guessed(video.shape[1:])
                    else:
                        through = pinhole(lever["fov"], true_camera, xy, video.shape[1:])
                        held_focal = through if lever["fov"] == "strain" and lever["hold"] else held_focal
                    if through is None:
                        raise SystemExit(f"--settings {name!r}: the video is seen orthographically: only a guessed camera (fov=) reads it")
                    if lever["trim"]:  # of the points read, those whose pairs keep their lengths
                        xy = trim_strained(xy, through, lever)
                        trimmed_px = np.clip(np.rint(xy[0]).astype(int), 0, [video.shape[2] - 1, video.shape[1] - 1])
                        row[f"{name} trimmed"], row[f"{name} trimmed on sheet"] = xy.shape[1], float(np.mean(on[0][trimmed_px[:, 1], trimmed_px[:, 0]]))
                    # One every: solved as the stage solves it; several: read off the every-frame solution
                    depths, distances = program(xy, through, lever, everies[0] if len(everies) == 1 else 1)
                except ValueError as error:  # the stage steps aside: the network's depth
                    print(f"  {name}: steps aside ({error})", flush=True)
                    for n in everies:
                        for scale in scales:
                            row[f"{label(name, n, scale)} per frame"] = row["network per frame"]
                            if score is not None:
                                row[f"{label(name, n, scale)} sparse"] = row["network sparse"]
                    row[f"{name} points s"], row[f"{name} programs s"] = tracked - start, 0.0
                    continue
                solved = time.perf_counter()
                if lever["each"] == "program":
                    row[f"{name} shortfall"] = shortfall(xy, depths, through, distances, dict(lever, every=everies[0] if len(everies) == 1 else 1))
                row[f"{name} strain"] = strain(xy, depths, through, distances, lever)
                if lever["contrast"]:  # how sharply the strain picks a focal length: recorded for a gate, not used here
                    estimate = isometric.estimate_focal(xy[:, np.isfinite(xy).all(axis=(0, 2))], video.shape[1:], evaluations=lever["cevals"],
                                                        smooth=lever["csmooth"], anchor=lever["canchor"])
                    row[f"{name} contrast"] = estimate.contrast
                    row[f"{name} strains"] = " ".join(f"{s:.6g}" for s in estimate.strains)  # the whole curve, for gates read off it later
                    if lever["estimate"] == 1 or (lever["estimate"] == 2 and estimate.inside):
                        # the depths through the estimate (2: where its least lies two steps inside the grid); strain and contrast as read
                        through = nrdepth.Camera(estimate.focal).at(video.shape[1:])
                        depths, distances = program(xy, through, lever, everies[0] if len(everies) == 1 else 1)
                if lever["rsmooth"]:  # the gates read the tracks as they are; the shape fused, the points smoothed in time
                    xy = gaussian_filter1d(xy, lever["rsmooth"], axis=0, mode="nearest")
                    depths, distances = program(xy, through, lever, everies[0] if len(everies) == 1 else 1)
                if true_camera is not None:
                    row[f"{name} focal ratio"] = float(through.focal[0] / true_camera.focal[0])
                same = (key, lever["keep"], lever["keyframes"], lever["neighbours"], lever["template"], lever["throughout"])
                programs[same + (lever["each"],)] = depths
                if lever["each"] == "lengths" and same + ("program",) in programs:
                    # every solved frame refined, or none (mdh_depths): which, beside the same points' program read before
                    refined = float(not np.array_equal(depths, programs[same + ("program",)], equal_nan=True))
                    row.update({f"{label(name, n)} refined": refined for n in everies})
                for n in everies:
                    kept = depths.copy()
                    if n > 1 and len(everies) > 1:
                        anchors = solved_frames(len(xy), keyframe_indices(len(xy), lever["keyframes"]), n)
                        _between(kept, anchors, np.isfinite(xy).all(axis=2))
                    try:
                        dense = densify(xy, kept, video.shape)
                    except ValueError as error:  # points on one line or fewer (the stage's MIN_READ turns such a video away): the network's depth
                        print(f"  {name}: steps aside ({error})", flush=True)
                        dense = None
                    for scale in scales:
                        fused = network if dense is None else isometric.fuse(network, dense, scale * config.size)
                        row[f"{label(name, n, scale)} per frame"] = mae_sn(fused, truth, mask=on)
                        if score is not None:
                            row[f"{label(name, n, scale)} sparse"] = score(fused)
                row[f"{name} points s"], row[f"{name} programs s"] = tracked - start, solved - tracked
            if args.margin_check is not None:
                row.update(margin_shift(video, levers[0], args.margin_check))
            rows.append(row)
            if args.csv is not None:  # rewritten whole after each video: a stopped run keeps what it read
                with open(args.csv, "w", newline="") as out:
                    writer = csv.DictWriter(out, fieldnames=list(dict.fromkeys(k for r in rows for k in r)), restval="nan")
                    writer.writeheader()
                    writer.writerows({k: (f"{v:.5f}" if isinstance(v, float) else v) for k, v in r.items()} for r in rows)
            print(f"{light} {args.start + k}: " + ", ".join(f"{n} {row[f'{n} per frame']:.4f}" for n in ["network", *names]), flush=True)
    if args.margin_only:
        print(f"{len(rows)} sheets: the flow over the points' box and {args.margin_check} px moves their tracks by a median "
              f"{np.median([r['margin shift median px'] for r in rows]):.4f} px (the videos' medians' median; at most {max(r['margin shift max px'] for r in rows):.3f} px)")
        return
    report(rows, names)


def program(xy: np.ndarray, camera, lever: dict, every: int) -> tuple:
    """A setting's programs over its points ``xy`` through ``camera``
    (``mdh_depths`` with its keyframes, neighbours, each frame, template and
    anchor, every ``every``-th frame solved): depths and template distances."""
    return isometric.mdh_depths(xy, camera, keyframes=lever["keyframes"], neighbours=lever["neighbours"], every=every, each_frame=lever["each"],
                                template=lever["template"], anchor=lever["anchor"], with_distances=True)


def truth_at(start: np.ndarray, vertices: np.ndarray, params: dict, size: int, depth: bool = False) -> np.ndarray:
    """The true image positions (T, n, 2) of the mesh vertices nearest the
    first frame's points ``start`` (n, 2); with ``depth`` their depths too (T, n, 3)."""
    from scipy.spatial import cKDTree

    from nrdepth.engine.generate import image_points

    seen = image_points(vertices.reshape(len(vertices), -1, 3), params, size)
    _, nearest = cKDTree(seen[0, :, :2]).query(start)
    return seen[:, nearest] if depth else seen[:, nearest, :2]


def sparse_scorer(video: np.ndarray, region, vertices: np.ndarray, params: dict, size: int, row: dict, network: np.ndarray):
    """``--sparse``: the points over ``region`` held to their first look in
    the stage's share of their frames (its held tracker and ``KEEP_HELD``), their true positions and
    depths where held and in view; writes the network's, the plane's and the
    bowl's sparse figures and the points' count into ``row``, and returns
    the scorer of a depth video (NaN where a frame keeps fewer than 8)."""
    held = isometric.track_grid(video, region, margin=FLOW_MARGIN, hold=True)
    held = held[:, isometric.point_held_shares(held, video.shape[1:]) >= KEEP_HELD]
    true = truth_at(held[0], vertices, params, size, depth=True)
    mask = np.isfinite(held).all(axis=2) & in_view(true[..., :2], size)
    uv, z = np.moveaxis(true[..., :2], 2, 1), true[..., 2]
    row["sparse points"] = float(held.shape[1])
    usable = mask.sum(axis=1).min() >= 8 if held.shape[1] else False
    score = (lambda depth: sparse_mae(depth, uv, z, mask)) if usable else (lambda depth: float("nan"))
    row["network sparse"] = score(network)
    base = sparse_baselines(uv, z, mask) if usable else {"plane": np.nan, "bowl": np.nan}
    row["plane sparse"], row["bowl sparse"] = float(base["plane"]), float(base["bowl"])
    return score


def margin_shift(video: np.ndarray, reference: dict, margin: int) -> dict:
    """How far (px) the flow over the points' box and ``margin`` moves the reference's tracks: median and largest."""
    every_point = [isometric.track_grid(video, points=reference["points"], flow=reference["flow"], margin=m)
                   for m in (reference["margin"], margin)]  # drop 0: the same points both ways
    shift = np.linalg.norm(every_point[1] - every_point[0], axis=2)
    return {"margin shift median px": float(np.nanmedian(shift)), "margin shift max px": float(np.nanmax(shift))}


def report(rows: list, names: list) -> None:
    print(f"{len(rows)} sheets:")
    for name in ["network", *names, "plane", "bowl"]:
        line = f"  {name:>32s}: per frame {np.mean([r[f'{name} per frame'] for r in rows]):.4f}"
        if f"{name} points s" in rows[0]:
            line += f", points {np.mean([r[f'{name} points s'] for r in rows]):.1f} s, programs {np.mean([r[f'{name} programs s'] for r in rows]):.1f} s"
        if name in names[1:]:
            difference = np.array([r[f"{name} per frame"] - r[f"{names[0]} per frame"] for r in rows])
            line += f", against {names[0]} {difference.mean():+.5f} ± {difference.std(ddof=1) / math.sqrt(len(rows)):.5f} (better on {int((difference < 0).sum())})"
        refined = [r[f"{name} refined"] for r in rows if np.isfinite(r.get(f"{name} refined", np.nan))]
        if refined:
            line += f", every frame refined on {int(sum(refined))} of {len(refined)}"
        print(line)
    if "margin shift max px" in rows[0]:
        print(f"  the flow over the points' box moves their tracks by a median {np.median([r['margin shift median px'] for r in rows]):.4f} px "
              f"(per video; at most {max(r['margin shift max px'] for r in rows):.3f} px)")


if __name__ == "__main__":
    main()
