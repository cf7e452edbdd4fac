"""Pictures of synthesised surfaces.

Each tile shows one frame of a clip in the undeformed grid's coordinates: colour
is the vertex depth z (one colour range per clip, so motion over time is
visible), brightness is Lambertian shading of the mesh normals under a fixed
oblique light, so folds and wrinkles read as relief.
"""

from __future__ import annotations

import os
from typing import Optional, Union

import numpy as np

from . import _core
from .surface import SurfaceConfig, sample_surface_params, synthesize_surfaces

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


def vertex_normals(positions: np.ndarray) -> np.ndarray:
    """Unit normals (..., grid, grid, 3) of grid vertex positions by central differences."""
    dx = np.gradient(positions, axis=-2)
    dy = np.gradient(positions, axis=-3)
    n = np.cross(dx, dy)
    return n / np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-12)


def shade_clip(positions: np.ndarray) -> np.ndarray:
    """RGB float tiles (frames, grid, grid, 3) of one clip's vertex positions."""
    z = positions[..., 2]
    lo, hi = float(z.min()), float(z.max())
    colour = colormap((z - lo) / max(hi - lo, 1e-12))
    light = np.array([-0.4, 0.5, 0.77])
    light /= np.linalg.norm(light)
    lambert = np.clip(vertex_normals(positions) @ light, 0.0, 1.0)
    return colour * (0.3 + 0.7 * lambert)[..., None]


def surface_sheet(
    seed: int = 0,
    clips: int = 4,
    frames: int = 16,
    grid: int = 64,
    columns: int = 4,
    scale: int = 2,
    config: Optional[SurfaceConfig] = None,
) -> np.ndarray:
    """A uint8 RGB sheet: one row per clip (params drawn from ``seed + row``),
    ``columns`` evenly spaced frames per row, each tile ``grid·scale`` pixels."""
    if clips < 1 or columns < 1 or scale < 1:
        raise ValueError("clips, columns and scale must be >= 1")
    params = [sample_surface_params(seed + i, config) for i in range(clips)]
    positions = synthesize_surfaces(params, frames, grid)
    picks = np.unique(np.linspace(0, frames - 1, min(columns, frames)).round().astype(int))
    gap, tile = 4, grid * scale
    sheet = np.ones((clips * (tile + gap) + gap, len(picks) * (tile + gap) + gap, 3))
    for r, clip in enumerate(positions):
        tiles = shade_clip(clip)[picks]
        for c, img in enumerate(tiles):
            # Row 0 of the grid is y = −1: flip so +y points up in the picture.
            img = np.repeat(np.repeat(img[::-1], scale, axis=0), scale, axis=1)
            y0, x0 = gap + r * (tile + gap), gap + c * (tile + gap)
            sheet[y0 : y0 + tile, x0 : x0 + tile] = img
    return (sheet * 255.0 + 0.5).astype(np.uint8)


def save_png(path: Union[str, os.PathLike], image: np.ndarray) -> None:
    """Write a uint8 (H, W, 3) image as PNG, atomically (temporary name, then rename)."""
    image = np.ascontiguousarray(image)
    if image.dtype != np.uint8 or image.ndim != 3 or image.shape[2] != 3:
        raise ValueError(f"image: expected uint8 (H, W, 3), got {image.dtype} {image.shape}")
    _core.write_png(os.fspath(path), image)
