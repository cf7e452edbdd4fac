"""The sheet stage's first step: points over the region followed through the
video, and, where no sheet is given, the sheet found among them (the points
that are held, move and keep their pairs' lengths).

Frames and units: the video's pixels (column x, row y, pixel centres at
integers); tracks (T, n, 2), NaN where a point is lost.
"""

from __future__ import annotations

from typing import Callable, Iterable, Iterator

import numpy as np

from ...camera import Camera
from ...isometric import NotSolved, bridge_gaps, moving_points, point_held_shares, start_grid, track_grid, unstrained_points
from ..frames import as_uint8, as_unit_float, resize, working_shape
from .gate import NO_ANSWER, GaveWay, enough_motion, enough_points
from .settings import SheetSettings

__all__ = ["tracked", "texture", "checked", "read_points", "found_points"]


def tracked(
    frames: Iterable[np.ndarray], region: np.ndarray, points: int, drop: float, hold: bool, settings: SheetSettings
) -> np.ndarray:
    """About ``points`` points over ``region`` (H, W) followed through
    ``frames`` (:func:`~nrdepth.isometric.track_grid`, ``drop`` of them left
    out, ``hold``: found again by their look in the first frame), in frames
    shrunk to :attr:`~.SheetSettings.track_side` where larger: their tracks
    (T, n, 2) in the video's pixels."""

    def follow(frames: Iterable[np.ndarray], region: np.ndarray) -> np.ndarray:
        return track_grid(frames, region, points=points, drop=drop, margin=settings.flow_margin, hold=hold)

    H, W = region.shape
    h, w = working_shape((H, W), settings.track_side)
    shrunk = resize(region[None].astype(np.float32), (h, w))[0] >= 0.5
    try:
        start_grid(shrunk, (h, w), points, drop)
    except ValueError:  # a region with room for the points only at the video's size
        h, w = H, W
    if (h, w) == (H, W):
        return follow((as_uint8(frame) for frame in frames), region)
    xy = follow((as_uint8(resize(as_unit_float(frame)[None], (h, w))[0]) for frame in frames), shrunk)
    return (xy + 0.5) * np.array([W / w, H / h]) - 0.5  # pixel centres to the video's


def texture(frame: np.ndarray, region: np.ndarray) -> float:
    """The 90th percentile of the absolute gray-level steps to the next pixel right and down, over ``region``."""
    f = frame.astype(np.float32)
    steps = np.concatenate(
        [
            np.abs(np.diff(f, axis=1))[region[:, 1:] & region[:, :-1]],
            np.abs(np.diff(f, axis=0))[region[1:] & region[:-1]],
        ]
    )
    return float(np.percentile(steps, 90)) if steps.size else 0.0


def checked(frames: Iterable[np.ndarray], check: Callable[[], None]) -> Iterator[np.ndarray]:
    """``frames``, ``check()`` called before each."""
    for frame in frames:
        check()
        yield frame


def read_points(xy: np.ndarray, frame: tuple, hold: bool, every_frame: bool, settings: SheetSettings) -> tuple:
    """Which of the points ``xy`` (T, n, 2) are read, bool (n,), and their
    tracks to read (T, n, 2): held, those found again in
    :attr:`~.SheetSettings.keep_held` of their frames in view, their gaps of
    at most :attr:`~.SheetSettings.bridge` frames bridged
    (:func:`~nrdepth.isometric.bridge_gaps`); with ``every_frame``, only
    those then found in every frame."""
    read = np.ones(xy.shape[1], bool)
    if hold:
        read &= point_held_shares(xy, frame) >= settings.keep_held
        xy = bridge_gaps(xy, settings.bridge)
    if every_frame:
        read &= np.isfinite(xy).all(axis=(0, 2))
    return read, xy


def found_points(
    xy: np.ndarray,
    read: np.ndarray,
    camera: Camera,
    asked: int,
    settings: SheetSettings,
    measured: dict,
    check: Callable[[], None],
) -> np.ndarray:
    """The sheet found among the points ``read`` (bool (n,)) of ``xy``: of
    them, those that move (:attr:`~.SheetSettings.moving_share`: none on a
    still background) and whose pairs keep their lengths through ``camera``
    (:attr:`~.SheetSettings.trim`, :attr:`~.SheetSettings.jump`), counted
    after each step against :attr:`~.SheetSettings.min_read` of the
    ``asked``. Returns the points found, bool (n,); ``measured`` takes the
    count and motion. Raises :class:`~.GaveWay`."""
    held_in = f"held in {settings.keep_held:.0%} of their frames and in every frame"
    farthest = np.nanmax(np.linalg.norm(xy - xy[:1], axis=2), axis=0)
    motion = (
        float(np.median(farthest[read])) if read.any() else 0.0
    )  # a point lost at once never moves from where it starts
    measured.update(points=int(read.sum()), motion=motion)
    enough_points(int(read.sum()), asked, settings, held_in, "too faint a texture")
    read = read.copy()
    read[read] = moving_points(xy[:, read], settings.min_motion, settings.moving_share)
    measured.update(points=int(read.sum()))
    if read.sum() < settings.min_read * asked:
        enough_motion(motion, settings)
    enough_points(int(read.sum()), asked, settings, f"{held_in} move", "no sheet that bends")
    check()
    try:
        read[read] = unstrained_points(
            xy[:, read], camera, settings.keyframes, settings.neighbours, settings.trim, jump=settings.jump
        )
    except NotSolved as error:
        raise GaveWay(NO_ANSWER.format(error.status)) from None
    measured.update(points=int(read.sum()))
    enough_points(int(read.sum()), asked, settings, "keep their pairs' lengths", "no sheet")
    return read
