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
  (SciPy's), nearest-neighbour outside their hull: what
  ``scipy.interpolate.griddata`` gives, spread by the Rust core.
- :func:`track_video`: tracks of a real video, as NRSfM users make them:
  Shi–Tomasi corners in the first frame followed frame to frame by OpenCV's
  pyramidal Lucas–Kanade, keeping only points that every step tracks and
  that a backward step brings back to within ``max_error`` pixels.
"""

from __future__ import annotations

from typing import Any, Dict, NamedTuple, Optional

import numpy as np

from .._core import spread
from ..engine.generate import GeneratorConfig
from ..engine.render import CAMERA_Z
from ..engine.surface import SurfaceParams, synthesize_surface

__all__ = ["Tracks", "clip_tracks", "nrsfm_depth", "densify", "measurement_matrix", "track_video"]


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
    convex hull, as ``scipy.interpolate.griddata``'s "linear" and then
    "nearest" give it (to rounding: ``tests/test_isometric.py``), a frame in
    a few milliseconds (``nrdepth._core.spread``). A point whose value or
    position is NaN in a frame (out of view) takes no part in it; each frame
    needs 3 points that do, not all on one line."""
    from scipy.spatial import Delaunay, QhullError

    T, H, W = shape
    out = np.empty(shape)
    for t in range(T):
        seen = np.isfinite(values[t]) & np.isfinite(xy[t]).all(axis=1)
        if np.count_nonzero(seen) < 3:
            raise ValueError(f"values: expected at least 3 points with a value in every frame, got {np.count_nonzero(seen)} in frame {t}")
        points = np.ascontiguousarray(xy[t, seen], np.float64)
        try:
            triangles = Delaunay(points).simplices  # griddata's own triangulation
        except QhullError:
            raise ValueError(f"xy: expected points in frame {t} that span the plane, got {len(points)} on one line or fewer") from None
        out[t] = spread(points, np.ascontiguousarray(values[t, seen], np.float64), np.ascontiguousarray(triangles, np.uint32), (H, W))
    return out


def track_video(
    frames: np.ndarray,
    max_points: int = 1089,
    mask: Optional[np.ndarray] = None,
    min_distance: Optional[float] = None,
    quality: float = 0.01,
    window: int = 21,
    levels: int = 3,
    max_error: float = 0.5,
) -> np.ndarray:
    """Point tracks (T, n, 2) (column, row; pixel centres at integers) of a
    grayscale video ``frames`` (T, H, W) uint8, through every frame.

    Up to ``max_points`` Shi–Tomasi corners (``cv2.goodFeaturesToTrack``,
    relative ``quality``, at least ``min_distance`` pixels apart, by default
    the spacing of ``max_points`` points spread evenly over ``mask`` or the
    frame) inside ``mask`` (H, W) of the first frame, followed from each frame
    to the next by pyramidal Lucas–Kanade (``cv2.calcOpticalFlowPyrLK``,
    ``window`` × ``window`` pixels, ``levels`` pyramid levels above the
    frame). A point is dropped for good when a step loses it or when tracking
    its new position back lands more than ``max_error`` pixels from where it
    was (the forward–backward check): NRSfM needs every point in every frame.
    """
    import cv2  # imported here: `import nrdepth` stays light

    frames = np.asarray(frames)
    if frames.ndim != 3 or frames.dtype != np.uint8 or frames.shape[0] < 2:
        raise ValueError(f"frames: expected a (T, H, W) uint8 grayscale video with T >= 2, got {frames.dtype} {frames.shape}")
    if not (isinstance(max_points, (int, np.integer)) and max_points >= 4):
        raise ValueError(f"max_points: expected an int >= 4, got {max_points!r}")
    if mask is None:
        mask = np.ones(frames.shape[1:], dtype=bool)
    mask = np.asarray(mask)
    if mask.shape != frames.shape[1:]:
        raise ValueError(f"mask: expected shape {frames.shape[1:]} (a frame's), got {mask.shape}")
    if not mask.any():
        raise ValueError("mask: expected at least one pixel to track in")
    if min_distance is None:
        min_distance = max(1.0, 0.7 * float(np.sqrt(mask.sum() / max_points)))
    if not (0 < quality < 1) or window < 3 or not (0 <= levels <= 8) or not max_error > 0:
        raise ValueError(f"quality, window, levels, max_error: expected 0 < quality < 1, window >= 3, 0 <= levels <= 8, "
                         f"max_error > 0; got {quality}, {window}, {levels}, {max_error}")
    corners = cv2.goodFeaturesToTrack(frames[0], int(max_points), float(quality), float(min_distance), mask=mask.astype(np.uint8))
    if corners is None or len(corners) < 4:
        raise ValueError("frames: fewer than 4 trackable corners in the first frame (too little texture inside mask)")
    lk = dict(winSize=(window, window), maxLevel=levels, criteria=(cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 50, 0.01))
    xy = np.empty((frames.shape[0], len(corners), 2), dtype=np.float32)
    xy[0] = corners.reshape(-1, 2)
    alive = np.ones(len(corners), dtype=bool)
    for t in range(1, frames.shape[0]):
        ahead, found, _ = cv2.calcOpticalFlowPyrLK(frames[t - 1], frames[t], xy[t - 1].reshape(-1, 1, 2), None, **lk)
        back, found_back, _ = cv2.calcOpticalFlowPyrLK(frames[t], frames[t - 1], ahead, None, **lk)
        xy[t] = ahead.reshape(-1, 2)
        error = np.linalg.norm(back.reshape(-1, 2) - xy[t - 1], axis=1)
        alive &= (found.ravel() == 1) & (found_back.ravel() == 1) & (error <= max_error)
    if alive.sum() < 4:
        raise ValueError(f"frames: only {alive.sum()} of {len(corners)} points survive tracking through every frame")
    return xy[:, alive].astype(np.float64)
