"""Held-out evaluation of a model: per-clip MAE-SN (both alignments) beside
the flat baseline, as in the paper's table "synthetic_data", and the relief's
sign-correct rate (frames) and in-clip flip rate (clips); for a model that
learnt the relief's scale (``depth_units`` "window"), the ratio of its relief
amplitude to the truth's.

Predictions are at the network's half resolution; the ground truth is brought
to it by 2×2 means. Data: a dataset folder's test split, or, without one,
``clips`` fresh clips of a generator run whose seed no training run uses.
"""

from __future__ import annotations

import csv
import json
import os
from pathlib import Path
from typing import Any, Dict, NamedTuple, Optional, Tuple, Union

import numpy as np
import torch

from ..engine.dataset import ClipStore
from ..engine.generate import GeneratorConfig, generate_clips, window_widths
from ..model.io import check_readings, load_model, predict_depth, resolve_device
from ..reconstruct import reconstruct
from ..scores.metrics import flat_baseline, mae_sn, sign_rates, sparse_baselines, sparse_mae, sparse_sign_rate
from .losses import relief_rms

__all__ = ["evaluate", "load_real_video", "load_real", "RealVideo", "score_real", "score_real_video", "relief_ratio", "TEST_SEED"]

TEST_SEED = 2_000_003
"""Generator seed of the held-out clips when no dataset is given."""


