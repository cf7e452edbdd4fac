"""Points followed through a video of a sheet, for its shape from
inextensibility (:mod:`nrdepth.isometric`): a grid over the sheet in the
first frame, moved from frame to frame by OpenCV's Farneback dense optical
flow, forward and backward; with ``hold``, found again after each step by
their look in the first frame (:mod:`nrdepth.isometric.hold`); the points
where the two flows disagree most left out.

Frames and units: pixel coordinates (column x, row y, pixel centres at
integers); NaN from the frame where a point leaves the view (with
``hold``: in each frame where it is not found again).
"""

from __future__ import annotations

import itertools
import math
from concurrent.futures import ThreadPoolExecutor
from contextlib import nullcontext
from typing import Iterable, Iterator, Optional, Tuple, Union

import numpy as np

from ..checks import option_error
from .hold import HOLD_WINDOW, Anchor

__all__ = ["track_grid", "start_grid", "start_texture", "PLACES", "track_points", "least_disagreeing", "inside", "held_share", "point_held_shares", "check_video", "frames_of", "bridge_gaps", "DROP", "BORDER", "FLOWS"]

DROP = 0.2
"""``reconstruct(focal=...)``'s share of the
tracked points left out: those whose forward and backward flows disagree
most (:func:`track_grid`'s ``drop``). At every fusion scale the paper
and the cloth per frame gain, and the long generated sheets decided it
by a rule fixed beforehand (docs/campaign.md)."""


BORDER = 0.0
""":func:`track_points`' and :func:`track_grid`'s margin in pixels: a
point closer than this to the frame's edge, or beyond it, is lost for
good. 0: a point is lost where it leaves the frame (8 lost more points
and read generated sheets worse: docs/reconstruction.md)."""


def check_video(video: np.ndarray) -> np.ndarray:
    video = np.asarray(video)
    if video.ndim != 3 or video.dtype != np.uint8 or video.shape[0] < 2 or min(video.shape[1:]) < 8:
        raise ValueError(f"video: expected a (T, H, W) uint8 grayscale video with T >= 2 and frames of at least 8×8, "
                         f"got {video.dtype} {video.shape}")
    return video


def frames_of(video: Union[np.ndarray, Iterable[np.ndarray]]) -> Tuple[np.ndarray, Iterator[np.ndarray]]:
    """The first frame of ``video`` and an iterator over the rest, each
    checked as it comes: ``video`` a (T, H, W) uint8 array, or any iterable
    of (H, W) uint8 frames (a stream, read once), at least 2 frames of at
    least 8×8."""
    if isinstance(video, np.ndarray):
        video = check_video(video)
        return video[0], iter(video[1:])
    frames = iter(video)
    first = next(frames, None)
    if not (isinstance(first, np.ndarray) and first.ndim == 2 and first.dtype == np.uint8 and min(first.shape) >= 8):
        got = "nothing" if first is None else f"{getattr(first, 'dtype', type(first).__name__)} {getattr(first, 'shape', '')}"
        raise ValueError(f"video: expected a (T, H, W) uint8 grayscale video or uint8 frames (H, W) of at least 8×8, got {got} first")

    def rest() -> Iterator[np.ndarray]:
        count = 1
        for frame in frames:
            if not (isinstance(frame, np.ndarray) and frame.dtype == np.uint8 and frame.shape == first.shape):
                raise ValueError(f"video: expected uint8 frames of the first one's shape {first.shape}, got "
                                 f"{getattr(frame, 'dtype', type(frame).__name__)} {getattr(frame, 'shape', '')} at frame {count}")
            count += 1
            yield frame
        if count < 2:
            raise ValueError("video: expected at least 2 frames, got 1")

    return first, rest()


def _check_mask(mask: Optional[np.ndarray], shape: Tuple[int, int]) -> np.ndarray:
    if mask is None:
        return np.ones(shape, bool)
    mask = np.asarray(mask)
    if mask.dtype != np.bool_ or mask.shape != shape:
        raise ValueError(f"mask: expected a bool array of a frame's shape {shape}, got {mask.dtype} {mask.shape}")
    return mask


PLACES = ("grid", "texture")
""":func:`track_grid`'s ways of placing its points in the first frame:
a square grid (:func:`start_grid`), or where the first frame has texture
to follow (:func:`start_texture`)."""


