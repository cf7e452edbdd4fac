"""Each frame's shape or its mirror: the maximum-depth program pulls every
frame's sheet away from the camera, so a sheet bent towards it comes out
mirrored (docs/findings.md). Here each frame solved by ``mdh_depths`` is
refined to keep its pairs' template distances (least squares of the
strains, the distances fixed), once from the program's depths and once
from their mirror along the rays about the points' best plane, and the
one that keeps the lengths better is taken. On generated print sheets
from their true tracks (no tracking error), per frame MAE-SN and the
share of frames whose sign is right, paired over the same sheets: the
program, each refined start alone, the choice by strain, and the choice
by the truth (what a perfect choice would reach).

    python experiments/sheet_mirror.py [--videos 8] [--start 400] [--frames 64] [--phases 4] [--set sheet_bend_angle=-2.2,-0.5]
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from nrdepth import generate_clips, isometric
from nrdepth.baselines.tracks import densify
from nrdepth.camera import Camera
from nrdepth.scores.metrics import dense_baselines, mae_sn, sign_rates

from isometric_generated import SEED, camera, long_sheets, setting, true_tracks


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--videos", type=int, default=8)
    parser.add_argument("--start", type=int, default=400)
    parser.add_argument("--frames", type=int, default=64)
    parser.add_argument("--phases", type=int, default=4)
    parser.add_argument("--every", type=int, default=1, help="mdh_depths' every")
    parser.add_argument("--keyframes", type=int, default=24)
    parser.add_argument("--noise", type=float, default=0.0, help="px of independent noise added to the true tracks")
    parser.add_argument("--set", action="append", default=[], metavar="FIELD=V[,V]", type=setting)
    args = parser.parse_args()
    config = long_sheets(args.frames, args.phases, ("print",), "below", args.set)
    clips = generate_clips(args.videos, seed=SEED, config=config, start=args.start, vertices=True)
    names = ["program", "refined", "mirror refined", "by strain", "by truth"]
    rows, started = [], time.perf_counter()
    rng = np.random.default_rng(SEED)
    for k, (video, truth, params) in enumerate(zip(clips.video, clips.depth, clips.params)):
        focal, centre = camera(params, config.size)
        xy, _ = true_tracks(clips.vertices[k], params, config.size)
        xy = xy + rng.normal(0, args.noise, xy.shape) if args.noise else xy
        pairs = isometric.neighbour_pairs(xy[0])
        cam = Camera(focal, centre)
        depths, distances = isometric.mdh_depths(xy, cam, pairs=pairs, keyframes=args.keyframes, every=args.every, with_distances=True)
        rays = cam.rays(xy)
        program, straight, mirrored, chosen = (np.empty_like(depths) for _ in range(4))
        for t in range(len(xy)):
            program[t] = depths[t]
            straight[t], strain_straight = isometric.keep_lengths(rays[t], pairs, depths[t], distances)
            mirrored[t], strain_mirrored = isometric.keep_lengths(rays[t], pairs, isometric.mirror_depths(rays[t], depths[t]), distances)
            chosen[t] = straight[t] if strain_straight <= strain_mirrored else mirrored[t]
        dense = {name: densify(xy, d, video.shape) for name, d in zip(names[:4], (program, straight, mirrored, chosen))}
        on = np.isfinite(truth)  # a backdrop clip's truth is NaN off the sheet
        row = {name: (np.array([mae_sn(d[t : t + 1], truth[t : t + 1], mask=on[t : t + 1]) for t in range(len(d))]),
                      sign_rates(d, truth, on)["sign_correct"]) for name, d in dense.items()}
        best = np.minimum(row["refined"][0], row["mirror refined"][0])
        row = {name: (float(errors.mean()), sign) for name, (errors, sign) in row.items()}
        row["by truth"] = (float(best.mean()), np.nan)
        base = dense_baselines(truth, on)
        row["plane"], row["bowl"] = (base["plane"], np.nan), (base["bowl"], np.nan)
        rows.append(row)
        print(f"sheet {args.start + k}: " + ", ".join(f"{name} {row[name][0]:.4f}" for name in names + ["bowl"]), flush=True)
    print(f"{len(rows)} sheets ({time.perf_counter() - started:.0f} s):")
    for name in names + ["plane", "bowl"]:
        line = f"  {name:>15s}: per frame {np.mean([r[name][0] for r in rows]):.4f}"
        if name != "program":
            difference = np.array([r[name][0] - r["program"][0] for r in rows])
            line += f", against the program {difference.mean():+.4f} ± {difference.std(ddof=1) / math.sqrt(len(rows)):.4f}"
        if not np.isnan(rows[0][name][1]):
            line += f", sign right in {100 * np.mean([r[name][1] for r in rows]):3.0f} % of frames"
        print(line)


if __name__ == "__main__":
    main()