def evaluate(
    model: Union[str, os.PathLike],
    data: Optional[Union[str, os.PathLike]] = None,
    out: Optional[Union[str, os.PathLike]] = None,
    clips: int = 256,
    config: Optional[GeneratorConfig] = None,
    batch_size: int = 8,
    device: str = "auto",
    readings: int = 1,
) -> Dict[str, Any]:
    """Score ``model`` (a ``model.safetensors`` or its folder); write
    ``per_clip.csv`` and ``summary.json`` into ``out`` when given.
    ``readings`` is :func:`~nrdepth.model.predict_depth`'s: how many
    symmetric readings of each clip are averaged."""
    check_readings(readings)
    net = load_model(model, device="cpu").to(resolve_device(device))
    if data is not None:
        store = ClipStore(data, "test")
        items = [store[i] for i in range(min(clips, len(store)))]
        video, depth, params = np.stack([v for v, _, _ in items]), np.stack([d for _, d, _ in items]), [p for _, _, p in items]
    else:
        generated = generate_clips(clips, seed=TEST_SEED, config=config or GeneratorConfig())
        video, depth, params = generated.video, generated.depth, generated.params
    pred = predict_depth(net, video, batch_size, readings=readings)
    truth = torch.nn.functional.avg_pool2d(torch.from_numpy(depth).float(), 2).numpy()
    rows = []
    for i, (p, g) in enumerate(zip(pred, truth)):
        rows.append({
            "clip": i,
            "mae_sn_frame": mae_sn(p, g, "frame"),
            "mae_sn_first": mae_sn(p, g, "first"),
            "mae_sn_first_offset": mae_sn(p, g, "first_offset"),
            "flat_frame": flat_baseline(g, "frame"),
            "flat_first": flat_baseline(g, "first"),
            "flat_first_offset": flat_baseline(g, "first_offset"),
            **sign_rates(p, g),
        })
    if net.depth_units == "window":  # a model that learnt the relief's scale: how well
        in_windows = truth / window_widths(params)[:, None, None, None]
        for row, p, g in zip(rows, pred, in_windows):
            row["relief_ratio"] = relief_ratio(p[None], g[None])
    summary: Dict[str, Any] = {"clips": len(rows), "model": str(model), "data": str(data) if data else f"generated, seed {TEST_SEED}", "readings": readings}
    for key in ("mae_sn_frame", "mae_sn_first", "mae_sn_first_offset", "flat_frame", "flat_first", "flat_first_offset", "sign_correct", "flip"):
        values = np.array([r[key] for r in rows])
        summary[key] = {"mean": float(values.mean()), "std": float(values.std())}
    if "relief_ratio" in rows[0]:  # a ratio: its geometric mean and the spread of its log
        logs = np.log([r["relief_ratio"] for r in rows])
        summary["relief_ratio"] = {"geometric_mean": float(np.exp(logs.mean())), "log_std": float(logs.std())}
    if out is not None:
        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        with (out / "per_clip.csv").open("w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(rows)
        (out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    return summary


def load_real_video(path: Union[str, os.PathLike]) -> Tuple[np.ndarray, np.ndarray]:
    """A real video with ground-truth depth from an ``.npz``: ``video`` uint8
    (T, H, W) and ``depth`` float (T, H, W), NaN where there is no truth
    (``benchmarks/bench_real.py --write-phisft`` makes one of ``phisft_R1``).
    Returns (video, depth float32); refuses anything else by name."""
    try:
        data = np.load(os.fspath(path))  # allow_pickle stays off: arrays only
    except (OSError, EOFError, ValueError) as e:
        raise ValueError(f"{path}: not a readable .npz of arrays ({e})") from None
    if not isinstance(data, np.lib.npyio.NpzFile):
        raise ValueError(f"{path}: expected an .npz holding 'video' and 'depth', got a single .npy array")
    with data:
        if not {"video", "depth"} <= set(data.files):
            raise ValueError(f"{path}: expected arrays 'video' and 'depth', found {sorted(data.files)}")
        try:
            video, depth = data["video"], data["depth"]
        except ValueError as e:  # object arrays need pickle, which is refused
            raise ValueError(f"{path}: not a readable .npz of arrays ({e})") from None
    if video.dtype != np.uint8 or video.ndim != 3:
        raise ValueError(f"{path}: 'video' must be uint8 (T, H, W), got {video.dtype} {video.shape}")
    if depth.shape != video.shape or not np.issubdtype(depth.dtype, np.floating):
        raise ValueError(f"{path}: 'depth' must be float with the video's shape {video.shape}, got {depth.dtype} {depth.shape}")
    if (np.isfinite(depth).sum(axis=(1, 2)) < 3).any():
        raise ValueError(f"{path}: every frame needs ground truth at 3 pixels or more to fit its GBR")
    return video, depth.astype(np.float32)


class RealVideo(NamedTuple):
    """A real video with ground truth, dense or sparse (:func:`load_real`)."""

    video: np.ndarray
    """uint8 (T, H, W)."""
    depth: Optional[np.ndarray] = None
    """Dense truth float32 (T, H, W), NaN where there is none."""
    points: Optional[Dict[str, np.ndarray]] = None
    """Sparse truth: ``frames`` (F,) the frames that carry it, ``uv`` (F, 2, N)
    pixel positions (column, row), ``z`` (F, N) depths (``kinect_paper``'s
    ``gt_mdh.npz`` cut to a video: ``benchmarks/bench_real.py --write-kinect``)."""


def load_real(path: Union[str, os.PathLike]) -> RealVideo:
    """A real video with ground truth from an ``.npz``: dense (``video``
    and ``depth``, :func:`load_real_video`) or sparse (``video``,
    ``frames``, ``uv``, ``z``: :attr:`RealVideo.points`); refuses anything
    else by name."""
    try:
        data = np.load(os.fspath(path))  # allow_pickle stays off: arrays only
    except (OSError, EOFError, ValueError) as e:
        raise ValueError(f"{path}: not a readable .npz of arrays ({e})") from None
    sparse = isinstance(data, np.lib.npyio.NpzFile) and {"video", "frames", "uv", "z"} <= set(data.files) and "depth" not in data.files
    if not sparse:
        if isinstance(data, np.lib.npyio.NpzFile):
            data.close()
        video, depth = load_real_video(path)  # names what is wrong with anything else
        return RealVideo(video, depth=depth)
    with data:
        try:
            arrays = {k: data[k] for k in ("video", "frames", "uv", "z")}
        except ValueError as e:  # object arrays need pickle, which is refused
            raise ValueError(f"{path}: not a readable .npz of arrays ({e})") from None
    video, frames, uv, z = arrays["video"], arrays["frames"], arrays["uv"], arrays["z"]
    if video.dtype != np.uint8 or video.ndim != 3:
        raise ValueError(f"{path}: 'video' must be uint8 (T, H, W), got {video.dtype} {video.shape}")
    if frames.ndim != 1 or frames.dtype.kind not in "iu" or len(frames) < 1 or frames.min() < 0 or frames.max() >= len(video):
        raise ValueError(f"{path}: 'frames' must be frame indices (F,) of the video's {len(video)}")
    if uv.shape != (len(frames), 2, z.shape[-1]) or z.shape != (len(frames), uv.shape[-1]) or not (np.isfinite(uv).all() and np.isfinite(z).all()):
        raise ValueError(f"{path}: 'uv' and 'z' must be finite (F, 2, N) and (F, N) with F = {len(frames)}, got {uv.shape} and {z.shape}")
    _, h, w = video.shape
    if uv.min() < 0 or uv[:, 0].max() > w - 1 or uv[:, 1].max() > h - 1 or z.shape[1] < 4:
        raise ValueError(f"{path}: 'uv' must hold at least 4 points a frame inside the {w}×{h} frame")
    return RealVideo(video, points={"frames": frames.astype(np.int64), "uv": uv.astype(np.float64), "z": z.astype(np.float64)})


def score_real(model: torch.nn.Module, real: RealVideo, device: Union[str, torch.device] = "cpu") -> Dict[str, float]:
    """:func:`score_real_video` for dense truth; for sparse truth the MAE in
    its units after each frame's GBR (:func:`nrdepth.scores.metrics.sparse_mae`),
    the plane's, and the share of frames whose relief sign is right."""
    if real.depth is not None:
        return score_real_video(model, real.video, real.depth, device)
    p = real.points
    pred = reconstruct(real.video, model, device=str(device), sheet_stage=False)[p["frames"]]
    return {"mae": sparse_mae(pred, p["uv"], p["z"]), "flat_mae": sparse_baselines(p["uv"], p["z"])["plane"],
            "sign_correct": sparse_sign_rate(pred, p["uv"], p["z"])}


def score_real_video(model: torch.nn.Module, video: np.ndarray, depth: np.ndarray, device: Union[str, torch.device] = "cpu") -> Dict[str, float]:
    """Reconstruct a real video (stitched, as ``nrdepth reconstruct`` does,
    without the sheet stage: what the model reads) and score it over the pixels with a ground-truth value: MAE-SN per frame
    and from the first frame, the flat plane's per frame, and the share of
    frames whose relief sign is read right."""
    mask = np.isfinite(depth)
    pred = reconstruct(video, model, device=str(device), sheet_stage=False)
    return {
        "frame": mae_sn(pred, depth, "frame", mask=mask),
        "first": mae_sn(pred, depth, "first", mask=mask),
        "flat_frame": flat_baseline(depth, "frame", mask=mask),
        "sign_correct": sign_rates(pred, depth, mask=mask)["sign_correct"],
    }


def relief_ratio(pred: np.ndarray, truth: np.ndarray) -> float:
    """The geometric mean over frames of the ratio of predicted to true relief
    amplitude (:func:`nrdepth.learning.losses.relief_rms`; 1 is right, and both must be
    in the same units)."""
    ratio = relief_rms(torch.from_numpy(pred).double()) / relief_rms(torch.from_numpy(np.asarray(truth)).double())
    return float(torch.exp(torch.log(ratio).mean()))


def format_summary(summary: Dict[str, Any]) -> str:
    """The paper's table layout: rows per alignment, model beside flat baseline."""
    s = summary
    return "\n".join([
        f"MAE-SN over {s['clips']} held-out clips ({s['data']}{', %d readings averaged' % s['readings'] if s.get('readings', 1) > 1 else ''}), mean ± std",
        f"{'':26s}{'model':>18s}{'flat baseline':>20s}",
        f"{'align each frame':26s}{s['mae_sn_frame']['mean']:>9.4f} ± {s['mae_sn_frame']['std']:.4f}{s['flat_frame']['mean']:>11.4f} ± {s['flat_frame']['std']:.4f}",
        f"{'alignment from 1st frame':26s}{s['mae_sn_first']['mean']:>9.4f} ± {s['mae_sn_first']['std']:.4f}{s['flat_first']['mean']:>11.4f} ± {s['flat_first']['std']:.4f}",
        f"{'1st frame, offset per frame':26s}{s['mae_sn_first_offset']['mean']:>9.4f} ± {s['mae_sn_first_offset']['std']:.4f}{s['flat_first_offset']['mean']:>11.4f} ± {s['flat_first_offset']['std']:.4f}",
        f"relief sign correct in {100 * s['sign_correct']['mean']:.1f} % of frames; it flips inside {100 * s['flip']['mean']:.1f} % of clips",
    ] + ([f"relief amplitude / the truth's: geometric mean {s['relief_ratio']['geometric_mean']:.3f} over clips "
          f"(log std {s['relief_ratio']['log_std']:.3f})"] if "relief_ratio" in s else []))