def track_grid(video: Union[np.ndarray, Iterable[np.ndarray]], mask: Optional[np.ndarray] = None, points: int = 400, window: int = 21,
               backward: bool = True, drop: float = 0.0, border: float = BORDER, flow: str = "farneback",
               margin: Optional[int] = None, hold: bool = False, place: str = "grid", flow_scale: float = 1.0, stride: int = 1) -> np.ndarray:
    """Tracks (T, n, 2) (column, row) of about ``points`` points over
    ``mask`` (H, W) of the first frame (default: the whole frame), placed
    by ``place`` (:data:`PLACES`: on a square grid, or where the first
    frame has texture), at least ``border`` pixels inside the frame's edge, moved through
    ``video`` ((T, H, W) uint8, or a stream of frames: :func:`frames_of`) by :func:`track_points` (``window``,
    ``backward``, ``border``, ``flow``, ``margin``, ``hold``, ``flow_scale``, ``stride``). ``drop``: the share of the points left out,
    those whose forward and backward flows disagree most over the video
    (:func:`track_points`' ``disagreement``; needs ``backward`` or
    ``hold``): points at a boundary of the motion, where the flow bleeds
    from one side to the other, whose tracks would read as stretch
    (docs/reconstruction.md)."""
    first, rest = frames_of(video)
    video = itertools.chain([first], rest)
    if drop > 0 and not (backward or hold):
        raise ValueError("drop: the points to leave out are found by the flow both ways or by the hold: expected backward=True or hold=True, or drop=0")
    if place not in PLACES:
        raise ValueError(f"place: expected one of {PLACES}, got {place!r}")
    grid = start_grid(mask, first.shape, points, drop, border) if place == "grid" else start_texture(first, mask, points, window, drop, border)
    if drop == 0:
        return track_points(video, grid, window, backward, border=border, flow=flow, margin=margin, hold=hold, flow_scale=flow_scale, stride=stride)
    xy, disagreement = track_points(video, grid, window, backward, disagreement=True, border=border, flow=flow, margin=margin, hold=hold,
                                    flow_scale=flow_scale, stride=stride)
    return xy[:, least_disagreeing(disagreement, drop)]


def _spacing(mask: np.ndarray, points: int, drop: float) -> float:
    """The spacing (pixels) of a square grid of about ``points`` over ``mask``, after checking ``points`` and ``drop``."""
    if not (isinstance(points, (int, np.integer)) and points >= 4):
        raise ValueError(f"points: expected an int >= 4, got {points!r}")
    if not (isinstance(drop, (int, float, np.floating)) and 0 <= drop < 1):
        raise ValueError(f"drop: expected a share of the points in [0, 1), got {drop!r}")
    return max(1.0, float(np.sqrt(mask.sum() / points)))


def start_grid(mask: Optional[np.ndarray], frame: Tuple[int, int], points: int = 400, drop: float = 0.0, border: float = BORDER) -> np.ndarray:
    """:func:`track_grid`'s starting points (n, 2) (column, row): a square
    grid of about ``points`` over ``mask`` (H, W) = ``frame`` (default: the
    whole frame), at least ``border`` pixels inside its edge. A mask with
    room for fewer than 4 once the share ``drop`` is left out is refused
    (by the name ``mask``), before any tracking."""
    mask = _check_mask(mask, tuple(frame))
    spacing = _spacing(mask, points, drop)
    rows, cols = np.mgrid[spacing / 2 : frame[0] : spacing, spacing / 2 : frame[1] : spacing]
    grid = np.column_stack([cols.ravel(), rows.ravel()])
    grid = grid[mask[rows.astype(int).ravel(), cols.astype(int).ravel()] & inside(grid, tuple(frame), border)]
    kept = len(grid) - int(round(drop * len(grid)))
    if kept < 4:
        raise option_error("mask", f"expected room for at least 4 points at {points} points over its area (drop {drop:g}), got {kept}")
    return grid


