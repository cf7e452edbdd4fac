"""The sheets' shape and sign from inextensibility on generated videos:
``reconstruct(video)`` against it fused with the isometric depth at each
``--scales`` (what ``reconstruct(video, focal=…)`` computes, with the
camera's own focal length and principal point) on the same generated
sheets (bends, rolls and folds with a little relief, ``bench_sheets.py``'s
families, a held-out seed), 256×256×16 (``--frames``; ``--phases``: spans
of the video, each bending the sheet a new way, ``GeneratorConfig.sheet_phases``),
through a pinhole of 40–80°, lit
from below (azimuth 180° ± 70°: the shading prior reads them inverted) and
from above (the default lights). Per frame MAE-SN and the share of frames
whose relief sign is right, paired over the same videos, beside the
shape-blind references.

``--trackers`` (``track_grid``'s flow both ways or forward only, or
``truth``: the mesh's own vertices nearest ``track_grid``'s grid, at their
true image positions in every frame, ``generate_clips(vertices=True)``
and ``image_points``; no tracking error, so what is left is the
heuristic's and the video's; with it, each video's flow drift: the flow
both ways from those vertices' first positions, its median distance from
their true positions in the last frame, over the points still in view;
``in view``: the same positions, each point lost from the first frame it
leaves the view, as ``track_points`` loses it: what a tracker could
hold at best), ``--drop`` (with the flow both ways: the shares of points
whose flows disagree most, left out, ``track_grid``'s ``drop``, each read as a tracker), ``--flat-start`` (every sheet starts unbent,
``GeneratorConfig.sheet_flat_start``), ``--set`` (any other ``GeneratorConfig`` field of the sheets, e.g.
``sheet_relief=0,0``: no relief along the normal, which stretches them), ``--template`` (``mdh_depths``'s
template distances: ``joint`` over keyframes, ``refined``, those
refined so that each pair keeps its distance in every keyframe, ``first``, the first
frame as a flat sheet facing the camera, or with ``--trackers truth``,
``truth``, the distances on the flat sheet between the mesh's vertices),
``--pairs`` (the points tied by inextensibility, ``neighbours:far:reach``,
:func:`nrdepth.isometric.neighbour_pairs`) and ``--relief`` (``fuse``'s
one λ per frame, or one for the video): a reading for each combination
given, each paired against the network and against the first combination.
``--lights``: the sheets lit from below, from above, or both (the default;
each light its own ``--videos``).

    python experiments/isometric_generated.py [--videos 32] [--start 0] [--frames 16] [--phases 1] [--textures print] [--scales 0,0.05,0.1,0.2,0.3] [--trackers forward,both,truth] [--drop 0,0.2] [--flat-start] [--template joint,refined,first] [--pairs 20:0:0,10:10:80] [--relief frame,video] [--lights below,above]
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path
from typing import Optional

import numpy as np

from nrdepth.scores.generated import SHEET_FAMILIES as FAMILIES

import nrdepth  # noqa: E402
from nrdepth import GeneratorConfig, generate_clips, image_points, isometric  # noqa: E402
from nrdepth.scores.metrics import dense_baselines, mae_sn, sign_rates  # noqa: E402
from nrdepth.baselines.tracks import densify  # noqa: E402

SEED = 4141
"""A seed no training run or other benchmark draws from."""


def camera(params: dict, size: int) -> tuple:
    """The focal length and principal point, in pixels, of a clip seen through its pinhole."""
    x0, y0, x1, y1 = params["window"]
    px, py = params["pinhole"]["xy"]
    return params["pinhole"]["camera_z"] * size / (x1 - x0), ((px - x0) / (x1 - x0) * size - 0.5, (y1 - py) / (y1 - y0) * size - 0.5)


def true_tracks(vertices: np.ndarray, params: dict, size: int, points: int = 400, region: Optional[np.ndarray] = None) -> tuple:
    """The true image positions (T, n, 2) of the mesh vertices (``vertices``
    (T, grid, grid, 3)) nearest the points of ``track_grid``'s grid over the
    first frame (only those inside ``region`` (size, size), the sheet's
    pixels over a backdrop, where given), in every frame (in view or not),
    and where those vertices lie on the flat sheet (n, 2), before it bends."""
    from scipy.spatial import cKDTree

    seen = image_points(vertices.reshape(len(vertices), -1, 3), params, size)[..., :2]
    spacing = size / np.sqrt(points)
    rows, cols = np.mgrid[spacing / 2 : size : spacing, spacing / 2 : size : spacing]
    if region is not None:
        inside = region[rows.astype(int), cols.astype(int)]
        rows, cols = rows[inside], cols[inside]
    _, nearest = cKDTree(seen[0]).query(np.column_stack([cols.ravel(), rows.ravel()]))
    index, grid = np.unique(nearest), vertices.shape[1]
    return seen[:, index], np.column_stack([index % grid, index // grid]) * 2.0 / (grid - 1) - 1.0


def in_view(xy: np.ndarray, size: int) -> np.ndarray:
    """Which of the positions (T, n, 2) a tracker could still hold: in the
    frame in every frame so far (``track_points`` loses a point for good
    where it leaves the frame)."""
    inside = isometric.inside(xy.reshape(-1, 2), (size, size), isometric.BORDER).reshape(xy.shape[:2])
    return np.logical_and.accumulate(inside, axis=0)


LIGHTS = {"below": (math.pi - 1.22, math.pi + 1.22), "above": None}
"""The sheets' lights: azimuth 180° ± 70° (the shading prior reads them inverted), or the generator's own (from above)."""


def long_sheets(frames: int, phases: int, textures, light: str = "above", sets=(), **fields) -> GeneratorConfig:
    """The long generated sheets these experiments read: 256², through a
    pinhole of 40–80°, lit from ``light`` (:data:`LIGHTS`), ``textures``
    their families, ``sets`` (``--set``'s (field, value) pairs) and
    ``fields`` any other ``GeneratorConfig`` field."""
    azimuth = LIGHTS[light]
    base = dict(frames=frames, size=256, grid=128, sheet_probability=1.0, sheet_phases=phases, texture_families=tuple(textures),
                camera_fov=(0.7, 1.4), crop_share=(1.0, 1.0), **({} if azimuth is None else {"light_azimuth": azimuth}))
    return GeneratorConfig(**{**base, **fields, **dict(sets)})


def setting(item: str) -> tuple:
    """``--set``'s ``field=v`` or ``field=lo,hi`` as (field, float or (lo, hi)), the field one of ``GeneratorConfig``'s
    (a bool field's ``v`` as a bool: 0 or 1)."""
    from dataclasses import fields

    field, _, value = item.partition("=")
    if field not in {f.name for f in fields(GeneratorConfig)} or not value:
        raise ValueError(f"expected FIELD=V or FIELD=LO,HI with a GeneratorConfig field, got {item!r}")
    values = tuple(float(v) for v in value.split(","))
    if isinstance(getattr(GeneratorConfig(), field), bool):
        return field, bool(values[0])
    return field, values[0] if len(values) == 1 else values


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--videos", type=int, default=32)
    parser.add_argument("--start", type=int, default=0, help="the first video's index in the held-out seed's draws (a fresh set of sheets: past those read before)")
    parser.add_argument("--frames", type=int, default=16, help="frames of each video")
    parser.add_argument("--phases", type=int, default=1, help="spans of each video, each bending the sheet a new way")
    parser.add_argument("--scales", type=lambda text: [float(v) for v in text.split(",")], default=[0, 0.05, 0.1, 0.2, 0.3],
                        help="fusion scales, fractions of the frame's side (0: the isometric depth alone)")
    parser.add_argument("--pairs", type=lambda text: [tuple(int(v) for v in item.split(":")) for item in text.split(",")], default=[(20, 0, 0)],
                        help="neighbours:far:reach of each reading (isometric.neighbour_pairs)")
    parser.add_argument("--trackers", type=lambda text: text.split(","), default=["both"],
                        help="isometric.track_grid's flow: forward, both (forward and backward), truth (the mesh's true positions), 'in view' (those a tracker could hold), or a list")
    parser.add_argument("--drop", type=lambda text: [float(v) for v in text.split(",")], default=[0.0],
                        help="with --trackers both: the shares of points whose flows disagree most, left out (isometric.track_grid), each a tracker")
    parser.add_argument("--set", action="append", default=[], metavar="FIELD=V[,V]", type=setting,
                        help="a GeneratorConfig field of the sheets, one value or lo,hi (e.g. sheet_relief=0,0), repeatable")
    parser.add_argument("--flat-start", action="store_true", help="every sheet starts unbent (GeneratorConfig.sheet_flat_start)")
    parser.add_argument("--relief", type=lambda text: text.split(","), default=["frame"], help="fuse's relief: frame, video or both")
    parser.add_argument("--template", type=lambda text: text.split(","), default=["joint"],
                        help="mdh_depths's template distances: joint, refined, first, truth (the flat sheet's, with --trackers truth), or a list")
    parser.add_argument("--lights", type=lambda text: text.split(","), default=["below", "above"], help="the sheets lit from below, above, or both")
    parser.add_argument("--csv", type=Path, default=None, help="also write each video's readings here (one row a video)")
    parser.add_argument("--textures", type=lambda text: tuple(text.split(",")), default=FAMILIES,
                        help="texture families (default: bench_sheets.py's)")
    args = parser.parse_args()
    if not set(args.trackers) <= {"forward", "both", "truth", "in view"} or not set(args.relief) <= {"frame", "video"} or not set(args.template) <= {*isometric.TEMPLATES, "truth"} or not set(args.lights) <= {"below", "above"}:
        parser.error("--trackers takes forward, both, truth and 'in view', --relief frame and video, --template joint, refined, first and truth, --lights below and above")
    if "truth" in args.template and not set(args.trackers) <= {"truth", "in view"}:
        parser.error("--template truth (the flat sheet's distances between the mesh's vertices) needs --trackers truth or 'in view'")
    if args.drop != [0.0] and "both" not in args.trackers:
        parser.error("--drop finds the points to leave out by the flow both ways: it needs --trackers both")
    trackers = [name for tracker in args.trackers for name in ([tracker] if tracker != "both" else [f"both, drop {d:g}" if d else "both" for d in args.drop])]
    combinations = [(tracker, pairs, template, relief) for tracker in trackers for pairs in args.pairs for template in args.template for relief in args.relief]
    label = lambda tracker, pairs, template, relief: "" if len(combinations) == 1 else " ({}, {}:{}:{}, {}, {})".format(tracker, *pairs, template, relief)  # noqa: E731
    fused = [(tracker, pairs, template, relief, s, f"fused at {s:g}{label(tracker, pairs, template, relief)}") for tracker, pairs, template, relief in combinations for s in args.scales]
    names = ["network"] + [name for *_, name in fused]
    first = {name: f"fused at {s:g}{label(*combinations[0])}" for *_, s, name in fused}  # the first combination at the same scale
    every, lights = [], []
    for light in LIGHTS:
        if light not in args.lights:
            continue
        config = long_sheets(args.frames, args.phases, args.textures, light, args.set, sheet_flat_start=args.flat_start)
        clips = generate_clips(args.videos, seed=SEED, config=config, start=args.start, vertices=bool({"truth", "in view"} & set(args.trackers)))
        rows, start = [], time.perf_counter()
        for k, (video, truth, params) in enumerate(zip(clips.video, clips.depth, clips.params)):
            focal, centre = camera(params, config.size)
            network = nrdepth.reconstruct(video, sheet_stage=False)
            sheets, drift = {}, np.nan
            for tracker in trackers:
                if tracker == "truth":
                    xy, flat = true_tracks(clips.vertices[k], params, config.size)
                    drift = float(np.nanmedian(np.linalg.norm(isometric.track_points(video, xy[0])[-1] - xy[-1], axis=1)))  # over the points still in view
                elif tracker == "in view":
                    xy, flat = true_tracks(clips.vertices[k], params, config.size)
                    xy[~in_view(xy, config.size)] = np.nan
                else:
                    xy = isometric.track_grid(video, backward=tracker != "forward", drop=float(tracker.partition("drop ")[2] or 0))
                for pairs in args.pairs:
                    for template in args.template:
                        tied = isometric.neighbour_pairs(xy[0], *pairs)
                        given = np.linalg.norm(flat[tied[:, 0]] - flat[tied[:, 1]], axis=1) if template == "truth" else template
                        depths = isometric.mdh_depths(xy, focal, centre, pairs=tied, keyframes=24, template=given)
                        sheets[tracker, pairs, template] = densify(xy, depths, video.shape)
            readings = {"network": network, **{name: isometric.fuse(network, sheets[tracker, pairs, template], s * config.size, relief=relief)
                                               for tracker, pairs, template, relief, s, name in fused}}
            row = {name: (mae_sn(d, truth), sign_rates(d, truth)["sign_correct"]) for name, d in readings.items()}
            base = dense_baselines(truth)
            row["plane"], row["bowl"] = (base["plane"], np.nan), (base["bowl"], np.nan)
            row["drift"] = drift
            rows.append(row)
        every += rows
        lights += [light] * len(rows)
        report(f"{args.videos} sheets lit from {light} ({time.perf_counter() - start:.0f} s):", rows, names, first)
    report(f"all {len(every)} sheets:", every, names, first)
    if args.csv is not None:
        import csv

        columns = names + ["plane", "bowl"]
        with open(args.csv, "w", newline="") as out:
            writer = csv.writer(out)
            writer.writerow(["light", "clip"] + [f"{n} per frame" for n in columns] + [f"{n} sign right" for n in names] + ["flow drift px"])
            for k, (light, row) in enumerate(zip(lights, every)):
                writer.writerow([light, args.start + k % args.videos] + [f"{row[n][0]:.5f}" for n in columns] + [f"{row[n][1]:.3f}" for n in names] + [f"{row['drift']:.2f}"])
        print(f"wrote {args.csv}")


def paired(rows: list, name: str, other: str) -> str:
    """Mean ± standard error of ``name``'s per-frame figure minus ``other``'s over the same videos."""
    difference = np.array([r[name][0] - r[other][0] for r in rows])
    return f"{difference.mean():+.5f} ± {difference.std(ddof=1) / math.sqrt(len(rows)):.5f}"


def report(title: str, rows: list, names: list, first: dict) -> None:
    print(title)
    for name in names + ["plane", "bowl"]:
        line = f"  {name:>14s}: per frame {np.mean([r[name][0] for r in rows]):.4f}"
        if name in names:
            line += f", sign right in {100 * np.mean([r[name][1] for r in rows]):3.0f} % of frames"
        if name in names[1:]:
            line += f", paired against the network {paired(rows, name, 'network')}"
        if name in first and first[name] != name:
            line += f", against the first combination {paired(rows, name, first[name])}"
        print(line)
    drift = [r["drift"] for r in rows]
    if np.isfinite(drift).all():
        print(f"  the flow both ways drifts from the true positions by {np.median(drift):.2f} px by the last frame (median over points, then over videos; {np.min(drift):.2f}–{np.max(drift):.2f})")

if __name__ == "__main__":
    main()
