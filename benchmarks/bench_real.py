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

kinect_paper: the whole 640×480×191 video, cropped to the sheet
(``KINECT_ROI``), scored on ``gt_mdh.npz`` as its README asks (depth sampled
at the 301 points of each of 23 frames, GBR fitted per frame, MAE in mm),
beside a plane, a fixed bowl and the best quadratic fitted to the truth.

    python benchmarks/bench_real.py [--model PATH] [--out docs]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import torch

import nrdepth
from nrdepth.reconstruct import inference_model
from nrdepth.labels import titled, with_colour_bar
from nrdepth.metrics import flat_baseline, gbr_align, mae_sn, sign_rates, sparse_baselines, sparse_mae
from nrdepth.preview import save_png
from nrdepth.videoio import colorize_depth, depth_range, read_video

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "real"


def crop_arg(text: str) -> tuple:
    top, bottom, left, right = (int(v) for v in text.split(","))
    return top, bottom, left, right


def picture(columns: list, titles: list, frames_shown: int = 4) -> np.ndarray:
    """Rows of frames under column titles, with a depth colour bar; each
    column a (T, H, W, 3) uint8 video."""
    t = len(columns[0])
    rows = []
    for k in np.linspace(0, t - 1, frames_shown).round().astype(int):
        rows.append(np.concatenate([np.pad(c[k], ((2, 2), (2, 2), (0, 0)), constant_values=255) for c in columns], axis=1))
    return with_colour_bar(titled(np.concatenate(rows, axis=0), titles, columns[0].shape[2] + 4), "far", "near")


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
    aligned = np.where(mask, gbr_align(depth, truth, "frame", mask=mask), np.nan)
    value_range = depth_range(np.where(mask, truth, np.nanmedian(truth)))
    colour = [colorize_depth(np.nan_to_num(d, nan=value_range[1]), value_range) for d in (truth, aligned)]
    save_png(out / "phisft_R1.png", picture([gray3(video)] + colour, ["frames", "ground truth", "nrdepth (gbr-aligned)"]))
    print(f"wrote {out / 'phisft_R1.png'}: frames | ground truth | nrdepth (GBR-aligned per frame; far = blue, no ground truth = far)")


KINECT_ROI = (64, 24, 528, 416)
"""x, y, width, height of the whole sheet in kinect_paper's 640×480 frames."""


def kinect_truth() -> dict:
    """``gt_mdh.npz``: ``frames`` (23,) 0-based indices of the frames with
    ground truth, ``uv`` (23, 2, 301) pixel positions, ``z`` (23, 301) depth in mm."""
    gt = np.load(DATA / "kinect_paper" / "gt_mdh.npz")
    return {"frames": gt["file_index"].astype(int) - 1, "uv": gt["uv"].astype(np.float64), "z": gt["P"][:, 2].astype(np.float64)}


def kinect_score(depth: np.ndarray, truth: dict, roi: tuple = KINECT_ROI) -> float:
    """MAE in mm of a depth video of the ``roi`` (x, y, w, h) of every frame
    on the sparse ground truth (``nrdepth.metrics.sparse_mae``)."""
    x, y, _, _ = roi
    return sparse_mae(depth[truth["frames"]], truth["uv"] - np.array([x, y], np.float64)[None, :, None], truth["z"])


def kinect(model, out: Path, roi: tuple = KINECT_ROI) -> None:
    x, y, w, h = roi
    video = read_video(DATA / "kinect_paper").frames[:, y : y + h, x : x + w]
    truth = kinect_truth()
    start = time.perf_counter()
    depth = nrdepth.reconstruct(video, model)
    seconds = time.perf_counter() - start
    base = sparse_baselines(truth["uv"], truth["z"])
    print(f"kinect_paper: {video.shape[0]} frames of {w}×{h} (x {x}–{x + w}, y {y}–{y + h}) reconstructed in {seconds:.1f} s; "
          f"MAE on the sparse ground truth ({len(truth['frames'])} frames × {truth['z'].shape[1]} points), mm:")
    print(f"  nrdepth {kinect_score(depth, truth, roi):.2f}   plane {base['plane']:.2f}   "
          f"fixed bowl {base['bowl']:.2f}   best quadratic (oracle) {base['quadratic']:.2f}")
    shown = depth[:48]
    save_png(out / "kinect_paper.png", picture([gray3(video[:48]), colorize_depth(shown, depth_range(shown))], ["frames", "nrdepth"]))
    print(f"wrote {out / 'kinect_paper.png'}: frames | nrdepth (one colour range for the video; near = yellow, far = blue)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--model", default=None, help="model.safetensors or run folder (default: the shipped model)")
    parser.add_argument("--crop", type=crop_arg, default=(110, 218, 106, 214), help="TOP,BOTTOM,LEFT,RIGHT of phisft_R1's 270×480 grid")
    parser.add_argument("--out", type=Path, default=Path("docs"), help="folder for the pictures")
    parser.add_argument("--skip-kinect", action="store_true")
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    model = inference_model(args.model, torch.device("cpu"))
    phisft(model, args.crop, args.out)
    if not args.skip_kinect:
        kinect(model, args.out)


if __name__ == "__main__":
    main()
