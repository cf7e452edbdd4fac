"""The sheet stage: the stitched depth's shape above a length scale from a
sheet's inextensibility (:mod:`nrdepth.isometric`), its relief below it
from the network.

Points over the sheet are followed through the selected frames whole (not
cut to the region: points near its edge stay in view), their depths come
from the maximum-depth heuristic through the camera, and they are spread
over the region's working frame and fused with the network's depth. By
default, points held to the first frame are read through the ``refined``
template, kept where enough are held and their pairs keep their lengths
(:data:`MAX_STRAIN`); with a focal length or a sheet given, where they
do not, the flow's points through the joint template. Where no sheet is
given, the sheet is first found among the held points (those that move
and keep their pairs' lengths). With neither given the stage runs over
the roi (or the whole frame) through a guessed pinhole, reads the shape
of a sheet it finds through the focal length its points' strain picks
(where that is bracketed), and a video that is no sheet, or gives the
shape nothing to read, keeps the network's depth; either way the stage
returns what it did (:class:`SheetDecision`). The reading
(:func:`read_sheet`) needs the frames alone, and the main job runs it in
a second thread beside the network's passes (:func:`read_beside`); only
the fusion (:func:`sheet_depth`) waits for the stitched depth.
"""

from __future__ import annotations

import itertools
import threading
from concurrent.futures import CancelledError, Future
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Callable, Iterable, Iterator, List, Optional, Tuple, Union

import numpy as np

from ..baselines.tracks import densify
from ..camera import Camera
from ..checks import option_error
from ..isometric import (NotSolved, TooFewPoints, estimate_focal, fuse, held_share, mdh_depths, moving_points, point_held_shares, start_grid, template_strain,
                         track_grid, unstrained_points)
from .frames import CHUNK, as_uint8, as_unit_float, resize, working_shape
from .decision import SheetDecision
from .options import ISOMETRIC_SCALE, REFINED_SCALE, ReconstructOptions

__all__ = ["sheet_region", "sheet_depth", "read_sheet", "read_beside", "SheetReading", "SheetDecision", "FLOW_MARGIN", "KEYFRAMES", "EVERY", "NEIGHBOURS", "TRACK_SIDE", "MIN_FRAMES", "MIN_FRAMES_BY_DEFAULT", "MIN_TEXTURE", "MIN_MOTION", "MIN_HELD", "MIN_READ", "MOVING_SHARE", "TRIM", "MIN_CONTRAST", "KEEP_HELD", "MAX_STRAIN", "READ_SMOOTH", "JUMP"]

FLOW_MARGIN = 48
"""The sheet's points are followed by the flow over their box and this
many pixels, not over the whole frame (the same tracks for a fraction of
the cost: docs/campaign.md, "The sheet stage's cost")."""

TRACK_SIDE = 640
"""Pixels: the sheet's points are followed in frames shrunk (area-averaged)
to this longer side at most, their places scaled back to the video's.
The flow's cost grows with the pixels: a 1920×1080 frame would cost nine
times ``kinect_paper``'s 640×480, the largest video any of the stage's
rules or checks read (a bound on cost, not chosen by a rule)."""

KEYFRAMES, EVERY, NEIGHBOURS = 8, 4, 8
"""The sheet's joint cone program runs over this many keyframes, only
every :data:`EVERY`-th other frame's program is solved (the frames
between linear in time), and each point is tied to its
:data:`NEIGHBOURS` nearest: of the settings that read generated long
sheets as the stage did before, the cheapest on kinect_paper (two rules
fixed before they were read: docs/campaign.md, "The sheet stage's cost"
and "Fewer pairs and keyframes in the joint program"). With the default
template, "joint", the one the rules read; the others keep 24
keyframes, every frame and 20 neighbours."""

MIN_FRAMES = 16
"""Fewer selected frames than this and the sheet stage leaves the network's
depth alone: the shortest clips the sheet's shape was read on (16 frames
barely bend a sheet: docs/reconstruction.md)."""

