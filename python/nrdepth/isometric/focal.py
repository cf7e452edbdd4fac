"""A pinhole camera's focal length from a sheet's tracked points: the one
through which the sheet's ``refined`` template keeps its pairs' lengths
best.

Algorithm: an inextensible sheet read through the wrong camera must
stretch to fit its tracks (too short a focal length exaggerates the
perspective, too long flattens it), and ``refined``'s least squares
leave that stretch as strain (:func:`~nrdepth.isometric.pair_strain`).
For each focal length on a grid even in its logarithm, spanning
pinholes that see :data:`VIEWS` degrees across the frame's longer side,
the keyframes' joint cone program and its refinement are solved (what
:func:`~nrdepth.isometric.mdh_depths` does first with
``template="refined"``, on :data:`POINTS` of the points), and their
strain measured; the least is refined by the parabola through it and
its two neighbours (in the logarithm). On ``kinect_paper``'s held
points the strain is least at the Kinect's focal length and twice as
large at 0.7× or 1.4× it; on the cloth, which stretches, it barely
changes (docs/campaign.md, "The focal length from the strain"). With
nothing given, the sheet stage's gates read through a guessed 40°
pinhole, :attr:`FocalEstimate.contrast` among them (it tells a sheet
from a surface that keeps its lengths through any camera), and where
they hold and the estimate is bracketed (:attr:`FocalEstimate.inside`)
the shape is read through the estimate (docs/campaign.md, "The default
through the focal length its points pick, where the strain's valley
lies inside the grid"); an estimate at the grid's edge may be far too
short, which costs more than the guess.

Frames and units: pixel coordinates (column x, row y); focal lengths in
pixels; the principal point at the frame's centre unless given.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional, Tuple

import numpy as np

from ..camera import Camera
from ..checks import is_number
from .mdh import keyframe_indices, neighbour_pairs, pair_strain, solve_template
from .mirror import check_anchor

__all__ = ["estimate_focal", "focal_grid", "least_strain", "FocalEstimate", "VIEWS", "STEPS", "POINTS"]

VIEWS = (25.0, 120.0)
"""Degrees across the frame's longer side: the narrowest and the widest
pinholes :func:`estimate_focal` tries (a phone's main camera sees about
65°, the cloth's 89°, the Kinect's 62°)."""
STEPS = 9
"""Focal lengths tried, even in their logarithm over :data:`VIEWS` (each
1.29 times the next)."""
POINTS = 150
"""At most this many of the points read (evenly in their order): the
strain's minimum stays where it is, at a third of the cost."""


@dataclass(frozen=True)
class FocalEstimate:
    """:func:`estimate_focal`'s answer: the ``focal`` length (pixels), the
    least ``strain`` on the grid, and the grid: its ``focals`` and their
    ``strains``. :attr:`contrast`: how well the video determines it."""

    focal: float
    strain: float
    focals: Tuple[float, ...]
    strains: Tuple[float, ...]

    @property
    def inside(self) -> bool:
        """Whether the least strain lies two steps inside the grid: both of
        :attr:`contrast`'s steps on it, the valley bracketed on either side."""
        return 2 <= int(np.argmin(self.strains)) < len(self.strains) - 2

    @property
    def contrast(self) -> float:
        """The strain two steps either side of the least (the smaller of the
        two, or the one there is at the grid's end) over the least: about 1
        where the strain does not tell focal lengths apart."""
        k = int(np.argmin(self.strains))
        sides = [self.strains[i] for i in (k - 2, k + 2) if 0 <= i < len(self.strains)]
        return float(min(sides) / self.strain) if self.strain > 0 else math.inf


