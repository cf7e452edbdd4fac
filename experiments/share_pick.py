"""Can a video pick its own share of the coarse companion? The share trades
the real cloth for the real paper (docs/reconstruction.md), so a cue that
reads, per video and without ground truth, which share suits it could
leave the trade. The cue tried here: how well the coarse reading at each
share agrees with the fine pass's own reading at the scale of a block (a
quarter of the working frame's shorter side): per frame and block, the correlation
of the two after each has its least-squares plane removed (the GBR leaves
planes free), averaged. The pick is the share with the highest agreement.

Scored: both real videos (``bench_real.py``'s regions) at each share and
at the pick, and ``--videos N`` generated 256²×48 videos (orthographic and
through a pinhole), MAE-SN per frame at each share and at each video's
pick, paired against the shipped quarter.

    python experiments/share_pick.py [--videos 32] [--camera orthographic] [--shares 0,0.25,0.5,0.75,1]
"""

from __future__ import annotations

import argparse
import math

import numpy as np
import torch

from nrdepth.scores.real import DATA, KINECT_INNER, KINECT_ROI, kinect_score, kinect_truth, phisft_at_bin
from coarse_chain import CAMERAS  # noqa: E402
from real_cross import coarse_reading, fine_pass_once, original_coarse_half, original_field_windows, pipeline  # noqa: E402

import nrdepth  # noqa: E402
from nrdepth.learning.evaluate import TEST_SEED  # noqa: E402
from nrdepth.engine.generate import observable_depth  # noqa: E402
from nrdepth.scores.metrics import mae_sn  # noqa: E402
from nrdepth.io import read_video  # noqa: E402


def detrended(block: np.ndarray, design: np.ndarray) -> np.ndarray:
    """``block`` (n, h, w) with each frame's least-squares plane removed, flattened (n, h·w)."""
    flat = block.reshape(len(block), -1).astype(np.float64)
    coef, *_ = np.linalg.lstsq(design, flat.T, rcond=None)
    return flat - (design @ coef).T


