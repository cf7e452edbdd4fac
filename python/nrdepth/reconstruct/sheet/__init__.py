"""The sheet stage: the stitched depth's shape above a length scale from a
sheet's inextensibility (:mod:`nrdepth.isometric`), its relief below it
from the network. One pipeline, one module a step:

- :mod:`.find`: points over the region followed through the video, and,
  with no sheet given, the sheet found among them;
- :mod:`.gate`: the checks every reading passes, whatever the options;
- :mod:`.read`: the readings tried and their points' depths;
- :mod:`.fuse`: the depths spread and fused with the network's, all or nothing;
- :mod:`.settings`: :class:`SheetSettings`, every tunable value, with the rule
  that chose it.

The stage always says what it did (:class:`~nrdepth.reconstruct.SheetDecision`),
and it is fail-safe: with neither ``focal`` nor ``sheet`` given, whatever goes
wrong inside it (an error of any step) keeps the network's depth, the error's
type and message as the decision's reason and its traceback logged at debug
level; with either given, the error names the option. Only an interrupt
passes through. The reading (:func:`read_sheet`) needs the frames alone, and
the main job runs it in a second thread beside the network's passes
(:func:`read_beside`); only the fusion (:func:`sheet_depth`) waits for the
stitched depth.
"""

from __future__ import annotations

import dataclasses
import logging
import threading
from concurrent.futures import CancelledError, Future
from contextlib import contextmanager
from dataclasses import dataclass
from typing import TYPE_CHECKING, Callable, Iterable, Iterator, Optional, Tuple

import numpy as np

from ...camera import Camera
from ...checks import option_error
from ...isometric import start_grid
from ..decision import SheetDecision
from ..frames import as_uint8
from .find import checked, texture, tracked
from .fuse import fused
from .gate import GaveWay, enough_frames, enough_texture
from .read import Plan, plans, read
from .settings import SheetSettings

if TYPE_CHECKING:  # the options hold the stage's settings (.settings): no import at run time
    from ..options import ReconstructOptions

__all__ = [
    "SheetStage",
    "stage_of",
    "sheet_region",
    "sheet_depth",
    "read_sheet",
    "read_beside",
    "SheetReading",
    "SheetDecision",
    "SheetSettings",
    "Plan",
]

log = logging.getLogger("nrdepth.sheet")


@dataclass(frozen=True)
class SheetStage:
    """Where the stage runs on a video: its points' ``region`` (bool (H, W) of
    the video's frames) and its ``camera``; or, where it does not run, the
    ``skipped`` decision that says why (``region`` and ``camera`` None)."""

    region: Optional[np.ndarray] = None
    camera: Optional[Camera] = None
    skipped: Optional[SheetDecision] = None


def stage_of(options: ReconstructOptions, frame: Tuple[int, int]) -> SheetStage:
    """Whether and where the stage runs on a video of frames of ``frame`` (H, W)
    (a skipped decision's ``frames`` is the caller's to fill). With ``focal`` or ``sheet`` given, a region or camera
    that cannot be read is an error naming the option; by default it skips
    the stage, with a decision saying why, as do ``sheet_stage=False``,
    ``units="pixels"`` and ``temporal``."""

    def skipped(reason: str) -> SheetStage:
        return SheetStage(skipped=SheetDecision(False, reason))

    if not options.sheet_stage:
        return skipped("the sheet stage is off (sheet_stage=False, --no-sheet)")
    if not options.sheet_mode:
        return skipped(
            "the sheet stage runs with units='standard' and temporal off only "
            f"(units={options.units!r}, temporal={options.temporal})"
        )
    try:
        return SheetStage(sheet_region(options, frame), options.sheet_camera(frame))
    except Exception as error:  # noqa: BLE001 - by default the stage never fails the job: it steps aside and says why
        if options.sheet_given:
            raise
        return skipped(f"the stage cannot run here ({' '.join(f'{type(error).__name__}: {error}'.split())})")


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
            raise option_error(
                "sheet",
                f"expected a box (x, y, w, h) or a bool array of the video's frame {tuple(frame)} with at least 16 "
                f"pixels on the sheet, got {region.dtype} {region.shape}",
            )
    try:
        start_grid(region, frame, int(options.isometric_points), float(options.isometric_drop))
    except ValueError as error:  # the points' region is the user's sheet (or roi)
        raise option_error("sheet" if sheet is not None or options.roi is None else "roi", error.detail) from None
    return region


@dataclass(frozen=True)
class SheetReading:
    """What :func:`read_sheet` read: its ``decision`` and, where it used the
    sheet's shape, the points read ``xy`` (T, n, 2) and their ``depths`` (T, n)."""

    decision: SheetDecision
    xy: Optional[np.ndarray] = None
    depths: Optional[np.ndarray] = None