MIN_FRAMES_BY_DEFAULT = 32
"""With nothing given (neither ``focal`` nor ``sheet``), fewer selected
frames than this and the stage leaves the network's depth alone: on a
short clip the maximum-depth program reads a dome, and over 16-frame
coloured-noise videos the default read worse than the network alone
(docs/campaign.md, "The sheet's shape by default, on long videos only")."""

MIN_TEXTURE = 1.0
"""The gray-level step between neighbouring pixels of the sheet's region
in the first frame that a tenth of them must reach, or the flow has
nothing to follow (a uniform or blurred region) and the stage leaves the
network's depth alone. A tenth, not half: white paper with print on it
is flat between its lines."""

MIN_MOTION = 0.5
"""Pixels: the median over the points read of the farthest each moves from
where it starts, below which the video does not move, and the stage
leaves the network's depth alone; half the flow's own median error on
the paper's true points (docs/findings.md)."""


MIN_HELD = 0.8
"""With held points and ``focal`` or ``sheet`` given: fewer of the
point-frames in view found again than this share
(:func:`~nrdepth.isometric.held_share`), and the reading gives way: the
video's texture is too faint for its points to be followed (as on most
generated sheets: docs/campaign.md, "Tracks held to the first frame").
As many lost as the drop leaves out."""

MIN_READ = 0.1
"""To find the sheet (no ``sheet`` given): fewer held points
read (held in :data:`KEEP_HELD` of their frames and in every frame, and
moving: :data:`MIN_MOTION`, :data:`MOVING_SHARE`) than this share of
``isometric_points``, and the reading gives way: too faint a texture, or
no sheet. They are counted in place of the point-frames held
(:data:`MIN_HELD`): over a region that holds more than a sheet, the
background's points are lost and the sheet's held (docs/campaign.md,
"The sheet's shape by default"). Counted again after :data:`TRIM`."""

MOVING_SHARE = 0.2
"""To find the sheet: of the points read, only those that move at least
:data:`MIN_MOTION` and this share of the median such point's farthest
motion are the sheet's (:func:`~nrdepth.isometric.moving_points`): a
still backdrop's points by the sheet's edge move a little."""

TRIM = 3.0
"""To find the sheet: of the points that move, those whose pairs stray
from their lengths more than this many times the points' median are left
out (:func:`~nrdepth.isometric.unstrained_points`): a pair with one point
off the sheet does not keep its length. With :data:`MOVING_SHARE`, the
nearest of three ways to the points that start on the sheet, on 32
generated paper-like sheets (docs/campaign.md, "Why the default's reading
did not hold")."""

JUMP: Optional[float] = 3.0
"""To find the sheet: with :data:`TRIM`, the points whose pairs' median
depth step is more than this many median template distances are left
out too (:func:`~nrdepth.isometric.unstrained_points`' ``jump``): a point
off the sheet keeps its pairs' lengths by sitting at the camera or far
behind. Adopted by a rule that asked it to cost 32 fresh generated sheets
at most +0.002 per frame (+0.0007 ± 0.0007; the real videos read as before;
docs/campaign.md, "Points off the sheet that keep their lengths by their
depth")."""

MIN_CONTRAST = 2.0
"""To find the sheet: where the strain of the points read does not pick
out a focal length (:func:`~nrdepth.isometric.estimate_focal`'s
``contrast`` under this), the reading gives way: a surface that moves
more than it stretches, such as coloured noise, keeps its lengths
through any camera, a sheet only through its own. Chosen by a rule on
32 generated sheets and 32 coloured-noise videos (of 15 candidates, the
one that read the sheets best while the noise stayed within +0.005 of
the network; 1.35 let 4 of 32 noise videos through), checked on 64
fresh videos (docs/campaign.md, "The contrast read off the strain's
whole curve")."""