def agreement(fine: np.ndarray, coarse: np.ndarray) -> float:
    """Mean over frames and blocks of the correlation of ``fine`` and ``coarse``
    (T, H, W), each block's plane removed."""
    t, h, w = fine.shape
    side = max(8, min(h, w) // 4)
    yy, xx = np.mgrid[:side, :side]
    design = np.stack([xx.ravel(), yy.ravel(), np.ones(side * side)], axis=1).astype(np.float64)
    scores = []
    for y in range(0, h - side + 1, side):
        for x in range(0, w - side + 1, side):
            a = detrended(fine[:, y : y + side, x : x + side], design)
            b = detrended(coarse[:, y : y + side, x : x + side], design)
            denominator = np.sqrt((a * a).sum(1) * (b * b).sum(1))
            scores.append(np.where(denominator > 0, (a * b).sum(1) / np.maximum(denominator, 1e-30), 0.0))
    return float(np.mean(scores))


def readings(video: np.ndarray, net, companion, shares: tuple):
    """The depth ``reconstruct`` gives at each share, and each share's
    agreement of its coarse reading with the fine field: both as
    ``reconstruct`` computes them (one fine pass, at the working size),
    kept as they pass by."""
    windows, field, halves = fine_pass_once(), [], {}

    def keeping_field(layout, frames, progress=None):
        def spans():
            for t0, depth in frames:
                field.append(depth)
                yield t0, depth
        return windows(layout, spans(), progress)

    def keeping_half(share):
        coarse = coarse_reading(net, companion, share)  # 0: the network's own windows, standardised

        def read(*args, **kw):
            halves[share] = coarse(*args, **kw)
            return halves[share]
        return read

    depths = {}
    pipeline.field_windows = keeping_field
    try:
        for s in shares:
            pipeline.coarse_half = keeping_half(s)
            depths[s] = nrdepth.reconstruct(video, net, sheet_stage=False)
    finally:
        pipeline.coarse_half, pipeline.field_windows = original_coarse_half, original_field_windows
    fine = np.concatenate(field)
    assert len(fine) == len(video), "the fine pass's spans cover every frame"
    agree = {s: agreement(fine, pipeline._resize(halves[s].astype(np.float32), fine.shape[1:])) for s in shares}
    return depths, agree


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--videos", type=int, default=32, help="generated videos per camera (0: the real videos only)")
    parser.add_argument("--shares", default="0,0.25,0.5,0.75,1")
    parser.add_argument("--camera", choices=[name for name, _ in CAMERAS], action="append", help="with --videos: this camera only (default: each)")
    args = parser.parse_args()
    shares = tuple(float(s) for s in args.shares.split(","))
    cpu = torch.device("cpu")
    net = pipeline.inference_model(None, cpu)
    companion, shipped = net.coarse_companion
    net.coarse_companion = None
    if shipped not in shares:
        parser.error(f"--shares: expected the shipped share {shipped:g} among them, got {args.shares!r}")
    cloth, truth = phisft_at_bin(4)
    depths, agree = readings(cloth, net, companion, shares)
    scored = np.isfinite(truth)
    print("phisft_R1: share, agreement, per frame, from the first frame")
    for s in shares:
        print(f"  {s:5.2f}{agree[s]:8.4f}{mae_sn(depths[s], truth, 'frame', mask=scored):8.4f}{mae_sn(depths[s], truth, 'first', mask=scored):8.4f}")
    print(f"  pick: {max(shares, key=agree.get):g}", flush=True)
    frames, points = read_video(DATA / "kinect_paper").frames, kinect_truth()
    for name, (x, y, w, h) in (("whole sheet", KINECT_ROI), ("crop inside", KINECT_INNER)):
        depths, agree = readings(frames[:, y : y + h, x : x + w], net, companion, shares)
        print(f"kinect_paper, {name}: share, agreement, mm")
        for s in shares:
            print(f"  {s:5.2f}{agree[s]:8.4f}{kinect_score(depths[s], points, (x, y, w, h)):8.2f}")
        print(f"  pick: {max(shares, key=agree.get):g}", flush=True)
    for camera, options in (c for c in CAMERAS if args.videos and c[0] in (args.camera or (name for name, _ in CAMERAS))):
        clips = nrdepth.generate_clips(args.videos, seed=TEST_SEED, config=nrdepth.GeneratorConfig(size=256, frames=48, **options))
        errors, picks = [], []
        for video, depth, params in zip(clips.video, clips.depth, clips.params):
            truth = observable_depth(depth, params)
            depths, agree = readings(video, net, companion, shares)
            errors.append([mae_sn(depths[s], truth, "frame") for s in shares])
            picks.append(shares.index(max(shares, key=agree.get)))
        errors = np.array(errors)
        picked = errors[np.arange(len(errors)), picks]
        base = errors[:, shares.index(shipped)]
        best = errors.min(axis=1)
        se = lambda d: d.std(ddof=1) / math.sqrt(len(d))  # noqa: E731
        print(f"{args.videos} generated 256²×48 videos, {camera}: per frame at each share, paired against {shipped:g}")
        for i, s in enumerate(shares):
            print(f"  {s:5.2f}{errors[:, i].mean():8.4f}   {(errors[:, i] - base).mean():+.4f} ± {se(errors[:, i] - base):.4f}")
        print(f"  pick {picked.mean():8.4f}   {(picked - base).mean():+.4f} ± {se(picked - base):.4f}   (picks: "
              + ", ".join(f"{s:g} ×{picks.count(i)}" for i, s in enumerate(shares)) + ")")
        print(f"  best share per video (oracle) {best.mean():.4f}   {(best - base).mean():+.4f}", flush=True)


if __name__ == "__main__":
    main()
