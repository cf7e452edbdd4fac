"""The network's relief kept below a length scale, the isometric depth's
shape taken above it (:mod:`nrdepth.isometric`)."""

from __future__ import annotations

from typing import Optional

import numpy as np

from ..scores.metrics import gbr_design, gbr_fit

__all__ = ["fuse"]

def fuse(depth: np.ndarray, isometric: np.ndarray, scale: float, mask: Optional[np.ndarray] = None,
         relief: str = "frame") -> np.ndarray:
    """The network's ``depth`` (T, H, W) with its shape above ``scale``
    (the standard deviation of a Gaussian, in pixels) taken from
    ``isometric`` (T, H, W, spread from the points: :mod:`nrdepth.reconstruct.sheet.fuse`): ``depth`` is fitted to
    ``isometric`` over ``mask`` (T, H, W, default every pixel) by
    ``λ d + α x + β y + τ``, a plane per frame, and their difference,
    smoothed by the Gaussian over ``mask``, is added. ``relief``: "frame"
    fits each frame's own λ (a GBR per frame); "video" takes one λ for the
    whole video (the median of the frames' own), so the relief keeps the
    network's scale from frame to frame and the sign the isometric depth
    has in most frames (better on both real videos, worse on short generated
    clips: docs/findings.md). In ``isometric``'s units; ``scale`` 0 gives
    ``isometric`` back."""
    depth, isometric = np.asarray(depth, np.float64), np.asarray(isometric, np.float64)
    if depth.ndim != 3 or depth.shape != isometric.shape:
        raise ValueError(f"depth, isometric: expected two depth videos (T, H, W) of one shape, got {depth.shape} and {isometric.shape}")
    if not (np.isfinite(scale) and scale >= 0):
        raise ValueError(f"scale: expected a length in pixels >= 0, got {scale!r}")
    if relief not in ("video", "frame"):
        raise ValueError(f"relief: expected 'video' or 'frame', got {relief!r}")
    mask = np.ones(depth.shape, bool) if mask is None else np.asarray(mask)
    if mask.dtype != np.bool_ or mask.shape != depth.shape:
        raise ValueError(f"mask: expected a bool array of the videos' shape {depth.shape}, got {mask.dtype} {mask.shape}")
    if not (np.isfinite(depth[mask]).all() and np.isfinite(isometric[mask]).all()):
        raise ValueError("depth, isometric: expected finite values inside mask (found NaN or inf)")
    if scale == 0:
        return isometric.copy()
    fits = [gbr_fit(d, i, m) for d, i, m in zip(depth, isometric, mask)]  # each frame's (α, β, λ, τ)
    if relief == "video":
        shared = float(np.median([fit[2] for fit in fits]))
        fits = []
        for d, i, m in zip(depth, isometric, mask):
            plane = gbr_design(np.zeros_like(d), m)[:, [0, 1, 3]]
            fits.append(np.insert(np.linalg.lstsq(plane, i[m] - shared * d[m], rcond=None)[0], 2, shared))
    out = np.empty_like(depth)
    weighed, weight = None, None  # the mask last blurred: most frames share one, and its blur costs as much as the difference's
    rows, cols = np.mgrid[0 : depth.shape[1], 0 : depth.shape[2]]
    for t, (d, i, m, fit) in enumerate(zip(depth, isometric, mask, fits)):
        aligned = fit[0] * cols + fit[1] * rows + fit[2] * d + fit[3]  # gbr_design's columns x, y, depth, 1, without building them
        if weighed is None or not np.array_equal(m, weighed):
            weighed, weight = m, _blur(m.astype(np.float64), scale)
        difference = _blur(np.where(m, i - aligned, 0.0), scale)
        out[t] = aligned + difference / np.maximum(weight, 1e-6)  # normalised: the mask's outside takes no part
    return out


def _blur(image: np.ndarray, sigma: float) -> np.ndarray:
    """A Gaussian blur of standard deviation ``sigma`` pixels with zeros
    outside the image, by FFT over the image padded by 4σ (at most its own
    size): the cost does not grow with σ."""
    from scipy import fft
    from scipy.ndimage import fourier_gaussian

    h, w = image.shape
    pad_h, pad_w = (min(int(np.ceil(4 * sigma)), n) for n in (h, w))
    padded = np.zeros((fft.next_fast_len(h + 2 * pad_h, real=True), fft.next_fast_len(w + 2 * pad_w, real=True)))
    padded[pad_h : pad_h + h, pad_w : pad_w + w] = image
    # workers: the rows' and columns' transforms spread over threads, each computed as on one
    blurred = fft.irfft2(fourier_gaussian(fft.rfft2(padded, workers=-1), sigma, n=padded.shape[1]), s=padded.shape, workers=-1)
    return blurred[pad_h : pad_h + h, pad_w : pad_w + w]
