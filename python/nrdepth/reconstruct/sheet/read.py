"""The sheet stage's readings: which it tries, in order, and one reading of
the points' depths from the sheet's inextensibility.

A reading (:class:`Plan`) names its template, whether its points are held
to their look in the first frame, whether the sheet is found among them
(nothing given: the region may hold more than a sheet) and whether it reads
only the points found in every frame, gated by the strain of their
``refined`` template (``through``). With neither ``focal`` nor ``sheet``
given there is one reading, the found one, whatever the options ask: they
choose its template and how each frame is solved, never which checks run.

Frames and units: the video's pixels; depth along the optical axis in units
of the mean template distance (:mod:`nrdepth.isometric`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Callable, List

import numpy as np

from ...camera import Camera
from ...isometric import NotSolved, TooFewPoints, estimate_focal, held_share, mdh_depths, template_strain
from .find import found_points, read_points
from .gate import NO_ANSWER, GaveWay, enough_held, enough_motion, focal_picked, lengths_kept
from .settings import ISOMETRIC_EACH_FRAME, SheetSettings

if TYPE_CHECKING:  # the options hold the stage's settings: imported where used
    from ..options import ReconstructOptions

__all__ = ["Plan", "Reading", "plans", "read"]


@dataclass(frozen=True)
class Plan:
    """One reading the stage may try (see the module's docstring)."""

    template: str
    hold: bool
    find: bool
    through: bool

    def name(self) -> str:
        """The reading's name in the log line: whose points, through which template."""
        return (
            "the sheet's held" if self.find else "held" if self.hold else "the flow's"
        ) + f" points through {self.template}"


@dataclass(frozen=True)
class Reading:
    """A reading's points ``xy`` (T, n, 2), their ``depths`` (T, n), the
    ``camera`` they were read through and the fusion's ``scale``."""

    xy: np.ndarray
    depths: np.ndarray
    camera: Camera
    scale: float


def plans(options: ReconstructOptions, long_enough: bool) -> List[Plan]:
    """The readings to try, in order, for ``options`` (``long_enough``: a
    video long enough for a sheet found by default)."""
    auto = options.isometric_template == "auto"
    if not options.sheet_given:  # a region that may be no sheet: the found reading alone, which says whether it is one
        return [Plan("refined" if auto else options.isometric_template, True, True, True)]
    hold = bool(options.isometric_hold)
    if not auto:
        return [Plan(options.isometric_template, hold, False, False)]
    held, joint = Plan("refined", True, False, True), Plan("joint", hold, False, False)
    if (
        options.sheet is None and long_enough
    ):  # focal alone: a region that may hold more than the sheet, found first as by default
        return [Plan("refined", True, True, True), held, joint]
    return [held, joint]


def read(
    xy: np.ndarray,
    frame: tuple,
    plan: Plan,
    options: ReconstructOptions,
    settings: SheetSettings,
    camera: Camera,
    measured: dict,
    check: Callable[[], None],
) -> Reading:
    """The points read of ``xy`` (T, n, 2, tracked over frames of ``frame``
    (H, W) as ``plan.hold`` says) and their depths through ``camera``, as
    ``plan`` reads them; raises :class:`~.gate.GaveWay` where the video
    gives it nothing to read. ``measured`` takes what the checks measured;
    ``check()`` is called before each program.

    Held, only the points found again in most of their frames are read
    (:attr:`~.SheetSettings.keep_held`). Through, only those found in every
    frame, and their ``refined`` template's strain must stay under
    :attr:`~.SheetSettings.max_strain`. Found, the sheet is the points that
    move and keep their lengths (:func:`~.find.found_points`), and their
    strain must pick a focal length (:attr:`~.SheetSettings.min_contrast`);
    with no focal length given, the shape is read through the one it picks
    where that lies inside the range tried. Through, the gates read the
    points as tracked, and the shape fused is solved again from them smoothed
    in time (:attr:`~.SheetSettings.read_smooth`)."""
    held = held_share(xy, frame) if plan.hold else None
    farthest = np.nanmax(np.linalg.norm(xy - xy[:1], axis=2), axis=0)
    measured.update(points=xy.shape[1], motion=float(np.median(farthest)), held=held, template=plan.template)
    if plan.hold and not plan.find:  # first: the motion is measured on the points held
        enough_held(held, settings)
    chosen, xy = read_points(xy, frame, plan.hold, plan.through or plan.find, settings)
    if plan.find:
        chosen = found_points(xy, chosen, camera, int(options.isometric_points), settings, measured, check)
    else:
        enough_motion(measured["motion"], settings)
    xy = xy[:, chosen]
    measured.update(points=xy.shape[1])
    if xy.shape[1] < 3:
        raise GaveWay(f"{xy.shape[1]} points held in every frame, fewer than the 3 a program needs")
    gate_template = "refined" if plan.through else plan.template
    # Through, the gate's program is the same whatever the options ask (refined, each frame the default way);
    # the shape's, as asked.
    depths, distances = _solve(
        xy,
        camera,
        gate_template,
        ISOMETRIC_EACH_FRAME if plan.through else options.isometric_each_frame,
        plan,
        settings,
        check,
    )
    if plan.through:
        strain = template_strain(xy, depths, camera, distances, settings.keyframes, settings.neighbours)
        measured.update(strain=strain)
        lengths_kept(strain, settings)
    seen = camera
    if plan.find:  # the costliest gate last (nine programs): on a sheet that stretches the strain has said no already
        check()
        try:
            estimate = estimate_focal(xy, frame)
        except NotSolved as error:
            raise GaveWay(NO_ANSWER.format(error.status)) from None
        measured.update(contrast=estimate.contrast, focal_estimate=estimate.focal)
        focal_picked(estimate.contrast, settings)
        if (
            options.focal is None and estimate.inside
        ):  # the gates passed through the guess; the shape through the focal length the strain picks
            seen = Camera(estimate.focal, camera.centre)
    if plan.through:  # the gates read the points as tracked; the shape fused, from them smoothed in time
        if settings.read_smooth > 0:
            from scipy.ndimage import gaussian_filter1d  # scipy loads with the stage, not with nrdepth

            xy = gaussian_filter1d(xy, settings.read_smooth, axis=0, mode="nearest")
        depths = _solve(xy, seen, plan.template, options.isometric_each_frame, plan, settings, check)[0]
        measured.update(focal=tuple(map(float, seen.focal)))
    refined = plan.through and plan.template == "refined"
    scale = (
        options.isometric_scale
        if options.isometric_scale is not None
        else settings.refined_scale
        if refined
        else settings.joint_scale
    )
    return Reading(xy, depths, seen, float(scale))


def _solve(
    xy: np.ndarray,
    camera: Camera,
    template: str,
    each_frame: str,
    plan: Plan,
    settings: SheetSettings,
    check: Callable[[], None],
) -> tuple:
    """:func:`~nrdepth.isometric.mdh_depths` of ``xy`` through ``camera``: (depths (T, n), template distances);
    raises :class:`~.gate.GaveWay`."""
    check()
    cheaper = (
        dict(keyframes=settings.keyframes, every=settings.every, neighbours=settings.neighbours)
        if template == "joint" or plan.through
        else {}
    )
    try:
        return mdh_depths(xy, camera, template=template, each_frame=each_frame, with_distances=True, **cheaper)
    except TooFewPoints as error:
        raise GaveWay(f"too few points held in frames {error.frames[:5]}") from None
    except (
        NotSolved
    ) as error:  # e.g. a focal length far too long: rays nearly parallel, no perspective to read the shape by
        raise GaveWay(NO_ANSWER.format(error.status)) from None