def start_texture(first: np.ndarray, mask: Optional[np.ndarray] = None, points: int = 400, window: int = 21, drop: float = 0.0,
                  border: float = BORDER) -> np.ndarray:
    """:func:`track_grid`'s starting points (n, 2) (column, row) where the
    first frame ``first`` (H, W) uint8 has texture to follow: up to
    ``points`` of OpenCV's Shi–Tomasi corners whose ``window``-pixel
    window (the trackers') lies on ``mask`` (default: the whole frame),
    strongest first, each scored over that window, at least 0.7 of :func:`start_grid`'s
    spacing from the others, none where the strongest's score falls below
    1 %: blank paper gets none, where the flow would drag them. Refused as
    :func:`start_grid` refuses, by the name ``mask``, with room for fewer
    than 4."""
    import cv2  # imported here: `import nrdepth` stays light

    first = np.asarray(first)
    if first.ndim != 2 or first.dtype != np.uint8:
        raise ValueError(f"first: expected a (H, W) uint8 grayscale frame, got {first.dtype} {first.shape}")
    mask = _check_mask(mask, first.shape)
    spacing = _spacing(mask, points, drop)
    if not (isinstance(window, (int, np.integer)) and window >= 3):
        raise ValueError(f"window: expected an int >= 3 (pixels), got {window!r}")
    # The pixels at least border inside the frame (as inside() counts them) and on the mask...
    (h, w), b = first.shape, math.ceil(border)
    room = np.zeros(first.shape, np.uint8)
    room[b : h - b, b : w - b] = mask[b : h - b, b : w - b]
    # ...with the whole window on the mask: the sheet's outline is the strongest corner there is, and its window half backdrop.
    room = cv2.erode(room, np.ones((window, window), np.uint8), borderType=cv2.BORDER_CONSTANT, borderValue=1)
    corners = cv2.goodFeaturesToTrack(first, maxCorners=int(points), qualityLevel=0.01, minDistance=0.7 * spacing, mask=room,
                                      blockSize=int(window))
    start = np.zeros((0, 2)) if corners is None else corners.reshape(-1, 2).astype(np.float64)
    kept = len(start) - int(round(drop * len(start)))
    if kept < 4:
        raise option_error("mask", f"expected texture for at least 4 points over its area (drop {drop:g}), found {kept}")
    return start


def least_disagreeing(disagreement: np.ndarray, drop: float) -> np.ndarray:
    """Indices, ascending, of the points kept when the share ``drop`` of
    them whose ``disagreement`` (n,) (:func:`track_points`) is largest is
    left out (ties: the later point goes)."""
    kept = len(disagreement) - int(round(drop * len(disagreement)))
    return np.sort(np.argsort(disagreement, kind="stable")[:kept])


