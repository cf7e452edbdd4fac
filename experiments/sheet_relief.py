"""How much a sheet bends in view: each frame's relief over its extent,
the standard deviation of the visible 3-D points' distance (along z) from
their best plane ``Z = a X + b Y + c`` over their extent in x, its median
over the frames. On generated print sheets through pinholes (the mesh's
vertices in view every 8th frame, ``image_points``; with ``--set`` any
``GeneratorConfig`` field, as ``isometric_generated.py`` takes it) and on
the two real videos' ground truth (``kinect_paper``'s 301 points in its
23 frames, ``phisft_R1``'s point clouds every 3rd frame). Inextensibility
reads a bend through perspective, so a sheet that bends less relative to
its size gives it less to read.

    python experiments/sheet_relief.py [--videos 12] [--start 400] [--set backdrop_probability=1]
"""

from __future__ import annotations

import argparse

import numpy as np

from nrdepth import generate_clips, image_points
from nrdepth.camera import Camera
from nrdepth.scores.real import data_folder

from isometric_generated import SEED, camera, long_sheets, setting


def relief_over_extent(points: np.ndarray) -> float:
    """The points' (n, 3) distance along z from their best plane, its standard deviation over their extent in x."""
    design = np.column_stack([points[:, 0], points[:, 1], np.ones(len(points))])
    height = points[:, 2] - design @ np.linalg.lstsq(design, points[:, 2], rcond=None)[0]
    return float(height.std() / np.ptp(points[:, 0]))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--videos", type=int, default=12)
    parser.add_argument("--start", type=int, default=400)
    parser.add_argument("--frames", type=int, default=64)
    parser.add_argument("--phases", type=int, default=4)
    parser.add_argument("--set", action="append", default=[], metavar="FIELD=V[,V]", type=setting)
    args = parser.parse_args()
    kinect = np.load(data_folder("kinect_paper") / "gt_mdh.npz")["P"]  # (23, 3, 301), mm
    print(f"kinect_paper: median {np.median([relief_over_extent(p.T) for p in kinect]):.4f}")
    clouds = np.load(data_folder("phisft_R1") / "gt_pointclouds.npz")
    offsets = clouds["offsets"]
    cloth = [relief_over_extent(clouds["points"][offsets[t] : offsets[t + 1]].astype(np.float64)) for t in range(0, len(offsets) - 1, 3)]
    print(f"phisft_R1: median {np.median(cloth):.4f}")
    config = long_sheets(args.frames, args.phases, ("print",), "above", args.set, grid=64)  # the shape, not the light, is read
    clips = generate_clips(args.videos, seed=SEED, config=config, start=args.start, vertices=True)
    medians = []
    for k, params in enumerate(clips.params):
        focal, centre = camera(params, config.size)
        rays = Camera(focal, centre)
        readings, shares = [], []
        for t in range(0, args.frames, 8):
            seen = image_points(clips.vertices[k][t].reshape(-1, 3), params, config.size)
            inside = (seen[:, :2] >= 0).all(1) & (seen[:, :2] <= config.size - 1).all(1)
            readings.append(relief_over_extent(rays.rays(seen[inside, :2]) * seen[inside, 2:3]))
            shares.append(inside.mean())
        medians.append(np.median(readings))
        print(f"  sheet {args.start + k}: median {medians[-1]:.4f}, most {max(readings):.4f}, {np.median(shares):.0%} of the sheet in view", flush=True)
    print(f"{args.videos} generated sheets: median of their medians {np.median(medians):.4f} (quartiles {np.percentile(medians, 25):.4f}–{np.percentile(medians, 75):.4f})")


if __name__ == "__main__":
    main()
