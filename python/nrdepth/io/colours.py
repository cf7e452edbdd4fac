"""The depth's colours: one range for a whole video (no flicker), near
yellow and far blue along a viridis-like ramp, NaN (off the surface) black."""

from __future__ import annotations

from typing import Optional, Tuple

import numpy as np

__all__ = ["colormap", "depth_range", "colorize_depth", "COLOURS"]

# A perceptually ordered blue → green → yellow ramp (viridis anchor colours).
_RAMP = np.array(
    [[68, 1, 84], [59, 82, 139], [33, 145, 140], [94, 201, 98], [253, 231, 37]], dtype=np.float64
) / 255.0


def colormap(values: np.ndarray) -> np.ndarray:
    """Map values in [0, 1] to RGB floats in [0, 1] along the ramp."""
    x = np.clip(values, 0.0, 1.0) * (len(_RAMP) - 1)
    i = np.minimum(x.astype(int), len(_RAMP) - 2)
    f = (x - i)[..., None]
    return _RAMP[i] * (1 - f) + _RAMP[i + 1] * f


def depth_range(depth: np.ndarray) -> Tuple[float, float]:
    """One colour range for a whole depth video: its 1st and 99th percentiles
    (robust to a few outliers, and the same for every frame, so no flicker),
    NaN (off the surface) left out."""
    if not np.isfinite(depth).any():
        raise ValueError("depth: expected some finite depth, got none")
    lo, hi = np.nanpercentile(depth, [1.0, 99.0])
    return float(lo), float(max(hi, lo + 1e-12))


COLOURS = np.rint(colormap(np.linspace(0.0, 1.0, 1024)) * 255.0).astype(np.uint8)
"""The colour ramp in 1024 uint8 steps: a lookup keeps a frame's colours in uint8 (a 1080p chunk in floats would take GBs)."""


def colorize_depth(depth: np.ndarray, value_range: Optional[Tuple[float, float]] = None) -> np.ndarray:
    """uint8 RGB (T, H, W, 3): near (small depth) yellow, far blue, over one
    range; NaN (off the surface) black."""
    lo, hi = depth_range(depth) if value_range is None else value_range
    depth = np.asarray(depth, np.float32)
    step = np.float32(1023.0 / (hi - lo))
    off = np.isnan(depth)
    masked = bool(off.any())
    index = np.clip((np.float32(hi) - (np.where(off, np.float32(hi), depth) if masked else depth)) * step + np.float32(0.5), 0, 1023).astype(np.uint16)
    colour = COLOURS[index]
    if masked:
        colour[off] = 0
    return colour