def track_points(video: Union[np.ndarray, Iterable[np.ndarray]], start: np.ndarray, window: int = 21, backward: bool = True,
                 disagreement: bool = False, border: float = BORDER, flow: str = "farneback", margin: Optional[int] = None,
                 hold: bool = False, flow_scale: float = 1.0, stride: int = 1):
    """Tracks (T, n, 2) (column, row) of the points ``start`` (n, 2) of the
    first frame, moved through ``video`` ((T, H, W) uint8, or a stream of
    frames: :func:`frames_of`) by dense optical flow (``flow``) from each frame to the
    next: the mean of where the forward flow takes a point and where the
    backward flow says it came from (both real videos read better, generated
    sheets within 0.0005 per frame: docs/reconstruction.md; the backward
    flow runs in a second thread), or with ``backward`` False the forward
    flow alone (half the flow's work). A point is lost for good (NaN)
    from the first frame after the start where it lies within ``border``
    pixels of the frame's edge or beyond it: the flow cannot follow what
    leaves the view, and would hold it at the edge.
    With ``disagreement`` (needs ``backward`` or ``hold``), also (n,): each point's
    distance between where the two flows take it (forward alone, held:
    between where the flow takes it and where it is found again), its
    mean over the steps it stays in view (pixels; 0 for a point lost at once, or, held, never found again). ``flow``: one of
    :data:`FLOWS`; ``margin``: the flow is computed over the points' bounding
    box grown by this many pixels (None: over the whole frame).

    ``hold``: each point the flow moves is then found again by its look in
    the first frame (:mod:`nrdepth.isometric.hold`), so that the chained
    flow's drift does not add up; a point not found again is NaN in that
    frame, not dragged, and may be found again later (NaN also where it
    is outside the frame). ``disagreement`` then averages over the frames
    where a point is held.

    ``flow_scale`` (0, 1]: the flow computed on the frames shrunk by this
    factor (area-averaged), its field scaled back: its cost goes with the
    area, and held points are found again at the frames' own size.

    ``stride``: only every ``stride``-th frame and the last are tracked
    (each step ``stride`` frames apart: held points only need the flow to
    land them within reach), the points in the frames between linear in
    time (NaN where either end is): a ``stride``-th of the flows' work."""
    import cv2  # imported here: `import nrdepth` stays light
    from scipy.ndimage import map_coordinates
    from threadpoolctl import threadpool_limits

    first, rest = frames_of(video)
    start = np.asarray(start, np.float64)
    if start.ndim != 2 or start.shape[1] != 2 or not np.isfinite(start).all():
        raise ValueError(f"start: expected finite points (n, 2) (column, row), got shape {start.shape}")
    if not (isinstance(window, (int, np.integer)) and window >= 3):
        raise ValueError(f"window: expected an int >= 3 (pixels), got {window!r}")
    if not (isinstance(border, (int, float, np.integer, np.floating)) and 0 <= border < min(first.shape) / 2):
        raise ValueError(f"border: expected pixels in [0, {min(first.shape) / 2:g}) (half the frame's shorter side), got {border!r}")
    if disagreement and not (backward or hold):
        raise ValueError("disagreement: the flows' disagreement needs backward=True, or hold=True (the forward flow against the hold)")
    if flow not in FLOWS:
        raise ValueError(f"flow: expected one of {FLOWS}, got {flow!r}")
    if margin is not None and not (isinstance(margin, (int, np.integer)) and margin >= 0):
        raise ValueError(f"margin: expected pixels >= 0 or None (the whole frame), got {margin!r}")
    if not isinstance(hold, (bool, np.bool_)):
        raise ValueError(f"hold: expected a bool, got {hold!r}")
    if isinstance(flow_scale, (bool, np.bool_)) or not (isinstance(flow_scale, (int, float, np.integer, np.floating)) and 0 < flow_scale <= 1):
        raise ValueError(f"flow_scale: expected a factor in (0, 1], got {flow_scale!r}")
    if isinstance(stride, (bool, np.bool_)) or not (isinstance(stride, (int, np.integer)) and stride >= 1):
        raise ValueError(f"stride: expected an int >= 1 (1: every frame tracked), got {stride!r}")
    dense, dense_back = _flow(cv2, flow, window, flow_scale), _flow(cv2, flow, window, flow_scale)  # one each: a DIS object is not shared between threads
    H, W = first.shape
    anchor = Anchor(cv2, first, start, max(H, W) if margin is None else margin) if hold else None

    def at(field: np.ndarray, where: np.ndarray) -> np.ndarray:  # bilinear
        return np.stack([map_coordinates(field[..., c], [where[:, 1], where[:, 0]], order=1, mode="nearest") for c in (0, 1)], axis=1)

    xy, tracked = [start], [0]  # the tracked frames' points and indices
    alive = np.arange(len(start))
    carried = start  # with hold: every point's place, held or carried on by the warp
    apart, steps = np.zeros(len(start)), np.zeros(len(start))
    previous = first
    # The backward flow in a second thread while this one computes the forward flow (OpenCV releases the GIL, and
    # one Farneback call gains nothing from a second core): the same numbers in less time on two cores. One BLAS
    # thread: the hold's small products gain nothing from more, whose threads spin after each call and take the
    # cores from the flows (kinect_paper's held points: 16.0 s against 25.8, the same tracks).
    with threadpool_limits(limits=1, user_api="blas"), ThreadPoolExecutor(1) if backward else nullcontext() as helper:
        for t, frame in _strided(rest, stride):  # two or three frames held at a time: a stream is read once
            now_xy = np.full_like(start, np.nan)
            if len(alive):
                was = carried if hold else xy[-1][alive]
                # The flow over the points' box and a margin, not the whole frame: its cost goes with the area.
                x0, y0 = (0, 0) if margin is None else (max(0, int(np.floor(was[:, k].min())) - margin) for k in (0, 1))
                x1, y1 = (W, H) if margin is None else (min(n, int(np.ceil(was[:, k].max())) + margin + 1) for k, n in ((0, W), (1, H)))
                a, b, corner = previous[y0:y1, x0:x1], frame[y0:y1, x0:x1], np.array([x0, y0], np.float64)
                field_back = helper.submit(dense_back, b, a) if backward else None
                ahead = was + at(dense(a, b), was - corner)
                now = ahead
                if backward:
                    field, back = field_back.result(), ahead
                    for _ in range(3):  # the point p whose backward flow lands on xy[t − 1]: p = xy[t − 1] − field(p)
                        back = was - at(field, back - corner)
                    now = (ahead + back) / 2
                if hold:  # every point stays alive: where it is not held it is NaN, and carried on
                    now, held, carried = anchor.hold(frame, now)
                    carried = np.where(held[:, None], now, carried)
                    stays = held & inside(now, (H, W), border)
                    now_xy[stays] = now[stays]
                    counted = stays
                else:
                    stays = inside(now, (H, W), border)
                    alive, now = alive[stays], now[stays]
                    now_xy[alive] = now
                    counted = alive
                if backward or hold:  # forward alone, held: where the flow took the point against where it is found again
                    apart[counted] += np.linalg.norm(ahead[stays] - (back if backward else now)[stays], axis=1)
                    steps[counted] += 1
            xy.append(now_xy)
            tracked.append(t)
            previous = frame
    xy = _every_frame(np.stack(xy), tracked)
    return (xy, apart / np.maximum(steps, 1)) if disagreement else xy


