"""The demo: reconstruct a synthesised deforming-surface video and score it.

A 256×256×16 clip is drawn by the clip generator (same ranges as training,
the held-out seed of :mod:`nrdepth.learning.evaluate`, so no training run saw it),
reconstructed whole by :func:`nrdepth.reconstruct` (coarse pass + stitched
64×64×16 patches) and scored by MAE-SN against its ray-cast depth, both
alignments, beside the flat baseline.
"""

from __future__ import annotations

import os
import time
from typing import Any, Callable, Dict, Optional, Union

import numpy as np

from .engine.generate import GeneratorConfig, generate_clips
from .io import colorize_depth, depth_range
from .io.figures import ColourBar, labelled
from .io.viewer import ViewerFrames, write_page
from .learning.evaluate import TEST_SEED
from .reconstruct import reconstruct
from .scores.metrics import flat_baseline, gbr_align, mae_sn

__all__ = ["run_demo", "demo_picture", "demo_page"]


def run_demo(
    model: Union[None, str, "os.PathLike[str]"] = None,
    size: int = 256,
    seed: int = TEST_SEED,
    index: int = 0,
    device: str = "auto",
    config: Optional[GeneratorConfig] = None,
    progress: Optional[Callable[[int, int], None]] = None,
) -> Dict[str, Any]:
    """Generate clip ``index`` of ``seed`` at ``size``², reconstruct it with
    ``model`` (default: the shipped one) and score it. Returns the video,
    ground-truth and reconstructed depth, MAE-SN of the reconstruction and of
    the flat baseline for both alignments, and the seconds each step took.
    ``progress(done, total)`` is called as frames of the fine pass are done."""
    config = config or GeneratorConfig(size=size)
    start = time.perf_counter()
    clip = generate_clips(1, seed=seed, config=config, start=index)
    video, truth = clip.video[0], clip.depth[0]
    generated = time.perf_counter()
    depth = reconstruct(video, model, device=device, progress=progress)
    done = time.perf_counter()
    return {
        "video": video,
        "truth": truth,
        "depth": depth,
        "mae_sn": {a: mae_sn(depth, truth, a) for a in ("frame", "first")},
        "flat": {a: flat_baseline(truth, a) for a in ("frame", "first")},
        "seconds": {"generate": generated - start, "reconstruct": done - generated},
    }


def demo_picture(result: Dict[str, Any], frames_shown: int = 4) -> np.ndarray:
    """uint8 RGB picture: one row per shown frame, columns frame | ground-truth
    depth | reconstruction mapped onto the truth by its per-frame GBR (the
    alignment MAE-SN scores), both depths in the truth's colour range, under
    column titles and the scores, with a colour bar in the truth's units
    (near is yellow, far is blue); drawn by matplotlib."""
    video, truth = result["video"], result["truth"]
    aligned = gbr_align(result["depth"], truth, "frame")
    value_range = depth_range(truth)
    colour = [colorize_depth(d, value_range) for d in (truth, aligned)]
    rows = []
    for t in np.linspace(0, len(video) - 1, frames_shown).round().astype(int):
        cells = [np.repeat(video[t][..., None], 3, axis=-1)] + [c[t] for c in colour]
        rows.append(np.concatenate([np.pad(c, ((2, 2), (2, 2), (0, 0)), constant_values=255) for c in cells], axis=1))
    score, flat = result["mae_sn"]["frame"], result["flat"]["frame"]
    return labelled(
        np.concatenate(rows, axis=0), ["frames", "ground truth", "nrdepth (GBR-aligned per frame)"], video.shape[2] + 4,
        colour_bar=ColourBar(*value_range, "depth (half-widths of the patch)"),
        title=f"a generated {video.shape[2]}×{video.shape[1]}×{len(video)} video: MAE-SN per frame {score:.3f} (flat plane {flat:.3f})")


def demo_page(result: Dict[str, Any], path: "Union[str, os.PathLike[str]]") -> "os.PathLike[str]":
    """The 3-D page (:mod:`nrdepth.io.viewer`) of a demo: the ground truth and
    the reconstruction mapped onto it by its per-frame GBR, side by side,
    each draped with the video, under one time slider."""
    video, truth = result["video"], result["truth"]
    videos = []
    for name, depth in (("ground truth", truth), ("nrdepth (gbr-aligned)", gbr_align(result["depth"], truth, "frame"))):
        frames = ViewerFrames(depth.shape)
        frames.add(np.asarray(depth, np.float32), video)
        videos.append((name, frames))
    return write_page(path, videos, fps=10.0, title="nrdepth demo: a generated video, its true depth and the reconstruction")