def sheet_depth(
    raw,
    work: Tuple[int, int],
    options: ReconstructOptions,
    camera: Camera,
    region: np.ndarray,
    frames: Callable[[], Iterable[np.ndarray]],
    reading: Optional["Future[SheetReading]"] = None,
) -> SheetDecision:
    """Gives the stitched depth ``raw`` (T, h, w; an array or
    :class:`~..frames.DiskFrames`, changed in place, all or nothing) at the
    working resolution ``work`` its shape above the fusion's scale from the
    sheet's inextensibility, as :func:`read_sheet` reads it from ``frames()``
    (or as ``reading``, :func:`read_beside`'s, has read it meanwhile).
    Returns what it did; fail-safe as the module says."""
    read_ = read_sheet(len(raw), options, camera, region, frames) if reading is None else reading.result()
    if not read_.decision.used:
        return read_.decision
    try:
        fused(raw, work, options.roi, region.shape, read_.xy, read_.depths, float(read_.decision.scale))
    except CancelledError:
        raise
    except Exception as error:  # noqa: BLE001 - fail-safe: the network's depth stays (fused writes all or nothing)
        return _failed(error, "fusing the sheet's depth", options, read_.decision)
    return read_.decision


@contextmanager
def read_beside(
    frame_count: int,
    options: ReconstructOptions,
    camera: Camera,
    region: np.ndarray,
    frames: Callable[[], Iterable[np.ndarray]],
) -> Iterator["Future[SheetReading]"]:
    """:func:`read_sheet` in a second thread while the caller works (the
    network's passes): the sheet's points need the frames alone. The same
    bytes as read in turn. Yields its future; on leaving (an interrupted
    job), a reading not yet done stops at its next frame or step and is
    waited for: no thread runs on into the interpreter's exit, where a
    library's C++ threads abort it."""
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


def read_sheet(
    frame_count: int,
    options: ReconstructOptions,
    camera: Camera,
    region: np.ndarray,
    frames: Callable[[], Iterable[np.ndarray]],
    check: Callable[[], None] = lambda: None,
) -> SheetReading:
    """The sheet's points and their depths from its inextensibility, or why
    not: points over ``region`` (:func:`sheet_region`, bool (H, W))
    followed through ``frames()`` (a fresh stream of the ``frame_count``
    selected frames whole, each (H, W), read as they come: two are held at
    a time; a second stream where a reading of other tracks follows) and
    their depths through ``camera``, for :func:`sheet_depth` to fuse.
    ``check()`` is called at each frame and between the steps: it may raise
    to stop the reading (:func:`read_beside`).

    The readings (:func:`~.read.plans`) are tried in order; the first that
    passes the gate (:mod:`.gate`) is used, and where every one gives way,
    or the video is too short or its region has no texture, the network's
    depth is left alone. The decision says each reading's reason for giving
    way and carries what the deciding reading measured."""
    settings: SheetSettings = options.sheet_settings
    camera = camera.at(region.shape)
    base = dict(
        focal=tuple(map(float, camera.focal)),
        centre=tuple(map(float, camera.centre)),
        frames=frame_count,
        guessed=options.focal is None,
    )
    try:
        enough_frames(frame_count, settings, options.sheet_given)
        readings = plans(options, frame_count >= settings.min_frames_by_default)
        passed = []  # each reading's reason for giving way
        tracks = {}  # hold: the tracks, followed once for every reading that reads them
        measured: dict = {}
        for plan in readings:
            if plan.hold not in tracks:
                stream = checked(frames(), check)
                first = as_uint8(next(stream))
                if not tracks:
                    base.update(texture=texture(first, region))
                    enough_texture(base["texture"], settings)
                tracks[plan.hold] = tracked(
                    _chain(first, stream),
                    region,
                    int(options.isometric_points),
                    float(options.isometric_drop),
                    plan.hold,
                    settings,
                )
            measured = {}  # the reading's own: a decision never mixes two readings' values
            try:
                found = read(tracks[plan.hold], region.shape, plan, options, settings, camera, measured, check)
            except GaveWay as error:
                passed.append(f"{plan.name()}: {error}" if len(readings) > 1 else str(error))
                continue
            why = "the video moves the textured sheet" + (f" (not {'; not '.join(passed)})" if passed else "")
            decision = SheetDecision(True, why, **{**base, **measured}, scale=found.scale)
            return SheetReading(decision, found.xy, found.depths)
        return SheetReading(SheetDecision(False, "; ".join(passed), **{**base, **measured}))
    except GaveWay as error:
        return SheetReading(SheetDecision(False, str(error), **base))
    except CancelledError:
        raise
    except Exception as error:  # noqa: BLE001 - fail-safe: the network's depth stays
        return SheetReading(_failed(error, "reading the sheet", options, SheetDecision(False, "", **base)))


def _chain(first: np.ndarray, rest: Iterator[np.ndarray]) -> Iterator[np.ndarray]:
    yield first
    yield from rest


def _failed(error: Exception, step: str, options: ReconstructOptions, decision: SheetDecision) -> SheetDecision:
    """The decision where ``step`` failed with ``error``: by default the network's
    depth, the error its reason; with ``focal`` or ``sheet`` given, an error naming it."""
    what = " ".join(f"{type(error).__name__}: {error}".split())
    if options.sheet_given:
        raise option_error(
            "focal" if options.focal is not None else "sheet", f"the sheet stage failed {step} ({what})"
        ) from error
    log.debug("the sheet stage failed %s; the network's depth stays", step, exc_info=error)
    return dataclasses.replace(decision, used=False, reason=f"the stage failed {step} ({what})", scale=None)
