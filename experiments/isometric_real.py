"""Both real videos' shape from inextensibility (``nrdepth.isometric``),
alone and fused with the shipped model's depth, beside the network and the
shape-blind references.

- ``kinect_paper``: the 640×480 frames and the Kinect's intrinsics
  (``gt_mdh.npz``'s K); points over the print in the first frame (the crop
  inside, as CSF2's tracks in ``bench_real.py``); scored on the whole sheet
  and the crop inside (mm after each frame's GBR; the network reads each
  region as its own video, as ``bench_sheets.py`` does).
- ``phisft_R1``: the network reads the 108×108 crop of the 4×4-binned
  frames, as ``bench_real.py`` does; the points are followed on the full
  1920×1080 frames (as ``reconstruct(focal=...)`` follows them on the
  selected frames whole), over the cloth inside the crop in the first
  frame (gray > 10, 8 pixels in from the matte), with the full frames'
  intrinsics, and their depths spread over the binned crop; MAE-SN per
  frame and from the first frame.

``--scales``: :func:`nrdepth.isometric.fuse`'s length scale, as a fraction
of the region's shorter side (0: the isometric depth alone); ``--relief``
its relief scale, ``--template`` :func:`nrdepth.isometric.mdh_depths`'s
template distances, ``--each-frame`` its ``each_frame``, ``--keyframes`` and ``--every`` its
``keyframes`` and ``every``, ``--far``/``--reach`` the far pairs of
:func:`nrdepth.isometric.neighbour_pairs`, ``--window`` and ``--forward``
:func:`nrdepth.isometric.track_grid`'s flow, ``--hold`` its points held to
the first frame, ``--drop`` the shares of its points
left out where the flow both ways disagrees most, each read in turn;
``--guessed``: both videos through the pinhole a user without a
calibration gets (``nrdepth.Camera.guessed``), not their true cameras. ``--grid``
reads the paper again at each number of points and neighbours given, and
with a focal length off by each factor given (no network): how much the
figure depends on them.

    python experiments/isometric_real.py [--csv docs/reconstruction/isometric_real.csv] [--plot docs/reconstruction/isometric_real.png]
    python experiments/isometric_real.py --drop 0,0.1,0.2,0.3 [--template refined]
    python experiments/isometric_real.py --grid --points 200,400,800 --neighbours 8,12,20
    python experiments/isometric_real.py --grid --focal-factors 0.5,0.7,1.4,2
"""

from __future__ import annotations

import argparse
import csv
import time
from pathlib import Path

import numpy as np

from nrdepth.scores.real import CENTRE, CROP, DATA, FOCAL, KINECT_INNER, KINECT_ROI, kinect_references, kinect_score, kinect_truth

import nrdepth  # noqa: E402
from nrdepth import isometric  # noqa: E402
from nrdepth.scores.metrics import dense_baselines, flat_baseline, mae_sn, sign_rates  # noqa: E402
from nrdepth.io import read_video  # noqa: E402
from nrdepth.reconstruct.options import ISOMETRIC_EACH_FRAME  # noqa: E402

FIGURES = ("kinect_mm", "kinect_inner_mm", "phisft_frame", "phisft_first")


def kinect_inputs() -> tuple:
    frames = read_video(DATA / "kinect_paper").frames
    K = np.load(DATA / "kinect_paper" / "gt_mdh.npz")["K"].astype(np.float64)
    x, y, w, h = KINECT_INNER
    print_area = np.zeros(frames.shape[1:], bool)
    print_area[y : y + h, x : x + w] = True
    return frames, (K[0, 0], K[1, 1]), (K[0, 2], K[1, 2]), print_area


def phisft_crop() -> tuple:
    """The binned crop the network reads and its truth."""
    data = np.load(DATA / "phisft_R1" / "derived_q4.npz")
    top, bottom, left, right = CROP
    return data["gray"][:, top:bottom, left:right], data["depth"][:, top:bottom, left:right]