KEEP_HELD = 0.8
"""With held points (``isometric_hold``), only those found again in at
least this share of their frames in view are read
(:func:`~nrdepth.isometric.point_held_shares`): a point on blank paper
is rarely found, and the warp's guesses between would pull the program.
On 32 generated print sheets they read −0.0146 ± 0.0089 per frame
against every held point (docs/campaign.md, "Print sheets")."""

READ_SMOOTH = 1.0
"""Frames: the held points read (found in every frame) are smoothed in
time by a Gaussian of this many frames before the shape that is fused is
solved from them; every gate (the trim, the strain, the contrast, the
focal length's estimate) reads them as tracked. A sheet's reading turns
on a third of a pixel of its tracks (docs/campaign.md, "The shape read
from its points smoothed in time, the gates as tracked")."""

MAX_STRAIN = 0.0107
"""With ``isometric_template="auto"``: the held points' ``refined``
template is read where its keyframes' pairs keep their lengths to this
root mean square strain (:func:`~nrdepth.isometric.pair_strain`), and
the flow's points through the joint template where they do not (a sheet
that stretches, or tracks that slip). By a rule fixed beforehand: the
90th percentile of the strain over 20 generated inextensible sheets
whose points are held (clips 902–917; the print reads 0.0031, the cloth
0.0110: docs/campaign.md, "refined where its lengths hold")."""


def sheet_region(options: ReconstructOptions, frame: Tuple[int, int]) -> np.ndarray:
    """Where the points go in the first selected frame, bool (H, W) of the
    video's ``frame``: ``options.sheet`` (a box or a bool array), else
    ``options.roi``, else the whole frame, with room for the points."""
    options.sheet_camera(frame)  # a focal length no pinhole has is refused here, before any work
    H, W = frame
    sheet = options.sheet
    if sheet is None or (np.ndim(sheet) == 1 and len(sheet) == 4):
        x, y, w, h = (options.roi or (0, 0, W, H)) if sheet is None else (int(v) for v in sheet)
        if not (0 <= x and 0 <= y and w > 0 and h > 0 and x + w <= W and y + h <= H):
            raise option_error("sheet", f"expected a box x, y, width, height inside the {W}×{H} frame, got {sheet!r}")
        region = np.zeros(frame, bool)
        region[y : y + h, x : x + w] = True
    else:
        region = np.asarray(sheet)
        if region.dtype != np.bool_ or region.shape != tuple(frame) or region.sum() < 16:
            raise option_error("sheet", f"expected a box (x, y, w, h) or a bool array of the video's frame {tuple(frame)} with at least 16 "
                               f"pixels on the sheet, got {region.dtype} {region.shape}")
    try:
        start_grid(region, frame, int(options.isometric_points), float(options.isometric_drop))
    except ValueError as error:  # the points' region is the user's sheet (or roi)
        raise option_error("sheet" if sheet is not None or options.roi is None else "roi", error.detail) from None
    return region


def sheet_depth(raw, work: Tuple[int, int], options: ReconstructOptions, camera: Camera, region: np.ndarray,
                frames: Callable[[], Iterable[np.ndarray]], reading: Optional["Future[SheetReading]"] = None) -> SheetDecision:
    """Gives the stitched depth ``raw`` (T, h, w; an array or
    :class:`~.frames.DiskFrames`, changed in place, a chunk at a time) at
    the working resolution ``work`` its shape above the fusion's scale
    from the sheet's inextensibility, as :func:`read_sheet` reads it from
    ``frames()`` (or as ``reading``, :func:`read_beside`'s, has read it
    meanwhile): the points' depths spread over the region's working frame
    and fused with the network's. Returns what it did."""
    read = read_sheet(len(raw), options, camera, region, frames) if reading is None else reading.result()
    if read.decision.used:
        _fused(raw, work, options, region, read.xy, read.depths, float(read.decision.scale))
    return read.decision