def _strided(frames: Iterable[np.ndarray], stride: int) -> Iterator[Tuple[int, np.ndarray]]:
    """(index, frame) of every ``stride``-th of ``frames`` (the frames after the first, counted from 1) and of the last."""
    skipped = None
    for t, frame in enumerate(frames, 1):
        skipped = None if t % stride == 0 else (t, frame)
        if skipped is None:
            yield t, frame
    if skipped is not None:
        yield skipped


def _every_frame(xy: np.ndarray, tracked: list) -> np.ndarray:
    """Tracks (T, n, 2) of every frame from the tracked frames' ``xy``
    (len(tracked), n, 2) at the ascending indices ``tracked``: linear in
    time between them, NaN where either end is (unlike ``mdh._between``'s
    depths, which take the nearer end's: a track lost at one end is not
    guessed at)."""
    if tracked[-1] + 1 == len(xy):
        return xy
    out = np.empty((tracked[-1] + 1,) + xy.shape[1:])
    for (a, b), (xa, xb) in zip(zip(tracked, tracked[1:]), zip(xy, xy[1:])):
        share = (np.arange(a, b) - a)[:, None, None] / (b - a)
        out[a:b] = xa + share * (xb - xa)
    out[tracked] = xy  # exactly as tracked (a NaN at the far end would spoil the near one's share 0)
    return out


FLOWS = ("farneback", "farneback2", "dis")
""":func:`track_points`' dense flows: OpenCV's Farneback (5 pyramid levels,
``window``-pixel windows, 5 iterations a level), the same at 2 iterations
a level (``farneback2``: 0.58× the time on ``kinect_paper``'s frames), or
DIS (its "medium" preset; ``window`` unused)."""