def phisft_isometric(shape: tuple, points: int, neighbours: int, far: int, reach: int, window: int, backward: bool, template: str, drop: float, hold: bool = False,
                     each_frame: str = "program", anchor: float = 0.0, place: str = "grid", keyframes: int = 24, every: int = 1,
                     guessed: bool = False, keep: float = 0.0, throughout: bool = False, flow: str = "farneback", flow_scale: float = 1.0) -> np.ndarray:
    """The cloth's isometric depth on the binned crop, of ``shape`` (T, H, W), through the true camera or, ``guessed``, ``Camera.guessed``'s;
    with ``hold``, only the points held in ``keep`` of their frames and, ``throughout``, in every frame."""
    from scipy.ndimage import binary_erosion

    from nrdepth.baselines.tracks import densify

    top, bottom, left, right = CROP
    full = read_video(DATA / "phisft_R1" / "rgbs").frames
    cloth = binary_erosion(full[0] > 10, iterations=8)
    inside = np.zeros_like(cloth)
    inside[4 * top : 4 * bottom, 4 * left : 4 * right] = True
    xy = isometric.track_grid(full, cloth & inside, points, window, backward, drop, flow=flow, hold=hold, place=place, flow_scale=flow_scale)
    xy = xy[:, isometric.point_held_shares(xy, full.shape[1:]) >= keep] if keep else xy
    xy = xy[:, np.isfinite(xy).all(axis=(0, 2))] if throughout else xy
    camera = nrdepth.Camera.guessed(full.shape[1:]) if guessed else nrdepth.Camera(FOCAL, CENTRE)
    depths, distances = isometric.mdh_depths(xy, camera, neighbours=neighbours, far=far, reach=reach, template=template, each_frame=each_frame,
                                               anchor=anchor, keyframes=keyframes, every=every, with_distances=True)
    strain = isometric.template_strain(xy, depths, camera, distances, keyframes, neighbours, far, reach)
    print(f"phisft_R1: {xy.shape[1]} points, their keyframes' strain {strain:.4f} (reconstruct.sheet.MAX_STRAIN: the stage's gate on refined)")
    binned = (xy + 0.5) / 4 - 0.5 - np.array([left, top])  # full-frame pixels to the binned crop's
    return densify(binned, depths, shape)


def cached_network(name: str, video: np.ndarray, cache: Path) -> np.ndarray:
    path = cache / f"{name}.npy"
    if not path.exists():
        cache.mkdir(parents=True, exist_ok=True)
        np.save(path, nrdepth.reconstruct(video, sheet_stage=False).astype(np.float32))
    return np.load(path).astype(np.float64)


