"""Real videos: scores on ``phisft_R1`` (a real cloth video with per-frame
depth ground truth) and ``kinect_paper`` (a bending sheet of paper with
sparse 3-D ground truth), and pictures of both.

phisft_R1: the 50 frames of ``derived_q4.npz`` (luma box-averaged 4×4, 270×480,
ground-truth depth splatted into the same grid; its README), cropped to the
cloth (``--crop``, default rows 110–218 and columns 106–214: 108×108 pixels
inside the cloth's silhouette in every frame, at that grid's scale, no
resizing). Scored over the crop's pixels with a ground-truth value, as the
README asks: MAE-SN per frame and from the first frame, the relief's
sign-correct rate (the camera looks along +z with y down, so depth grows away
from it as nrdepth's does), and a flat plane scored the same way.

phisft_R1's figures come beside the shape-blind references: the plane, a
fixed bowl (a paraboloid, the same in every frame) and the best quadratic
fitted to each frame of the truth (``nrdepth.metrics.dense_baselines``).

kinect_paper: the whole 640×480×191 video, cropped to the sheet
(``KINECT_ROI``) and, reconstructed on its own, to a crop inside it
(``KINECT_INNER``), each scored on the points of ``gt_mdh.npz`` inside it as
its README asks (depth sampled at the points of each of 23 frames, GBR
fitted per frame, MAE in mm; the relief's sign from the fit's λ), beside
CSF2 on points tracked on the print (48-frame windows, shorter where the
tracker loses the points; K = 2), a plane, a fixed bowl and
the best quadratic fitted to the truth.

    python benchmarks/bench_real.py [--model PATH] [--out docs] [--skip-csf2]
    python benchmarks/bench_real.py --write-kinect kinect_sheet.npz      # for nrdepth train --real
    python benchmarks/bench_real.py --write-phisft phisft_bin4.npz       # the same for the cloth
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import torch

import nrdepth
from nrdepth.reconstruct import inference_model
from nrdepth.figures import ColourBar, labelled
from nrdepth.metrics import dense_baselines, flat_baseline, gbr_align, mae_sn, sign_rates, sparse_baselines, sparse_mae, sparse_sign_rate
from nrdepth.preview import save_png
from nrdepth.videoio import colorize_depth, depth_range, read_video

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "real"


CROP = (110, 218, 106, 214)
"""the crop scored here of the 4×4-binned grid: TOP, BOTTOM, LEFT, RIGHT."""
FOCAL, CENTRE = (971.522, 944.575), (962.134, 554.778)
"""The full frames' intrinsics (pixels; the data set's README)."""


def crop_at_bin(b: int) -> tuple:
    """:data:`CROP`'s region on the full frames binned b×b: TOP, BOTTOM, LEFT, RIGHT."""
    return tuple(round(c * 4 / b) for c in CROP)


