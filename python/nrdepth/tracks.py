"""Point tracks of generated videos, depth of tracked points by NRSfM, and
dense depth from sparse points: what the paper's comparison with CSF2 needs.

- :func:`clip_tracks`: the image positions (pixel coordinates, column x and
  row y, pixel centres at integers) and true depths of mesh vertices spread
  evenly over the visible surface, tracked exactly through the frames (the
  generator knows every vertex: its mesh is ``synthesize_surface`` of the
  clip's parameters, its camera the clip's window).
- :func:`nrsfm_depth`: per-frame depth of the tracked points from an NRSfM
  reconstruction (3-D shapes and orthographic cameras): the third axis of
  each frame's camera, ``r_1 × r_2``, applied to the centred shape.
- :func:`densify`: dense depth (T, H, W) from depths at scattered image
  points by linear interpolation over their Delaunay triangulation
  (``scipy.interpolate.griddata``), nearest-neighbour outside their hull.
"""

from __future__ import annotations

from typing import Any, Dict, NamedTuple

import numpy as np

from .generate import GeneratorConfig
from .surface import SurfaceParams, synthesize_surface

__all__ = ["Tracks", "clip_tracks", "nrsfm_depth", "densify", "measurement_matrix"]


class Tracks(NamedTuple):
    xy: np.ndarray
    """float64 (T, n, 2): column and row of each point in each frame (pixel centres at integers)."""
    depth: np.ndarray
    """float64 (T, n): the points' true depth ``camera_z − z``."""
    vertices: np.ndarray
    """int64 (n, 2): grid row and column of each tracked mesh vertex."""


def clip_tracks(params: Dict[str, Any], config: GeneratorConfig, points: int = 33, noise: float = 0.0, seed: int = 0) -> Tracks:
    """Tracks of up to ``points × points`` mesh vertices spread evenly over
    the part of the surface visible in every frame of a generated clip
    (``params`` is one of ``generate_clips(...).params``); ``noise``: the
    standard deviation of Gaussian pixel noise added to the positions."""
    from .render import CAMERA_Z

    if not (isinstance(points, int) and points >= 2):
        raise ValueError(f"points: expected an int >= 2, got {points!r}")
    if not (noise >= 0 and np.isfinite(noise)):
        raise ValueError(f"noise: expected a non-negative pixel standard deviation, got {noise!r}")
    positions = synthesize_surface(SurfaceParams.from_dict(params["surface"]), config.frames, config.grid).astype(np.float64)
    x0, y0, x1, y1 = params["window"]
    size = config.size
    cols = (positions[..., 0] - x0) / (x1 - x0) * size - 0.5
    rows = (y1 - positions[..., 1]) / (y1 - y0) * size - 0.5
    inside = ((cols >= 0) & (cols <= size - 1) & (rows >= 0) & (rows <= size - 1)).all(axis=0)  # (grid, grid)
    jy, jx = np.nonzero(inside)
    if len(jy) < 4:
        raise ValueError("params: fewer than 4 mesh vertices stay inside the view")
    # An even subgrid of the visible vertices' index box, kept where visible.
    pick_y = np.unique(np.linspace(jy.min(), jy.max(), points).round().astype(int))
    pick_x = np.unique(np.linspace(jx.min(), jx.max(), points).round().astype(int))
    gy, gx = np.meshgrid(pick_y, pick_x, indexing="ij")
    keep = inside[gy, gx]
    vertices = np.column_stack([gy[keep], gx[keep]])
    xy = np.stack([cols[:, vertices[:, 0], vertices[:, 1]], rows[:, vertices[:, 0], vertices[:, 1]]], axis=-1)
    if noise > 0:
        xy = xy + np.random.default_rng(seed).normal(0.0, noise, xy.shape)
    depth = CAMERA_Z - positions[:, vertices[:, 0], vertices[:, 1], 2]
    return Tracks(xy, depth, vertices)


def measurement_matrix(xy: np.ndarray) -> np.ndarray:
    """Tracks (T, n, 2) as NRSfM's W (2T × n): rows 2t, 2t + 1 = x, y of frame t.
    Image rows grow downwards; y is negated so that the frame is right-handed
    with depth growing away from the camera."""
    xy = np.asarray(xy, dtype=np.float64)
    T, n, _ = xy.shape
    W = np.empty((2 * T, n))
    W[0::2], W[1::2] = xy[..., 0], -xy[..., 1]
    return W


def nrsfm_depth(shapes: np.ndarray, cameras: np.ndarray) -> np.ndarray:
    """Depth (T, n) of an NRSfM reconstruction: shapes (3T × n) in the object
    frame, cameras (2T × 3); each frame's centred shape along its camera's
    optical axis r_1 × r_2 (normalised). Defined up to sign and offset per
    frame, as NRSfM's output is: scores should align by GBR."""
    T = cameras.shape[0] // 2
    S = shapes.reshape(T, 3, -1)
    S = S - S.mean(axis=2, keepdims=True)
    R = cameras.reshape(T, 2, 3)
    axis = np.cross(R[:, 0], R[:, 1])
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    return np.einsum("ta,tan->tn", axis, S)


def densify(xy: np.ndarray, values: np.ndarray, shape: tuple) -> np.ndarray:
    """Dense (T, H, W) from values (T, n) at points xy (T, n, 2) (column,
    row): linear over the points' Delaunay triangles, nearest outside their
    convex hull."""
    from scipy.interpolate import griddata

    T, H, W = shape
    rows, cols = np.mgrid[0:H, 0:W]
    out = np.empty(shape)
    for t in range(T):
        linear = griddata(xy[t], values[t], (cols, rows), method="linear")
        hole = np.isnan(linear)
        if hole.any():
            linear[hole] = griddata(xy[t], values[t], (cols[hole], rows[hole]), method="nearest")
        out[t] = linear
    return out