def estimate_focal(xy: np.ndarray, frame: Tuple[int, int], centre: Optional[Tuple[float, float]] = None, keyframes: int = 8,
                   neighbours: int = 8, views: Tuple[float, float] = VIEWS, steps: int = STEPS, points: int = POINTS,
                   evaluations: int = 100, smooth: float = 0.0, anchor: float = 0.0) -> FocalEstimate:
    """The focal length (pixels) through which tracks ``xy`` (T, n, 2),
    finite in every frame, of a sheet in frames of ``frame`` (H, W) keep
    their pairs' lengths best (module docstring): ``keyframes`` frames
    spread over the video, each point tied to its ``neighbours`` nearest,
    ``steps`` focal lengths over pinholes seeing ``views`` degrees, at
    most ``points`` points, each refinement at most ``evaluations``
    evaluations (``solve_template``'s); ``centre``: the principal point (default: the
    frame's centre). Two experiments, neither the stage's
    (docs/campaign.md, "The focal length's strain from tracks smoothed in
    time" and "What comes next"): ``smooth``, the tracks first smoothed in
    time by a Gaussian of this many frames (0: as tracked), against the
    floor the trackers' noise sets under the strain; ``anchor``, each
    refinement pulled towards its cone program's depths by this weight
    (0: free; ``solve_template``'s), to keep it in the taut start's
    basin, where the focal length shows. The focal lengths are read one after another, on
    one BLAS thread: their refinements are bound by Python (SciPy's
    LSMR), and in two threads they contend for the GIL (on
    ``kinect_paper``'s held points 10.1 s against 7.3, the same answer)."""
    from threadpoolctl import threadpool_limits

    xy = np.asarray(xy, np.float64)
    if xy.ndim != 3 or xy.shape[2] != 2 or xy.shape[0] < 2 or xy.shape[1] < 3 or not np.isfinite(xy).all():
        raise ValueError(f"xy: expected tracks (T, n, 2) with T >= 2 and n >= 3, finite in every frame, got shape {xy.shape}")
    if not (len(views) == 2 and all(is_number(v) for v in views) and 0 < views[0] < views[1] < 180):
        raise ValueError(f"views: expected (narrowest, widest) degrees across the frame, 0 < narrowest < widest < 180, got {views!r}")
    for name, value, least in (("keyframes", keyframes, 2), ("neighbours", neighbours, 1), ("steps", steps, 3), ("points", points, 3),
                               ("evaluations", evaluations, 1)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < least:
            raise ValueError(f"{name}: expected an int >= {least}, got {value!r}")
    if len(frame) != 2 or min(frame) < 1:
        raise ValueError(f"frame: expected (H, W) pixels, got {frame!r}")
    if not (is_number(smooth) and np.isfinite(smooth) and smooth >= 0):
        raise ValueError(f"smooth: expected finite frames >= 0 (0: the tracks as they are), got {smooth!r}")
    check_anchor(anchor)
    if smooth > 0:
        from scipy.ndimage import gaussian_filter1d

        xy = gaussian_filter1d(xy, float(smooth), axis=0, mode="nearest")
    chosen = np.unique(np.rint(np.linspace(0, xy.shape[1] - 1, min(points, xy.shape[1]))).astype(int))
    keys = keyframe_indices(len(xy), keyframes)
    tracks = xy[keys][:, chosen]
    pairs = neighbour_pairs(tracks[0], neighbours)
    focals = focal_grid(frame, views, steps)

    def strain(focal: float) -> float:
        camera = Camera(float(focal), centre).at(tuple(frame))
        rays = camera.rays(tracks)
        depths, distances = solve_template(rays, pairs, refined=True, evaluations=evaluations, anchor=anchor)
        return pair_strain(tracks, depths, camera, pairs, distances)

    # One BLAS thread: the same rounding on any machine, and no BLAS threads spinning beside Python-bound work.
    with threadpool_limits(limits=1, user_api="blas"):
        strains = np.array([strain(focal) for focal in focals])
    return least_strain(focals, strains)


def focal_grid(frame: Tuple[int, int], views: Tuple[float, float] = VIEWS, steps: int = STEPS) -> np.ndarray:
    """The focal lengths (pixels) :func:`estimate_focal` tries for frames of
    ``frame`` (H, W): ``steps``, even in their logarithm, from the pinhole
    seeing ``views[1]`` degrees across the longer side to the one seeing ``views[0]``."""
    side = max(frame)
    longest, shortest = (side / 2 / math.tan(math.radians(v) / 2) for v in views)
    return np.exp(np.linspace(math.log(shortest), math.log(longest), steps))


def least_strain(focals: np.ndarray, strains: np.ndarray) -> FocalEstimate:
    """The estimate from the ``strains`` measured through ``focals`` (even in
    their logarithm): the least, refined by the parabola through it and its
    two neighbours (in the logarithm)."""
    strains = np.asarray(strains, np.float64)
    k = int(np.argmin(strains))
    focal = float(focals[k])
    if 0 < k < len(focals) - 1:
        a, b, c = strains[k - 1 : k + 2]
        curvature = a - 2 * b + c
        if curvature > 0:
            step = math.log(focals[1] / focals[0])
            focal = float(math.exp(math.log(focals[k]) + step * 0.5 * (a - c) / curvature))
    return FocalEstimate(focal, float(strains[k]), tuple(map(float, focals)), tuple(map(float, strains)))