@dataclass(frozen=True)
class SheetReading:
    """What :func:`read_sheet` read: its ``decision`` and, where it used the
    sheet's shape, the points read ``xy`` (T, n, 2) and their ``depths`` (T, n)."""

    decision: SheetDecision
    xy: Optional[np.ndarray] = None
    depths: Optional[np.ndarray] = None


@contextmanager
def read_beside(frame_count: int, options: ReconstructOptions, camera: Camera, region: np.ndarray,
                frames: Callable[[], Iterable[np.ndarray]]) -> Iterator["Future[SheetReading]"]:
    """:func:`read_sheet` in a second thread while the caller works (the
    network's passes): the sheet's points need the frames alone, and the
    two leave each other's cores idle less than either alone (kinect_paper:
    docs/reconstruction.md). The same bytes as read in turn. Yields its
    future; on leaving (an interrupted job), a reading not yet done stops
    at its next frame or step and is waited for: no thread runs on into
    the interpreter's exit, where a library's C++ threads abort it."""
    stop = threading.Event()

    def check() -> None:
        if stop.is_set():
            raise CancelledError("the job that started the sheet's reading has ended")

    future: "Future[SheetReading]" = Future()

    def run() -> None:
        try:
            future.set_result(read_sheet(frame_count, options, camera, region, frames, check))
        except BaseException as error:  # noqa: B036 (handed to the caller, who re-raises it)
            future.set_exception(error)

    thread = threading.Thread(target=run, name="nrdepth sheet reading")
    thread.start()
    try:
        yield future
    finally:
        stop.set()
        thread.join()


