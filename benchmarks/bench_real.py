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
fitted to each frame of the truth (``nrdepth.scores.metrics.dense_baselines``).

kinect_paper: the whole 640×480×191 video, cropped to the sheet
(``KINECT_ROI``) and, reconstructed on its own, to a crop inside it
(``KINECT_INNER``), each scored on the points of ``gt_mdh.npz`` inside it as
its README asks (depth sampled at the points of each of 23 frames, GBR
fitted per frame, MAE in mm; the relief's sign from the fit's λ), beside
CSF2 on points tracked on the print (48-frame windows, shorter where the
tracker loses the points; K = 2), a plane, a fixed bowl and
the best quadratic fitted to the truth.

    python benchmarks/bench_real.py [--model PATH] [--out docs/benchmarks] [--skip-csf2]
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
from nrdepth.io.figures import ColourBar
from nrdepth.scores.metrics import dense_baselines, flat_baseline, gbr_align, mae_sn, sign_rates
from nrdepth.engine.preview import save_png
from nrdepth.io import colorize_depth, depth_range, read_video
from nrdepth.io.figures import frame_rows, gray_rgb
from nrdepth.scores.real import DATA, KINECT_INNER, KINECT_ROI, kinect_references, kinect_score, kinect_truth, phisft_at_bin

def crop_arg(text: str) -> tuple:
    top, bottom, left, right = (int(v) for v in text.split(","))
    return top, bottom, left, right


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
    save_png(out / "phisft_R1.png", frame_rows([gray_rgb(video)] + colour, ["frames", "ground truth", "nrdepth"], ColourBar(*value_range, "Kinect depth (m)")))
    print(f"wrote {out / 'phisft_R1.png'}: frames | ground truth | nrdepth (GBR-aligned per frame; far = blue, no ground truth = far)")


def csf2_depth(video: np.ndarray, mask: np.ndarray, window: int = 48, K: int = 2, d_fraction: float = 0.1) -> tuple:
    """CSF2 (``nrdepth.baselines.nrsfm``) on points tracked inside ``mask`` (H, W)
    (``nrdepth.baselines.tracks``), in windows of ``window`` frames (halved, down to
    a quarter, where too few points survive a window), each densified over
    the frame (nearest outside the points' hull): (T, H, W) and the window
    lengths used."""
    import math

    from nrdepth.baselines.nrsfm import cameras, csf2
    from nrdepth.baselines.tracks import densify, measurement_matrix, nrsfm_depth, track_video

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
            save_png(out / "kinect_paper.png", frame_rows([gray_rgb(video[:48]), colorize_depth(shown, depth_range(shown))], ["frames", "nrdepth"],
                                                       ColourBar(*depth_range(shown), "depth (relative: a video shows it up to a GBR)")))
    print(f"wrote {out / 'kinect_paper.png'}: frames | nrdepth on the whole sheet (one colour range for the video; near = yellow, far = blue)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--model", default=None, help="model.safetensors or run folder (default: the shipped model)")
    parser.add_argument("--crop", type=crop_arg, default=(110, 218, 106, 214), help="TOP,BOTTOM,LEFT,RIGHT of phisft_R1's 270×480 grid")
    parser.add_argument("--out", type=Path, default=Path("docs/benchmarks"), help="folder for the pictures")
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
