"""Which tracked points are the sheet's, where the video is not cut to it.

Points spread over a whole frame land on the sheet and on what is behind
or beside it. Two tests leave the others out:

- :func:`moving_points`: a still background's points do not move, but
  those by the sheet's edge move a little (their windows hold some of
  the sheet) or are dragged along. A point is kept where it moves at
  least ``least`` pixels from where it starts and at least ``share`` of
  the median such point's farthest motion.
- :func:`unstrained_points`: a sheet keeps its pairs' lengths; a pair
  with one point off it does not. The keyframes' joint cone program and
  its ``refined`` least squares (what :func:`~nrdepth.isometric.mdh_depths`
  solves first with ``template="refined"``) fit every pair's length; each
  point's strain is the root mean square of its pairs' relative length
  errors ``‖Z_i r_i − Z_j r_j‖ / D_ij − 1`` over the keyframes, and the
  points above ``factor`` times the median are left out, solved again up
  to ``passes`` times. A point off the sheet can keep its pairs' lengths
  all the same, by sitting at the camera or far behind the sheet (its
  pairs then span depth, their lengths free to fit): with ``jump``, a
  point is also left out where its pairs' median depth step (root mean
  square over the keyframes) is more than ``jump`` times the median
  template distance. On a sheet a pair's depth step is at most its
  length, and a point's median pair is about the median's length.

On 32 generated paper-like sheets over still textured backdrops the two
together left a median of 100 % of the points read on the sheet (95 %
without them), and the sheet's shape through a guessed pinhole read them
as well as from the points that start on the sheet (docs/campaign.md,
"Why the default's reading did not hold").

Frames and units: tracks (T, n, 2) in pixel coordinates (column x, row
y), NaN where a point is lost; motion in pixels.
"""

from __future__ import annotations

from typing import Optional

import numpy as np

from ..camera import Camera
from ..checks import is_number
from .mdh import keyframe_indices, neighbour_pairs, solve_template

__all__ = ["moving_points", "unstrained_points"]


def moving_points(xy: np.ndarray, least: float = 0.5, share: float = 0.2) -> np.ndarray:
    """Bool (n,): the points of tracks ``xy`` (T, n, 2) whose farthest
    distance from where they start (over the frames they are in view) is
    at least ``least`` pixels and at least ``share`` of the median over
    the points that reach ``least``; none kept where no point reaches it."""
    xy = np.asarray(xy, np.float64)
    if xy.ndim != 3 or xy.shape[2] != 2:
        raise ValueError(f"xy: expected tracks (T, n, 2), got shape {xy.shape}")
    for name, value, top in (("least", least, np.inf), ("share", share, 1.0)):
        if not (is_number(value) and 0 <= value <= top):
            raise ValueError(f"{name}: expected a number in [0, {top:g}], got {value!r}")
    # fmax skips NaN (out of view); a point lost from the first frame on is never seen to move
    farthest = np.nan_to_num(np.fmax.reduce(np.linalg.norm(xy - xy[:1], axis=2), axis=0), nan=0.0) if len(xy) else np.zeros(xy.shape[1])
    moving = farthest >= least
    if not moving.any():
        return moving
    return farthest >= max(least, share * float(np.median(farthest[moving])))


def unstrained_points(xy: np.ndarray, camera: Camera, keyframes: int = 8, neighbours: int = 8, factor: float = 3.0,
                      passes: int = 3, jump: Optional[float] = None) -> np.ndarray:
    """Bool (n,): the points of tracks ``xy`` (T, n, 2), finite in every
    frame, whose pairs keep their lengths (module docstring): those whose
    strain in the ``keyframes``' ``refined`` template through ``camera``
    (each tied to its ``neighbours`` nearest) is at most ``factor`` times
    the points' median, after up to ``passes`` rounds of leaving the
    others out and solving again; with ``jump``, also at most that many
    median template distances from its neighbours in depth (module
    docstring). Every point where too few are left to tie each to its
    neighbours."""
    xy = np.asarray(xy, np.float64)
    if xy.ndim != 3 or xy.shape[2] != 2 or not np.isfinite(xy).all():
        raise ValueError(f"xy: expected tracks (T, n, 2) finite in every frame, got shape {xy.shape}")
    if not (is_number(factor) and factor >= 1):
        raise ValueError(f"factor: expected a number >= 1 (times the median strain), got {factor!r}")
    if jump is not None and not (is_number(jump) and 0 < jump < np.inf):
        raise ValueError(f"jump: expected None or a positive number (times the median template distance), got {jump!r}")
    for name, value, low in (("keyframes", keyframes, 2), ("neighbours", neighbours, 1), ("passes", passes, 1)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
            raise ValueError(f"{name}: expected an int >= {low}, got {value!r}")
    keys = keyframe_indices(len(xy), keyframes)
    kept = np.ones(xy.shape[1], bool)
    for _ in range(passes):
        index = np.flatnonzero(kept)
        if len(index) <= neighbours + 1:
            break
        tracks = xy[keys][:, index]
        pairs = neighbour_pairs(tracks[0], neighbours)
        rays = camera.rays(tracks)
        depths, distances = solve_template(rays, pairs, refined=True)
        points = rays * depths[..., None]
        pair = np.sqrt(np.mean((np.linalg.norm(points[:, pairs[:, 0]] - points[:, pairs[:, 1]], axis=2) / distances - 1) ** 2, axis=0))
        n = len(index)
        strain = np.sqrt((np.bincount(pairs[:, 0], pair**2, n) + np.bincount(pairs[:, 1], pair**2, n)) / np.maximum(np.bincount(pairs.ravel(), minlength=n), 1))
        strained = strain > factor * np.median(strain)
        if jump is not None:
            step = np.sqrt(np.mean((depths[:, pairs[:, 0]] - depths[:, pairs[:, 1]]) ** 2, axis=0))
            strained |= _median_by_point(pairs, step, n) > jump * np.median(distances)
        if not strained.any():
            break
        kept[index[strained]] = False
    return kept


def _median_by_point(pairs: np.ndarray, values: np.ndarray, n: int) -> np.ndarray:
    """(n,): each point's median of ``values`` (E,) over the ``pairs`` (E, 2) it is in (0 where none)."""
    point = pairs.T.ravel()
    value = np.concatenate([values, values])
    order = np.lexsort((value, point))
    point, value = point[order], value[order]
    start = np.searchsorted(point, np.arange(n))
    count = np.bincount(point, minlength=n)
    if not len(value):
        return np.zeros(n)
    low, high = (np.clip(start + k, 0, len(value) - 1) for k in ((count - 1) // 2, count // 2))  # clipped: a point in no pair reads 0 below
    return np.where(count > 0, (value[low] + value[high]) / 2, 0.0)