def read_all(args) -> list:
    """Rows: one per reading (the network, then each ``--drop`` at each scale), each figure of both videos."""
    frames, focal, centre, print_area = kinect_inputs()
    if args.guessed:
        focal, centre = nrdepth.Camera.guessed(frames.shape[1:]).focal, None  # the guess's principal point: the frame's centre
    truth = kinect_truth()
    video, cloth_truth = phisft_crop()
    scored = np.isfinite(cloth_truth)
    networks = {region: cached_network(f"kinect_{region[0]}_{region[1]}", frames[:, region[1] : region[1] + region[3], region[0] : region[0] + region[2]], args.cache)
                for region in (KINECT_ROI, KINECT_INNER)}
    cloth_network = cached_network("phisft", video, args.cache)
    rows = []
    for drop, scale in [(None, None)] + [(drop, scale) for drop in args.drop for scale in args.scales]:
        if drop is not None and scale == args.scales[0]:  # each share's isometric depths, once
            start = time.perf_counter()
            paper = isometric.isometric_depth(frames, focal, centre, mask=print_area, points=args.points[0], neighbours=args.neighbours[0],
                                              far=args.far, reach=args.reach, window=args.window,
                                              backward=not args.forward, template=args.template, drop=drop, hold=args.hold,
                                              each_frame=args.each_frame, anchor=args.anchor, place=args.place, keyframes=args.keyframes, every=args.every,
                                              flow=args.flow, flow_scale=args.flow_scale)
            print(f"kinect_paper: isometric depth in {time.perf_counter() - start:.0f} s")
            start = time.perf_counter()
            cloth = phisft_isometric(video.shape, args.points[0], args.neighbours[0], args.far, args.reach, args.window, not args.forward, args.template, drop,
                                     hold=args.hold, each_frame=args.each_frame, anchor=args.anchor, place=args.place, keyframes=args.keyframes, every=args.every,
                                     guessed=args.guessed, keep=args.keep, throughout=args.throughout, flow=args.flow, flow_scale=args.flow_scale)
            print(f"phisft_R1: isometric depth in {time.perf_counter() - start:.0f} s")
        reading = "network" if scale is None else ("isometric" if scale == 0 else f"fused at {scale:g}") + (f", drop {drop:g}" if len(args.drop) > 1 else "")
        row = {"reading": reading, "drop": "" if drop is None else drop, "scale": "" if scale is None else scale}
        for key, region in (("kinect_mm", KINECT_ROI), ("kinect_inner_mm", KINECT_INNER)):
            x, y, w, h = region
            net = networks[region]
            depth = net if scale is None else isometric.fuse(net, paper[:, y : y + h, x : x + w], scale * min(w, h), relief=args.relief)
            row[key] = kinect_score(depth, truth, region)
            row[key.replace("_mm", "_sign")] = kinect_score(depth, truth, region, signs=True)
        depth = cloth_network if scale is None else isometric.fuse(cloth_network, cloth, scale * min(video.shape[1:]), mask=video > 10, relief=args.relief)
        row["phisft_frame"] = mae_sn(depth, cloth_truth, "frame", mask=scored)
        row["phisft_first"] = mae_sn(depth, cloth_truth, "first", mask=scored)
        row["phisft_sign"] = sign_rates(depth, cloth_truth, mask=scored)["sign_correct"]
        rows.append(row)
        print(f"{row['reading']:>16s}: kinect_paper {row['kinect_mm']:.2f} / {row['kinect_inner_mm']:.2f} mm (sign {row['kinect_sign']:.2f}), "
              f"phisft_R1 {row['phisft_frame']:.4f} / {row['phisft_first']:.4f} (sign {row['phisft_sign']:.2f})", flush=True)
    whole, inner = kinect_references(truth, KINECT_ROI), kinect_references(truth, KINECT_INNER)
    base = dense_baselines(cloth_truth, mask=scored)
    for name in ("plane", "bowl", "quadratic"):
        rows.append({"reading": name, "drop": "", "scale": "", "kinect_mm": whole[name], "kinect_inner_mm": inner[name],
                     "phisft_frame": base[name], "phisft_first": flat_baseline(cloth_truth, "first", mask=scored) if name == "plane" else ""})
        print(f"{name:>16s}: kinect_paper {whole[name]:.2f} / {inner[name]:.2f} mm, phisft_R1 {base[name]:.4f} per frame")
    return rows


def grid(args) -> None:
    frames, focal, centre, print_area = kinect_inputs()
    truth = kinect_truth()
    from nrdepth.baselines.tracks import densify

    for points in args.points:
        xy = isometric.track_grid(frames, print_area, points, args.window, not args.forward, args.drop[0], hold=args.hold)
        for neighbours in args.neighbours:
            for factor in args.focal_factors:
                start = time.perf_counter()
                depth = densify(xy, isometric.mdh_depths(xy, np.multiply(focal, factor), centre, neighbours=neighbours, far=args.far, reach=args.reach), frames.shape)
                scores = [kinect_score(depth[:, y : y + h, x : x + w], truth, (x, y, w, h)) for x, y, w, h in (KINECT_ROI, KINECT_INNER)]
                print(f"{xy.shape[1]} points, {neighbours} neighbours, focal × {factor:g}: kinect_paper {scores[0]:.2f} / {scores[1]:.2f} mm "
                      f"({time.perf_counter() - start:.0f} s)", flush=True)