def _flow(cv2, name: str, window: int, scale: float = 1.0):
    """The dense flow from one uint8 frame to another, (H, W, 2) float32
    (column, row); with ``scale`` below 1, computed on both shrunk by it."""
    if name in ("farneback", "farneback2"):
        iterations = 5 if name == "farneback" else 2
        flow = lambda a, b: cv2.calcOpticalFlowFarneback(a, b, None, 0.5, 5, window, iterations, 7, 1.5, 0)  # noqa: E731
    else:
        dis = cv2.DISOpticalFlow_create(cv2.DISOPTICAL_FLOW_PRESET_MEDIUM)
        flow = lambda a, b: dis.calc(np.ascontiguousarray(a), np.ascontiguousarray(b), None)  # noqa: E731
    if scale == 1:
        return flow

    def shrunk(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        size = (max(1, round(a.shape[1] * scale)), max(1, round(a.shape[0] * scale)))
        small = flow(cv2.resize(a, size, interpolation=cv2.INTER_AREA), cv2.resize(b, size, interpolation=cv2.INTER_AREA))
        field = cv2.resize(small, (a.shape[1], a.shape[0]), interpolation=cv2.INTER_LINEAR)
        return field * np.array([a.shape[1] / size[0], a.shape[0] / size[1]], np.float32)

    return shrunk


def inside(xy: np.ndarray, shape: Tuple[int, int], border: float) -> np.ndarray:
    """Which points (n, 2) lie at least ``border`` pixels inside a frame of ``shape`` (H, W)."""
    return (xy[:, 0] >= border) & (xy[:, 0] <= shape[1] - 1 - border) & (xy[:, 1] >= border) & (xy[:, 1] <= shape[0] - 1 - border)


def held_share(xy: np.ndarray, shape: Tuple[int, int]) -> float:
    """The share of held tracks' (T, n, 2) point-frames after the first
    that are held, of those still in a frame of ``shape`` (H, W): a point
    that is NaN within :data:`~nrdepth.isometric.hold.HOLD_WINDOW` px of the frame's edge, where
    it was last held, counts as gone from view, not as lost."""
    held, lost = _held_counts(xy, shape)
    return float(held.sum() / max(held.sum() + lost.sum(), 1))


def point_held_shares(xy: np.ndarray, shape: Tuple[int, int]) -> np.ndarray:
    """Each point's :func:`held_share` (n,): a point on blank paper or off
    the sheet is rarely held; NaN where never in view after the first frame."""
    held, lost = _held_counts(xy, shape)
    return np.where(held + lost > 0, held / np.maximum(held + lost, 1), np.nan)


def _held_counts(xy: np.ndarray, shape: Tuple[int, int]) -> Tuple[np.ndarray, np.ndarray]:
    """Each point's frames after the first held, and lost while in view (n,), (n,)."""
    xy = np.asarray(xy)
    if xy.ndim != 3 or xy.shape[2] != 2 or len(xy) == 0:
        raise ValueError(f"xy: expected tracks (T, n, 2) with T >= 1, got shape {xy.shape}")
    last = xy[0].copy()
    held = np.zeros(xy.shape[1], int)
    lost = np.zeros(xy.shape[1], int)
    for frame in xy[1:]:
        found = np.isfinite(frame).all(axis=1)
        last[found] = frame[found]
        gone = ~inside(last, shape, HOLD_WINDOW)
        held += found
        lost += ~found & ~gone
    return held, lost


def bridge_gaps(xy: np.ndarray, frames: int) -> np.ndarray:
    """Tracks (T, n, 2) with each point's runs of at most ``frames`` NaN
    frames between two frames where it is found filled in, linearly in
    time between those two; longer gaps, and those before its first or
    after its last frame found (out of view), stay NaN. Held tracks lose a
    point for a frame where noise moves Lucas–Kanade's way back by a few
    tenths of a pixel; over a few frames a sheet's points move nearly
    linearly (the programs' ``every`` assumes as much). 0: a copy."""
    xy = np.array(xy, np.float64)
    if xy.ndim != 3 or xy.shape[2] != 2:
        raise ValueError(f"xy: expected tracks (T, n, 2), got shape {xy.shape}")
    if not (isinstance(frames, (int, np.integer)) and frames >= 0):
        raise ValueError(f"frames: expected an int >= 0 (the longest gap bridged), got {frames!r}")
    found = np.isfinite(xy).all(axis=2)
    if frames == 0 or found.all():
        return xy
    T = len(xy)
    t = np.arange(T)[:, None]
    before = np.maximum.accumulate(np.where(found, t, -1), axis=0)  # the last frame found at or before each
    after = np.minimum.accumulate(np.where(found, t, T)[::-1], axis=0)[::-1]  # the first at or after
    bridged = ~found & (before >= 0) & (after < T) & (after - before - 1 <= frames)
    frame, point = np.nonzero(bridged)
    a, b = before[frame, point], after[frame, point]
    weight = ((frame - a) / (b - a))[:, None]
    xy[frame, point] = (1 - weight) * xy[a, point] + weight * xy[b, point]
    return xy
