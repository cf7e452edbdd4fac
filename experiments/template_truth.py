"""Why the sheet stage reads the real paper and not the generated sheets:
its template distances, at true image positions (no tracker).

For each generated paper-like sheet (``--videos`` geometries from
``--start``, lit from below; the light does not move the mesh) the stage's
grid over the sheet in the first frame, at the mesh's true positions while
in view (``sheet_levers.truth_at``, ``isometric_generated.in_view``), and
for ``kinect_paper`` its 301 MDH points at their given positions in the 23
ground-truth frames: the pairs (8 neighbours), their true lengths, the
template distances ``--template`` estimates (``mdh_depths(with_distances=True)``,
8 keyframes, lengths kept: the stage's; ``joint`` by default, as the
stage, or ``refined``), and the program's depths through that template
and through the true lengths. Printed per video:

- the template's error, each pair's estimate over its true length (scaled
  by the median): 5th and 95th percentiles;
- the share of pairs never seen face-on: in no frame in view is their
  image length at least 0.9 of what the pair would show facing the camera
  at its depth (``f · length / depth``);
- the program's error at the points (each frame's GBR fit, as
  ``sparse_mae``), over the fixed bowl's, through each template;
- the same, for each generated sheet, with only the points in view in
  every frame, as the paper's are.

    python experiments/template_truth.py [--videos 16] [--start 864] [--template refined]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

import nrdepth
from nrdepth import generate_clips, isometric
from nrdepth.scores.metrics import sparse_baselines

sys.path.insert(0, str(Path(__file__).parent))
from isometric_generated import SEED, camera, in_view, long_sheets  # noqa: E402
from sheet_levers import truth_at  # noqa: E402

PAPER_LIKE = [("backdrop_probability", 1.0), ("backdrop_flat_probability", 0.0), ("sheet_bend_angle", (-3.0, 3.0)),
              ("sheet_bends", (2.0, 3.0)), ("sheet_relief", (0.0, 0.0))]
FACE_ON = 0.9


def read(xy: np.ndarray, points: np.ndarray, seen: np.ndarray, cam: nrdepth.Camera, template: str = "joint") -> dict:
    """``xy`` (T, n, 2) true positions (NaN out of view), ``points`` (T, n, 3)
    the points in the camera's frame (x, y, depth along the axis), ``seen``
    (T, n): ``template``'s (``mdh_depths``') error, the share never seen face-on and the
    program's error through each template, over the bowl's."""
    pairs = isometric.neighbour_pairs(xy[0], 8)
    both = seen[:, pairs[:, 0]] & seen[:, pairs[:, 1]]
    chords = np.linalg.norm(points[:, pairs[:, 0]] - points[:, pairs[:, 1]], axis=2)
    lengths = np.nanmedian(np.where(both, chords, np.nan), axis=0)  # the true lengths (the data set's points vary by ~2 %)
    depths, estimate = isometric.mdh_depths(xy, cam, pairs=pairs, keyframes=8, template=template, each_frame="lengths", with_distances=True)
    through_truth = isometric.mdh_depths(xy, cam, pairs=pairs, template=lengths, each_frame="lengths")
    ratio = estimate / lengths
    ratio /= np.median(ratio)
    image = np.linalg.norm(xy[:, pairs[:, 0]] - xy[:, pairs[:, 1]], axis=2)
    facing = cam.focal[0] * lengths / (0.5 * (points[:, pairs[:, 0], 2] + points[:, pairs[:, 1], 2]))
    face_on = np.nanmax(np.where(both, image / facing, np.nan), axis=0)
    uv, z = np.moveaxis(np.nan_to_num(xy), 2, 1), points[..., 2]
    bowl = sparse_baselines(uv, z, seen)["bowl"]
    score = lambda d: point_error(xy, d, z, seen)  # noqa: E731
    return {"template p5": np.percentile(ratio, 5), "template p95": np.percentile(ratio, 95), "never face-on": float(np.mean(face_on < FACE_ON)),
            "estimated": score(depths) / bowl, "true lengths": score(through_truth) / bowl}


def point_error(xy: np.ndarray, depths: np.ndarray, z: np.ndarray, seen: np.ndarray) -> float:
    """Mean over frames of the mean absolute error of the points' ``depths``
    (T, n) against their true ``z`` after each frame's fit
    ``a·u + b·v + λ·depth + t`` (``sparse_mae``'s, at the points themselves)."""
    errors = []
    for t in range(len(z)):
        m = seen[t] & np.isfinite(depths[t])
        design = np.column_stack([xy[t, m], depths[t, m], np.ones(m.sum())])
        fit, *_ = np.linalg.lstsq(design, z[t, m], rcond=None)
        errors.append(np.abs(design @ fit - z[t, m]).mean())
    return float(np.mean(errors))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--videos", type=int, default=16, help="generated geometries")
    parser.add_argument("--start", type=int, default=864, help="the first one's index in the held-out seed's draws")
    parser.add_argument("--template", default="joint", choices=("joint", "refined"), help="mdh_depths' template (the stage's: joint)")
    args = parser.parse_args()
    rows = []
    truth = np.load(Path(__file__).parents[1].parent / "shared/data/real/kinect_paper/gt_mdh.npz")
    K = truth["K"]
    xy, points = np.moveaxis(truth["uv"], 1, 2).astype(np.float64), np.moveaxis(truth["P"], 1, 2).astype(np.float64)
    rows.append(("kinect_paper", read(xy, points, np.ones(xy.shape[:2], bool), nrdepth.Camera((K[0, 0], K[1, 1]), (K[0, 2], K[1, 2])), args.template)))
    print(line(*rows[-1]), flush=True)
    config = long_sheets(64, 4, ["print"], "below", PAPER_LIKE)
    clips = generate_clips(args.videos, seed=SEED, config=config, start=args.start, vertices=True)
    kept = []
    for k, (truth_depth, params) in enumerate(zip(clips.depth, clips.params)):
        grid = isometric.start_grid(np.isfinite(truth_depth[0]), truth_depth.shape[1:], 400)
        points = truth_at(grid, clips.vertices[k], params, config.size, depth=True)
        seen = in_view(points[..., :2], config.size)
        cam = nrdepth.Camera(*camera(params, config.size))
        # (column, row, depth) to the camera's frame: x, y from the rays
        rays = np.stack([(points[..., 0] - cam.centre[0]) / cam.focal[0], (points[..., 1] - cam.centre[1]) / cam.focal[1]], axis=-1)
        metric = np.concatenate([rays * points[..., 2:], points[..., 2:]], axis=-1)
        rows.append((str(args.start + k), read(np.where(seen[..., None], points[..., :2], np.nan), metric, seen, cam, args.template)))
        print(line(*rows[-1]), flush=True)
        throughout = seen.all(axis=0)  # as the paper's points: none leaves the view
        kept.append(read(points[:, throughout, :2], metric[:, throughout], seen[:, throughout], cam, args.template))
        print(f"  {throughout.mean():.0%} of the points in view throughout, those alone: " + line("", kept[-1]).lstrip(": "), flush=True)
    generated = [r for name, r in rows[1:]]
    print(f"{len(generated)} generated sheets, means: " + ", ".join(f"{key} {np.mean([r[key] for r in generated]):.3f}" for key in generated[0])
          + f"; corr(never face-on, estimated) {np.corrcoef([r['never face-on'] for r in generated], [r['estimated'] for r in generated])[0, 1]:.2f}")
    print("  the points in view throughout alone, means: " + ", ".join(f"{key} {np.mean([r[key] for r in kept]):.3f}" for key in kept[0]))


def line(name: str, r: dict) -> str:
    return (f"{name}: template/true p5 {r['template p5']:.3f} p95 {r['template p95']:.3f}, never face-on {r['never face-on']:.1%}; "
            f"the program over the bowl through its template {r['estimated']:.3f}, through the true lengths {r['true lengths']:.3f}")


if __name__ == "__main__":
    main()
