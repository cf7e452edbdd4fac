"""The stitched depth given its units and the video's resolution back:
an offset and scale read over the whole video (a chunk of frames at a
time), then each frame resized to the video's frame, NaN off the mask."""

from __future__ import annotations

import math
from typing import Iterable, Tuple

import numpy as np

from .frames import CHUNK, frames_of, resize
from .pipeline import Pipeline
from .stitch import temporal_align

__all__ = ["units_of", "final", "full_resolution", "relief_scale"]


def units_of(pipeline: Pipeline, raw: np.ndarray, temporal: bool, units: str) -> Tuple[float, float]:
    """The (offset, scale) that give the stitched depth ``raw`` (T, h, w)
    at the working resolution (an array or a memory map; written over
    with ``temporal``) :func:`~nrdepth.reconstruct`'s units and zero mean:
    ``(full(raw) − offset) · scale``, ``full`` the resize to the video's
    resolution (:func:`final`)."""
    t = len(raw)
    if temporal:
        raw[:] = temporal_align(np.asarray(raw))
    spans = [(a, min(a + CHUNK, t)) for a in range(0, t, CHUNK)]
    if units == "pixels":
        # The coarse pass reads the relief's scale (one window the frame); the
        # patches' fits shrink it (least squares regresses toward the fit's
        # target, and the joint alignment's agreement term falls with the
        # scale squared), so the stitched relief takes the coarse pass's.
        scale = relief_scale((raw[a:b] for a, b in spans), (pipeline.coarse(a, b) for a, b in spans))
        mean = sum(float(raw[a:b].sum(dtype=np.float64)) for a, b in spans) / raw.size
        h, w = pipeline.work
        # Pixels of the video, not of the working frame.
        return mean, scale * math.sqrt(h * w) * pipeline.full[1] / w
    # A network without a depth scale (GBR-invariant losses only): a
    # canonical one rather than whatever magnitude its weights drifted to.
    pivot = float(np.nanmean(raw[0:1], dtype=np.float64))  # sums about a value near the mean: no cancellation
    total = squares = n = 0.0
    for a, b in spans:
        frames = full_resolution(pipeline, raw[a:b], a).astype(np.float64) - pivot
        on = np.isfinite(frames)
        total, squares, n = total + float(frames[on].sum()), squares + float(np.square(frames[on]).sum()), n + int(on.sum())
    mean = total / n
    return pivot + mean, 1.0 / (math.sqrt(max(squares / n - mean * mean, 0.0)) or 1.0)


def final(pipeline: Pipeline, raw: np.ndarray, start: int, stop: int, offset: float, scale: float) -> np.ndarray:
    """Frames ``start .. stop`` of the final depth, float32 at the video's resolution (:func:`units_of`)."""
    return ((full_resolution(pipeline, raw[start:stop], start).astype(np.float64) - offset) * scale).astype(np.float32)


def full_resolution(pipeline: Pipeline, frames: np.ndarray, start: int) -> np.ndarray:
    """Working frames from ``start`` at the video's resolution; NaN off the mask."""
    if pipeline.work == pipeline.full:
        return np.asarray(frames, np.float32)
    if pipeline.mask is None:
        return resize(frames, pipeline.full)
    # Each pixel off the working mask takes its nearest on it, so the resize blends only the surface.
    from scipy.ndimage import distance_transform_edt  # on demand: only masked runs need scipy.ndimage

    filled = np.array(frames, np.float32)
    for frame in filled:
        off = np.isnan(frame)
        if off.any() and not off.all():
            rows, cols = distance_transform_edt(off, return_distances=False, return_indices=True)
            frame[:] = frame[rows, cols]
    full = resize(filled, pipeline.full)
    full[~frames_of(pipeline.mask, start, start + len(frames))] = np.nan
    return full


def relief_scale(depth: Iterable[np.ndarray], reference: Iterable[np.ndarray]) -> float:
    """Least-squares s with s·r(depth) ≈ r(reference) over a video (T, H,
    W), given whole or as chunks of frames of both, r being each frame minus
    its least-squares plane; 1 if ``depth`` has no relief (planar frames, up
    to rounding)."""
    if isinstance(depth, np.ndarray):
        depth, reference = [depth], [reference]
    num = den = total = 0.0
    basis = None
    for chunk, ref_chunk in zip(depth, reference):
        if basis is None:
            h, w = chunk.shape[1:]
            y, x = np.mgrid[0:h, 0:w]
            basis, _ = np.linalg.qr(np.stack([x.ravel(), y.ravel(), np.ones(h * w)], axis=1))
        for frame, ref in zip(chunk, ref_chunk):
            f = frame.ravel().astype(np.float64)
            total += float(f @ f)
            f -= basis @ (basis.T @ f)
            num += float(f @ ref.ravel())  # the plane of ``ref`` is orthogonal to the residual ``f``
            den += float(f @ f)
    return num / den if den > 1e-12 * total else 1.0