def read_sheet(frame_count: int, options: ReconstructOptions, camera: Camera, region: np.ndarray,
               frames: Callable[[], Iterable[np.ndarray]], check: Callable[[], None] = lambda: None) -> SheetReading:
    """The sheet's points and their depths from its inextensibility, or
    why not: points over ``region`` (:func:`sheet_region`, bool (H, W))
    followed through ``frames()`` (a fresh stream of the ``frame_count``
    selected frames whole, each (H, W), read as they come: two are held
    at a time; a second stream where the first reading gives way) and
    their depths through ``camera``, for :func:`sheet_depth` to fuse.
    ``check()`` is called at each frame and between the steps: it may
    raise to stop the reading (:func:`read_beside`).

    The readings tried, in order, with ``isometric_template`` "auto":
    where no sheet is given (nothing, or ``focal`` alone over at least
    :data:`MIN_FRAMES_BY_DEFAULT` frames), the sheet found among the
    points held to the first frame; then, with ``focal`` or ``sheet``
    given (``options.sheet_given``), the points held, of them those found
    in every frame; each through the ``refined`` template, fused at
    ``REFINED_SCALE``, where their pairs keep their lengths (strain at
    most :data:`MAX_STRAIN`); last, the points of ``isometric_hold`` (the
    flow's by default) through the joint template at ``ISOMETRIC_SCALE``
    (``isometric_scale`` given replaces both scales). With another
    template, that one alone. A reading gives way where the video gives
    it nothing to read (held points found again in fewer point-frames than
    :data:`MIN_HELD`, or, to find the sheet, fewer read than
    :data:`MIN_READ` of those asked for once those that do not move
    (:data:`MOVING_SHARE`) or strain their pairs (:data:`TRIM`) are left
    out, or a strain that picks out no focal length (:data:`MIN_CONTRAST`),
    points that move less than :data:`MIN_MOTION`, a frame with too few
    of them for its program, or a program with no answer, as through a
    focal length far too long); where every reading gives way, or the
    video has fewer than :data:`MIN_FRAMES` frames or a region with less
    texture than :data:`MIN_TEXTURE`, the network's depth is left alone.
    Held, only the points found again in :data:`KEEP_HELD` of their frames
    are read. The decision says each reading's reason for giving way."""
    camera = camera.at(region.shape)
    T = frame_count
    record = dict(focal=tuple(map(float, camera.focal)), centre=tuple(map(float, camera.centre)), frames=T, guessed=options.focal is None)
    if T < MIN_FRAMES:
        return SheetReading(SheetDecision(False, f"{T} frames, fewer than the {MIN_FRAMES} the sheet's shape needs", **record))
    long_enough = T >= MIN_FRAMES_BY_DEFAULT
    if not options.sheet_given and not long_enough:
        return SheetReading(SheetDecision(False, f"{T} frames, fewer than the {MIN_FRAMES_BY_DEFAULT} a sheet found by default needs", **record))
    auto = options.isometric_template == "auto"
    readings: List[Tuple[str, bool, bool]]  # (template, hold, find: the sheet found among the points)
    if not auto:
        hold = bool(options.isometric_hold)
        readings = [(options.isometric_template, hold, hold and not options.sheet_given)]
    elif options.sheet is not None:
        readings = [("refined", True, False), ("joint", bool(options.isometric_hold), False)]
    elif options.focal is not None:  # a region that may hold more than the sheet: found first, as by default
        readings = ([("refined", True, True)] if long_enough else []) + [("refined", True, False), ("joint", bool(options.isometric_hold), False)]
    else:  # nothing given, a region that may be no sheet: the found reading alone, which says whether it is one
        readings = [("refined", True, True)]
    passed: List[str] = []  # each reading's reason for giving way
    tracked = {}  # hold: the tracks, followed once for every reading that reads them
    for template, hold, find in readings:
        if hold not in tracked:
            stream = _checked(frames(), check)
            first = as_uint8(next(stream))
            if not tracked:
                texture = _texture(first, region)
                record.update(texture=texture)
                if texture < MIN_TEXTURE:
                    return SheetReading(SheetDecision(False, f"the sheet's region has no texture for the flow to follow ({texture:.2f} < {MIN_TEXTURE:g})", **record))
            tracked[hold] = _tracked(itertools.chain([first], stream), region, options, hold)
        through = auto and template == "refined"  # the points found in every frame: the setting its rule read
        read = _read(tracked[hold], region.shape, hold, find, through, template, options, camera, record, check)
        if isinstance(read, str):
            passed.append(f"{_named(template, hold, find)}: {read}" if len(readings) > 1 else read)
            continue
        scale = options.isometric_scale if options.isometric_scale is not None else (REFINED_SCALE if through else ISOMETRIC_SCALE)
        why = "the video moves the textured sheet" + (f" (not {'; not '.join(passed)})" if passed else "")
        return SheetReading(SheetDecision(True, why, scale=float(scale), **record), *read)
    return SheetReading(SheetDecision(False, "; ".join(passed), **record))


def _tracked(frames: Iterable[np.ndarray], region: np.ndarray, options: ReconstructOptions, hold: bool) -> np.ndarray:
    """The points over ``region`` (H, W) followed through ``frames``
    (:func:`~nrdepth.isometric.track_grid`), in frames shrunk to
    :data:`TRACK_SIDE` where larger, their tracks (T, n, 2) in the video's pixels."""
    follow = lambda frames, region: track_grid(frames, region, points=int(options.isometric_points), drop=float(options.isometric_drop),  # noqa: E731
                                               margin=FLOW_MARGIN, hold=hold)
    H, W = region.shape
    h, w = working_shape((H, W), TRACK_SIDE)
    shrunk = resize(region[None].astype(np.float32), (h, w))[0] >= 0.5
    try:
        start_grid(shrunk, (h, w), int(options.isometric_points), float(options.isometric_drop))
    except ValueError:  # a region with room for the points only at the video's size
        h, w = H, W
    if (h, w) == (H, W):
        return follow((as_uint8(frame) for frame in frames), region)
    xy = follow((as_uint8(resize(as_unit_float(frame)[None], (h, w))[0]) for frame in frames), shrunk)
    return (xy + 0.5) * np.array([W / w, H / h]) - 0.5  # pixel centres to the video's