def phisft_at_bin(b: int) -> tuple:
    """``phisft_R1`` on the full frames box-averaged b×b, cut to the region
    of :data:`CROP`: gray uint8 (50, S, S) and ground-truth Z float32 (metres,
    NaN where no point falls), with S = 108·4/b."""
    root = DATA / "phisft_R1"
    top, bottom, left, right = crop_at_bin(b)
    if b == 4:
        data = np.load(root / "derived_q4.npz")
        return data["gray"][:, top:bottom, left:right], data["depth"][:, top:bottom, left:right]
    full = read_video(root / "rgbs").frames.astype(np.float64)
    t, h, w = full.shape
    gray = np.rint(full[:, : h // b * b, : w // b * b].reshape(t, h // b, b, w // b, b).mean(axis=(2, 4))).astype(np.uint8)
    clouds = np.load(root / "gt_pointclouds.npz")
    depth = np.full(gray.shape, np.nan, np.float32)
    for i in range(t):
        p = clouds["points"][clouds["offsets"][i] : clouds["offsets"][i + 1]].astype(np.float64)
        u, v = ((f * p[:, k] / p[:, 2] + c + 0.5) / b - 0.5 for k, f, c in zip((0, 1), FOCAL, CENTRE))
        iu, iv = np.rint(u).astype(int), np.rint(v).astype(int)
        inside = (iu >= 0) & (iu < w // b) & (iv >= 0) & (iv < h // b)
        far_first = np.argsort(-p[inside, 2], kind="stable")  # the nearest point is written last
        depth[i, iv[inside][far_first], iu[inside][far_first]] = p[inside, 2][far_first]
    return gray[:, top:bottom, left:right], depth[:, top:bottom, left:right]


def crop_arg(text: str) -> tuple:
    top, bottom, left, right = (int(v) for v in text.split(","))
    return top, bottom, left, right


def picture(columns: list, titles: list, colour_bar: "ColourBar | None" = None, frames_shown: int = 4) -> np.ndarray:
    """Rows of frames under column titles, with a depth colour bar when the
    depth columns share one range; each column a (T, H, W, 3) uint8 video."""
    t = len(columns[0])
    rows = []
    for k in np.linspace(0, t - 1, frames_shown).round().astype(int):
        rows.append(np.concatenate([np.pad(c[k], ((2, 2), (2, 2), (0, 0)), constant_values=255) for c in columns], axis=1))
    return labelled(np.concatenate(rows, axis=0), titles, columns[0].shape[2] + 4, colour_bar=colour_bar)


def gray3(video: np.ndarray) -> np.ndarray:
    return np.repeat(video[..., None], 3, axis=-1)


def phisft(model, crop: tuple, out: Path) -> None:
    data = np.load(DATA / "phisft_R1" / "derived_q4.npz")
    top, bottom, left, right = crop
    video = data["gray"][:, top:bottom, left:right]
    truth = data["depth"][:, top:bottom, left:right]
    mask = np.isfinite(truth)
    start = time.perf_counter()
    depth = nrdepth.reconstruct(video, model)
    seconds = time.perf_counter() - start
    ours = {a: mae_sn(depth, truth, a, mask=mask) for a in ("frame", "first")}
    paper = nrdepth.reconstruct(video, model, alignment="coarse", window="triangle")
    theirs = {a: mae_sn(paper, truth, a, mask=mask) for a in ("frame", "first")}
    flat = {a: flat_baseline(truth, a, mask=mask) for a in ("frame", "first")}
    signs = sign_rates(depth, truth, mask=mask)
    t, h, w = video.shape
    print(f"phisft_R1: {t} frames of {w}×{h} (rows {top}–{bottom}, columns {left}–{right} of the 270×480 grid), "
          f"{mask.mean() * 100:.1f} % of pixels with ground truth; reconstructed in {seconds:.1f} s")
    print(f"{'MAE-SN':26s}{'nrdepth':>10s}{'flat plane':>12s}{'ratio':>8s}   (with the paper's stitch)")
    for a, label in (("frame", "align each frame"), ("first", "alignment from 1st frame")):
        print(f"{label:26s}{ours[a]:>10.4f}{flat[a]:>12.4f}{ours[a] / flat[a]:>8.3f}   ({theirs[a]:.4f}, ratio {theirs[a] / flat[a]:.3f})")
    print(f"relief sign correct in {100 * signs['sign_correct']:.1f} % of frames (flips inside the video: {'yes' if signs['flip'] else 'no'})")
    base = dense_baselines(truth, mask=mask)
    print(f"shape-blind references, per frame: plane {base['plane']:.4f}, fixed bowl {base['bowl']:.4f}, "
          f"best quadratic fitted to the truth (oracle) {base['quadratic']:.4f}")
    aligned = np.where(mask, gbr_align(depth, truth, "frame", mask=mask), np.nan)
    value_range = depth_range(np.where(mask, truth, np.nanmedian(truth)))
    colour = [colorize_depth(np.nan_to_num(d, nan=value_range[1]), value_range) for d in (truth, aligned)]
    save_png(out / "phisft_R1.png", picture([gray3(video)] + colour, ["frames", "ground truth", "nrdepth"], ColourBar(*value_range, "Kinect depth (m)")))
    print(f"wrote {out / 'phisft_R1.png'}: frames | ground truth | nrdepth (GBR-aligned per frame; far = blue, no ground truth = far)")


PHISFT_BORDER = 10
"""``phisft_R1``'s border region: the cloth's pixels within this many pixels
(on the 4×4-binned grid) of the black background. In :data:`CROP` they are
the hem and the left edge, a quarter of the scored pixels, and they carry
most of what separates checkpoints on this video (docs/campaign.md)."""


def phisft_regions(gray: np.ndarray, truth: np.ndarray) -> dict:
    """The scored pixels (finite ``truth``) of ``phisft_R1`` frames ``gray``
    (T, H, W) split into ``"border"`` (within :data:`PHISFT_BORDER` pixels of
    the background, gray 0) and ``"inside"``: bool (T, H, W) each."""
    from scipy.ndimage import distance_transform_edt

    scored = np.isfinite(truth)
    near = np.stack([distance_transform_edt(frame > 0) <= PHISFT_BORDER for frame in gray])
    return {"border": scored & near, "inside": scored & ~near}


def scaled_error(aligned: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """MAE-SN's error map of a depth already aligned to ``truth`` (T, H, W):
    the absolute error divided by each frame's truth's standard deviation
    over its finite pixels; NaN where the truth is."""
    spread = np.array([frame[np.isfinite(frame)].std() for frame in truth])[:, None, None]
    return np.abs(aligned - truth) / spread


def region_errors(depth: np.ndarray, truth: np.ndarray, regions: dict) -> dict:
    """MAE-SN per frame split by region: each frame of ``depth`` GBR-aligned
    over all its scored pixels as :func:`~nrdepth.metrics.mae_sn` does, its
    :func:`scaled_error` averaged over each region's pixels (the regions'
    pixel-weighted mean is close to, not equal to, MAE-SN's mean of frame
    means)."""
    error = scaled_error(gbr_align(depth, truth, "frame", mask=np.isfinite(truth)), truth)
    return {name: float(error[region].mean()) for name, region in regions.items()}


KINECT_ROI = (64, 24, 528, 416)
"""x, y, width, height of the whole sheet in kinect_paper's 640×480 frames."""


def kinect_truth() -> dict:
    """``gt_mdh.npz``: ``frames`` (23,) 0-based indices of the frames with
    ground truth, ``uv`` (23, 2, 301) pixel positions, ``z`` (23, 301) depth in mm."""
    gt = np.load(DATA / "kinect_paper" / "gt_mdh.npz")
    return {"frames": gt["file_index"].astype(int) - 1, "uv": gt["uv"].astype(np.float64), "z": gt["P"][:, 2].astype(np.float64)}


def kinect_score(depth: np.ndarray, truth: dict, roi: tuple = KINECT_ROI, signs: bool = False) -> float:
    """MAE in mm of a depth video of the ``roi`` (x, y, w, h) of every frame
    on the sparse ground truth's points inside it (``nrdepth.metrics.sparse_mae``),
    or with ``signs`` the share of frames whose relief sign is right."""
    x, y, w, h = roi
    uv = truth["uv"] - np.array([x, y], np.float64)[None, :, None]
    inside = (uv[:, 0] >= 0) & (uv[:, 0] <= w - 1) & (uv[:, 1] >= 0) & (uv[:, 1] <= h - 1)
    return (sparse_sign_rate if signs else sparse_mae)(depth[truth["frames"]], uv, truth["z"], mask=inside)


def kinect_references(truth: dict, roi: tuple) -> dict:
    """Plane, fixed bowl and oracle quadratic on the points inside ``roi``."""
    x, y, w, h = roi
    u, v = truth["uv"][:, 0] - x, truth["uv"][:, 1] - y
    return sparse_baselines(truth["uv"], truth["z"], mask=(u >= 0) & (u <= w - 1) & (v >= 0) & (v <= h - 1))


def csf2_depth(video: np.ndarray, mask: np.ndarray, window: int = 48, K: int = 2, d_fraction: float = 0.1) -> tuple:
    """CSF2 (``nrdepth.nrsfm``) on points tracked inside ``mask`` (H, W)
    (``nrdepth.tracks``), in windows of ``window`` frames (halved, down to
    a quarter, where too few points survive a window), each densified over
    the frame (nearest outside the points' hull): (T, H, W) and the window
    lengths used."""
    import math

    from nrdepth.nrsfm import cameras, csf2
    from nrdepth.tracks import densify, measurement_matrix, nrsfm_depth, track_video

    parts, lengths, start = [], [], 0
    while start < len(video):
        for length in (window, window // 2, window // 4):
            part = video[start : start + length]
            try:
                xy = track_video(part, max_points=1089, mask=mask)
                break
            except ValueError:
                if length == window // 4:
                    raise
        W = measurement_matrix(xy)
        result = csf2(W, K=K, d=math.ceil(d_fraction * len(part)), Rs=cameras(W))
        parts.append(densify(xy, nrsfm_depth(result.shapes, result.cameras), part.shape))
        lengths.append(len(part))
        start += len(part)
    return np.concatenate(parts), lengths


KINECT_INNER = (200, 96, 320, 272)
"""x, y, width, height of a crop inside the sheet (the printed part in frame 0; ``bench_table3.KINECT_CROP``)."""


def kinect(model, out: Path, roi: tuple = KINECT_ROI, csf2: bool = True) -> None:
    frames = read_video(DATA / "kinect_paper").frames
    truth = kinect_truth()
    print(f"kinect_paper: {len(frames)} frames; MAE on the sparse ground truth ({len(truth['frames'])} frames × {truth['z'].shape[1]} points "
          f"inside each region), mm, and the share of frames whose relief sign is right:")
    for label, region in (("the whole sheet", roi), ("a crop inside it", KINECT_INNER)):
        x, y, w, h = region
        video = frames[:, y : y + h, x : x + w]
        start = time.perf_counter()
        depth = nrdepth.reconstruct(video, model)
        seconds = time.perf_counter() - start
        base = kinect_references(truth, region)
        row = (f"  {label} ({w}×{h} at x {x}, y {y}): nrdepth {kinect_score(depth, truth, region):.2f} "
               f"(sign right in {100 * kinect_score(depth, truth, region, signs=True):.0f} %, {seconds:.1f} s)")
        if csf2:
            start = time.perf_counter()
            # Points on the print, which the tracker follows through a window (the sheet's edges and the hands it loses).
            inner = np.zeros(video.shape[1:], bool)
            ix, iy, iw, ih = KINECT_INNER
            inner[max(iy - y, 0) : iy - y + ih, max(ix - x, 0) : ix - x + iw] = True
            theirs, lengths = csf2_depth(video, inner)
            row += (f", CSF2 on tracks {kinect_score(theirs, truth, region):.2f} (K = 2, windows of {'/'.join(str(n) for n in lengths)} frames, "
                    f"{time.perf_counter() - start:.1f} s)")
        print(row + f", plane {base['plane']:.2f}, fixed bowl {base['bowl']:.2f}, best quadratic (oracle) {base['quadratic']:.2f}")
        if region == roi:
            shown = depth[:48]
            save_png(out / "kinect_paper.png", picture([gray3(video[:48]), colorize_depth(shown, depth_range(shown))], ["frames", "nrdepth"],
                                                       ColourBar(*depth_range(shown), "depth (relative: a video shows it up to a GBR)")))
    print(f"wrote {out / 'kinect_paper.png'}: frames | nrdepth on the whole sheet (one colour range for the video; near = yellow, far = blue)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--model", default=None, help="model.safetensors or run folder (default: the shipped model)")
    parser.add_argument("--crop", type=crop_arg, default=(110, 218, 106, 214), help="TOP,BOTTOM,LEFT,RIGHT of phisft_R1's 270×480 grid")
    parser.add_argument("--out", type=Path, default=Path("docs"), help="folder for the pictures")
    parser.add_argument("--skip-kinect", action="store_true")
    parser.add_argument("--skip-csf2", action="store_true", help="no CSF2 on kinect_paper (tracking and NRSfM take a minute)")
    parser.add_argument("--write-kinect", default=None, metavar="NPZ",
                        help="save kinect_paper's sheet (KINECT_ROI) with its sparse truth for `nrdepth train --real NPZ` and stop")
    parser.add_argument("--write-phisft", default=None, metavar="NPZ",
                        help="save phisft_R1's crop (4×4-binned frames) with its depth for `nrdepth train --real NPZ` and stop")
    args = parser.parse_args()
    if args.write_phisft:
        video, truth = phisft_at_bin(4)
        np.savez_compressed(args.write_phisft, video=video, depth=truth)
        print(f"wrote {args.write_phisft}: phisft_R1's crop, video {video.shape} uint8, depth in metres (NaN: no truth) for nrdepth train --real")
        return
    if args.write_kinect:
        x, y, w, h = KINECT_ROI
        truth = kinect_truth()
        video = read_video(DATA / "kinect_paper").frames[:, y : y + h, x : x + w]
        np.savez_compressed(args.write_kinect, video=video, frames=truth["frames"], uv=truth["uv"] - np.array([x, y], np.float64)[None, :, None], z=truth["z"])
        print(f"wrote {args.write_kinect}: kinect_paper's sheet {video.shape} uint8 and its sparse truth (frames, uv, z in mm) for nrdepth train --real")
        return
    args.out.mkdir(parents=True, exist_ok=True)
    model = inference_model(args.model, torch.device("cpu"))
    phisft(model, args.crop, args.out)
    if not args.skip_kinect:
        kinect(model, args.out, csf2=not args.skip_csf2)


if __name__ == "__main__":
    main()