def plot(rows: list, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    drops = sorted({r["drop"] for r in rows if r["drop"] != ""})
    network = next(r for r in rows if r["reading"] == "network")
    refs = {r["reading"]: r for r in rows if r["reading"] in ("plane", "bowl")}
    fig, axes = plt.subplots(1, 4, figsize=(16, 3.6))
    titles = {"kinect_mm": "kinect_paper, whole sheet (mm)", "kinect_inner_mm": "kinect_paper, crop inside (mm)",
              "phisft_frame": "phisft_R1, MAE-SN per frame", "phisft_first": "phisft_R1, from the first frame"}
    for ax, key in zip(axes, FIGURES):
        for drop in drops:
            curve = [r for r in rows if r["drop"] == drop]
            ax.plot([r["scale"] for r in curve], [r[key] for r in curve], "o-", label=f"isometric fused with the network, drop {drop:g}")
        ax.axhline(network[key], color="k", label="network (shipped)")
        for name, style in (("plane", ":"), ("bowl", "--")):
            if refs[name][key] != "":
                ax.axhline(float(refs[name][key]), color="gray", linestyle=style, label=name)
        ax.set_title(titles[key], fontsize=9)
        ax.set_xlabel("fusion scale (fraction of the shorter side; 0 = isometric alone)", fontsize=7)
    axes[0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    print(f"wrote {path}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    numbers = lambda kind: (lambda text: [kind(v) for v in text.split(",")])  # noqa: E731
    parser.add_argument("--points", type=numbers(int), default=[400], help="points tracked (the first is used without --grid)")
    parser.add_argument("--neighbours", type=numbers(int), default=[20], help="neighbours tied to each point (the first is used without --grid)")
    parser.add_argument("--relief", default="frame", choices=("frame", "video"), help="fuse's relief scale: each frame's own, or one for the video")
    parser.add_argument("--window", type=int, default=21, help="the flow's window in pixels (isometric.track_grid)")
    parser.add_argument("--forward", action="store_true", help="the forward flow alone, not both ways (isometric.track_grid)")
    parser.add_argument("--flow", default="farneback", choices=isometric.FLOWS, help="the dense flow (isometric.track_grid's flow)")
    parser.add_argument("--flow-scale", type=float, default=1.0, help="the flow on frames shrunk by this factor (isometric.track_grid's flow_scale)")
    parser.add_argument("--hold", action="store_true", help="each point found again by its look in the first frame (isometric.track_grid's hold)")
    parser.add_argument("--keep", type=float, default=0.0, help="with --hold, the cloth's points held in this share of their frames alone (isometric.point_held_shares)")
    parser.add_argument("--throughout", action="store_true", help="the cloth's points found in every frame alone")
    parser.add_argument("--place", default="grid", choices=isometric.PLACES, help="where the points go in the first frame (isometric.track_grid's place)")
    parser.add_argument("--template", default="joint", choices=isometric.TEMPLATES,
                        help="mdh_depths's template distances: over keyframes, refined by least squares, or the first frame as a flat sheet facing the camera")
    parser.add_argument("--each-frame", default=ISOMETRIC_EACH_FRAME, choices=isometric.EACH_FRAME, help="mdh_depths's each_frame (default: the stage's)")
    parser.add_argument("--anchor", type=float, default=0.0, help="mdh_depths's anchor (with --each-frame lengths: each refined depth pulled towards the program's)")
    parser.add_argument("--drop", type=numbers(float), default=[0.0],
                        help="shares of the points whose flows both ways disagree most, left out (isometric.track_grid), each read in turn (the first is used with "
                        "--grid; default 0, every point: reconstruct(focal=...) leaves out isometric.DROP)")
    parser.add_argument("--keyframes", type=int, default=24, help="mdh_depths's keyframes in the joint program (the stage's: reconstruct.sheet.KEYFRAMES)")
    parser.add_argument("--every", type=int, default=1, help="mdh_depths's every: only every n-th frame's program solved (the stage's: reconstruct.sheet.EVERY)")
    parser.add_argument("--far", type=int, default=0, help="far pairs of each point (isometric.neighbour_pairs)")
    parser.add_argument("--reach", type=int, default=0, help="the far pairs' largest rank")
    parser.add_argument("--scales", type=numbers(float), default=[0, 0.05, 0.1, 0.2, 0.3, 0.5])
    parser.add_argument("--focal-factors", type=numbers(float), default=[1.0], help="with --grid: the focal length used, times the true one")
    parser.add_argument("--guessed", action="store_true", help="both videos through nrdepth.Camera.guessed's pinhole, not their true cameras")
    parser.add_argument("--grid", action="store_true", help="only the paper, at each --points, --neighbours and --focal-factors")
    parser.add_argument("--cache", type=Path, default=Path("eval_isometric"), help="the network's readings are kept here")
    parser.add_argument("--csv", type=Path)
    parser.add_argument("--plot", type=Path)
    args = parser.parse_args()
    if args.grid:
        return grid(args)
    rows = read_all(args)
    if args.csv:
        with open(args.csv, "w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=list(rows[0]), extrasaction="ignore", lineterminator="\n")
            writer.writeheader()
            writer.writerows({k: (f"{v:.4f}" if isinstance(v, float) else v) for k, v in r.items()} for r in rows)
    if args.plot:
        plot(rows, args.plot)


if __name__ == "__main__":
    main()