def _checked(frames: Iterable[np.ndarray], check: Callable[[], None]) -> Iterator[np.ndarray]:
    """``frames``, ``check()`` called before each."""
    for frame in frames:
        check()
        yield frame


def _named(template: str, hold: bool, find: bool) -> str:
    """A reading's name in the log line: whose points, through which template."""
    return ("the sheet's held" if find else "held" if hold else "the flow's") + f" points through {template}"


def _read(xy: np.ndarray, frame: Tuple[int, int], hold: bool, find: bool, through: bool, template: str, options: ReconstructOptions, camera: Camera,
          record: dict, check: Callable[[], None]) -> Union[Tuple[np.ndarray, np.ndarray], str]:
    """The points read and their depths ((T, n, 2), (T, n)) of ``xy`` (T, n, 2) tracked over
    frames of ``frame`` (H, W), ``hold`` (found again by their look in the
    first frame), of them ``through``: only those found in every frame,
    and the strain of their ``refined`` template held to
    :data:`MAX_STRAIN`; or why the video gives this reading nothing to
    read. To ``find`` the sheet (held, no sheet given: the region may hold
    more than the sheet), of the held points in every frame, only
    those that move (:data:`MOVING_SHARE`) and whose pairs keep their
    lengths (:data:`TRIM`) are read, they are counted (:data:`MIN_READ`)
    in place of the point-frames held (:data:`MIN_HELD`), and their strain
    must pick a focal length (:data:`MIN_CONTRAST`). ``record`` takes what the checks measured;
    ``check()`` is called before each program."""
    held = held_share(xy, frame) if hold else None
    farthest = np.nanmax(np.linalg.norm(xy - xy[:1], axis=2), axis=0)
    motion = float(np.median(farthest))
    record.update(points=xy.shape[1], motion=motion, held=held, template=template)
    if hold and not find and held < MIN_HELD:  # first: the motion is measured on the points held
        return f"the points are found again in only {held:.0%} of the frames (< {MIN_HELD:.0%}): too faint a texture"
    read = np.ones(xy.shape[1], bool)
    if hold:
        read &= point_held_shares(xy, frame) >= KEEP_HELD
    if through or find:
        read &= np.isfinite(xy).all(axis=(0, 2))
    need = MIN_READ * options.isometric_points
    held_in = f"held in {KEEP_HELD:.0%} of their frames{' and in every frame' if through or find else ''}"
    still = f"the video does not move (the points {{:.2f}} px at most from where they start, < {MIN_MOTION:g})"
    no_answer = "the sheet's cone program found no answer ({}): is the focal length right?"
    if find:  # of the points read, those that move (none on a still background) and keep their pairs' lengths, counted
        motion = float(np.median(farthest[read])) if read.any() else 0.0  # a point lost at once never moves from where it starts
        record.update(points=int(read.sum()), motion=motion)
        if read.sum() < need:
            return f"{read.sum()} points {held_in}, fewer than {MIN_READ:.0%} of the {options.isometric_points} asked for: too faint a texture"
        read[read] = moving_points(xy[:, read], MIN_MOTION, MOVING_SHARE)
        record.update(points=int(read.sum()))
        if read.sum() < need:
            return still.format(motion) if motion < MIN_MOTION else \
                f"{read.sum()} points {held_in} move, fewer than {MIN_READ:.0%} of the {options.isometric_points} asked for: no sheet that bends"
        check()
        try:
            read[read] = unstrained_points(xy[:, read], camera, KEYFRAMES, NEIGHBOURS, TRIM, jump=JUMP)
            record.update(points=int(read.sum()))
        except NotSolved as error:
            return no_answer.format(error.status)
        if read.sum() < need:
            return f"{read.sum()} points keep their pairs' lengths, fewer than {MIN_READ:.0%} of the {options.isometric_points} asked for: no sheet"
    elif not motion >= MIN_MOTION:
        return still.format(motion)
    xy = xy[:, read]
    record.update(points=xy.shape[1])
    if xy.shape[1] < 3:
        return f"{xy.shape[1]} points held in every frame, fewer than the 3 a program needs"
    cheaper = {"keyframes": KEYFRAMES, "every": EVERY, "neighbours": NEIGHBOURS} if template == "joint" or through else {}  # what the rules read

    def solve(seen_by: Camera) -> Union[Tuple[np.ndarray, np.ndarray], str]:
        check()
        try:
            return mdh_depths(xy, seen_by, template=template, each_frame=options.isometric_each_frame, with_distances=True, **cheaper)
        except TooFewPoints as error:
            return f"too few points held in frames {error.frames[:5]}"
        except NotSolved as error:  # e.g. a focal length far too long: rays nearly parallel, no perspective to read the shape by
            return no_answer.format(error.status)

    solved, seen = solve(camera), camera
    if isinstance(solved, str):
        return solved
    depths, distances = solved
    if through:
        strain = template_strain(xy, depths, camera, distances, KEYFRAMES, NEIGHBOURS)
        record.update(strain=strain)
        if strain > MAX_STRAIN:
            return f"their pairs do not keep their lengths (strain {strain:.4f} > {MAX_STRAIN:g}): a sheet that stretches, or tracks that slip"
    if find:  # the costliest gate last (nine programs): on a sheet that stretches the strain has said no already
        check()
        try:
            estimate = estimate_focal(xy, frame)
        except NotSolved as error:
            return no_answer.format(error.status)
        record.update(contrast=estimate.contrast, focal_estimate=estimate.focal)
        if not estimate.contrast >= MIN_CONTRAST:
            return f"no focal length keeps their pairs' lengths better than the others (contrast {estimate.contrast:.2f} < {MIN_CONTRAST:g}): no sheet"
        if options.focal is None and estimate.inside:  # the gates passed through the guess; the shape through the focal length the strain picks
            seen = Camera(estimate.focal, camera.centre)
    if through or find:  # the gates read the points as tracked; the shape fused, from them smoothed in time
        from scipy.ndimage import gaussian_filter1d

        xy = gaussian_filter1d(xy, READ_SMOOTH, axis=0, mode="nearest")
        solved = solve(seen)
        if isinstance(solved, str):
            return solved
        depths = solved[0]
        record.update(focal=tuple(map(float, seen.focal)))
    return xy, depths


