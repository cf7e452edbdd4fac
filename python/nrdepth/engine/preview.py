"""Pictures of synthesised surfaces.

Each tile shows one frame of a clip in the undeformed grid's coordinates: colour
is the vertex depth z (one colour range per clip, so motion over time is
visible), brightness is Lambertian shading of the mesh normals under a fixed
oblique light, so folds and wrinkles read as relief.
"""

from __future__ import annotations

import os
from dataclasses import replace
from typing import Optional, Sequence, Union

import numpy as np

from .. import _core
from ..io.colours import colormap
from ..io.figures import labelled
from .generate import GeneratorConfig, generate_clips
from .render import Light, Material, render
from .surface import SurfaceConfig, SurfaceParams, grid_triangles, sample_surface_params, synthesize_surface, synthesize_surfaces


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


def _tile(image: np.ndarray, size: int) -> np.ndarray:
    """Nearest-neighbour resize of an (h, w[, 3]) float image to (size, size, 3)."""
    if image.ndim == 2:
        image = np.repeat(image[..., None], 3, axis=-1)
    rows = (np.arange(size) * image.shape[0] // size).clip(0, image.shape[0] - 1)
    cols = (np.arange(size) * image.shape[1] // size).clip(0, image.shape[1] - 1)
    return image[rows][:, cols]


def _wireframe(positions: np.ndarray, window: Sequence[float], size: int, every: int = 4) -> np.ndarray:
    """Grid lines (every ``every``-th vertex row and column) of one frame's
    vertex positions (grid, grid, 3), seen by the camera over ``window``."""
    x0, y0, x1, y1 = window
    img = np.zeros((size, size, 3))
    z = positions[..., 2]
    shade = colormap((z - z.min()) / max(float(np.ptp(z)), 1e-12))
    lines = [positions[i, :] for i in range(0, len(positions), every)] + [positions[:, j] for j in range(0, len(positions), every)]
    colours = [shade[i, :] for i in range(0, len(positions), every)] + [shade[:, j] for j in range(0, len(positions), every)]
    for line, colour in zip(lines, colours):
        t = np.linspace(0, len(line) - 1, 8 * len(line))
        k = np.minimum(t.astype(int), len(line) - 2)
        f = (t - k)[:, None]
        pts = line[k] * (1 - f) + line[k + 1] * f
        col = ((pts[:, 0] - x0) / (x1 - x0) * size).astype(int)
        row = ((y1 - pts[:, 1]) / (y1 - y0) * size).astype(int)
        ok = (row >= 0) & (row < size) & (col >= 0) & (col < size)
        img[row[ok], col[ok]] = colour[np.minimum(k, len(colour) - 1)][ok]
    return img


def clip_sheet(clips: int = 3, seed: int = 0, frames_shown: int = 4, scale: int = 2, config: Optional[GeneratorConfig] = None) -> np.ndarray:
    """One row per generated clip: ``frames_shown`` rendered frames, the same
    frames' depth (one colour range per clip), and the mesh of the first frame."""
    config = GeneratorConfig() if config is None else config
    data = generate_clips(clips, seed=seed, config=config)
    tile = config.size * scale
    picks = np.unique(np.linspace(0, config.frames - 1, frames_shown).round().astype(int))
    gap = 4
    columns = 2 * len(picks) + 1
    sheet = np.ones((clips * (tile + gap) + gap, columns * (tile + gap) + gap, 3))
    for r in range(clips):
        depth = data.depth[r]
        near, far = float(np.nanmin(depth)), float(np.nanmax(depth))
        off_sheet = np.isnan(depth)[..., None]  # backdrop clips: white where the view is off the sheet
        tiles = [_tile(data.video[r, f] / 255.0, tile) for f in picks]
        tiles += [_tile(np.where(off_sheet[f], 1.0, colormap(np.nan_to_num(far - depth[f]) / max(far - near, 1e-12))), tile) for f in picks]
        surface = SurfaceParams.from_dict(data.params[r]["surface"])
        positions = synthesize_surface(surface, config.frames, config.grid)[0]
        tiles.append(_wireframe(positions, data.params[r]["window"], tile))
        for c, img in enumerate(tiles):
            y0, x0 = gap + r * (tile + gap), gap + c * (tile + gap)
            sheet[y0 : y0 + tile, x0 : x0 + tile] = img
    titles = [f"frame {f}" for f in picks] + [f"depth {f}" for f in picks] + ["mesh"]
    return labelled((sheet.clip(0, 1) * 255 + 0.5).astype(np.uint8), titles, tile + gap)


def parameter_sweep(seed: int = 0, size: int = 128) -> np.ndarray:
    """The paper's figure "Illustration of the effect of the parameters": one
    surface with low ν, ζ, ξ and Σ = I, then the same surface with more
    constraint, a non-identity Σ, more flexibility and more folding. Each
    panel renders frame 0 under an oblique light with a check texture over
    the whole patch, so in-plane folding shows as distorted checks."""
    base = SurfaceParams(
        intensity=0.12, constraint=0.05, folding=0.05, flexibility=0.4,
        orientation=(1.0, 0.0, 1.0), speeds=(1.0, 1.0, 1.0), phase_seed=seed,
    )
    c, s = np.cos(0.5), np.sin(0.5)
    rot = np.array([[c, -s], [s, c]])
    sigma = rot @ np.diag([0.05, 4.0]) @ rot.T
    variants = [
        base,
        replace(base, constraint=3.0),
        replace(base, orientation=(sigma[0, 0], sigma[0, 1], sigma[1, 1])),
        replace(base, flexibility=1.5),
        replace(base, folding=1.0),
    ]
    grid = 96
    triangles = grid_triangles(grid)
    coords = np.linspace(0.0, 1.0, grid)
    u, v = np.meshgrid(coords, 1.0 - coords)
    uv = np.stack([u, v], axis=-1).reshape(-1, 2)
    texture = np.kron((np.indices((16, 16)).sum(0) % 2) * 0.5 + 0.4, np.ones((16, 16)))
    lights = [Light("directional", (-0.5, 0.6, 0.8), 0.9)]
    gap = 4
    sheet = np.ones((size + 2 * gap, len(variants) * (size + gap) + gap, 3))
    for k, params in enumerate(variants):
        vertices = synthesize_surface(params, frames=1, grid=grid)[0].reshape(-1, 3)
        out = render(vertices, triangles, uv, texture, size, (-1.3, -1.3, 1.3, 1.3), lights, Material(0.25, 0.75, 0.3, 30.0))
        x0 = gap + k * (size + gap)
        sheet[gap : gap + size, x0 : x0 + size] = _tile(out.image.clip(0, 1), size) * 0.9 + 0.1 * (out.coverage[..., None] == 0)
    titles = ["low values", "more constraint ν", "anisotropic Σ", "more flexibility ξ", "more folding ζ"]
    return labelled((sheet.clip(0, 1) * 255 + 0.5).astype(np.uint8), titles, size + gap)


def preview_sheet(seed: int = 0, clips: int = 3, config: Optional[GeneratorConfig] = None) -> np.ndarray:
    """:func:`clip_sheet` above :func:`parameter_sweep`, on one white page."""
    top = clip_sheet(clips=clips, seed=seed, config=config)
    bottom = parameter_sweep(seed=seed)
    width = max(top.shape[1], bottom.shape[1])
    pad = lambda a: np.pad(a, ((0, 0), (0, width - a.shape[1]), (0, 0)), constant_values=255)  # noqa: E731
    return np.concatenate([pad(top), pad(bottom)], axis=0)