def _fused(raw, work: Tuple[int, int], options: ReconstructOptions, region: np.ndarray, xy: np.ndarray, depths: np.ndarray, scale: float) -> None:
    """``raw`` fused in place, a chunk at a time, with the points' depths spread over the region's working frame."""
    x, y, w_region, h_region = options.roi or (0, 0, region.shape[1], region.shape[0])
    h, w = work
    # Into the region's working frame: area-averaged resizes keep pixel centres' relative places.
    working = (xy - np.array([x, y]) + 0.5) * np.array([w / w_region, h / h_region]) - 0.5
    for a in range(0, len(xy), CHUNK):  # each frame is fused alone: memory stays a chunk's
        b = min(a + CHUNK, len(xy))
        chunk = np.asarray(raw[a:b])
        on = np.isfinite(chunk)
        fused = fuse(np.where(on, chunk, 0.0), densify(working[a:b], depths[a:b], chunk.shape), scale * min(h, w), mask=on)
        raw[a:b] = np.where(on, fused, np.nan).astype(np.float32)


def _texture(frame: np.ndarray, region: np.ndarray) -> float:
    """The 90th percentile of the absolute gray-level steps to the next pixel right and down, over ``region``."""
    f = frame.astype(np.float32)
    steps = np.concatenate([np.abs(np.diff(f, axis=1))[region[:, 1:] & region[:, :-1]], np.abs(np.diff(f, axis=0))[region[1:] & region[:-1]]])
    return float(np.percentile(steps, 90)) if steps.size else 0.0
