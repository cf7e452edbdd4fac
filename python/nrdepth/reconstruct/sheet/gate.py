"""The sheet stage's gate: each check a reading must pass, and the words it
gives way with. A check raises :class:`GaveWay`; it never returns a reason.
Every option of the stage is read through these same checks: an option asks
for a reading (a template, a way to solve each frame, a scale), it never
switches a check off."""

from __future__ import annotations

from .settings import SheetSettings

__all__ = [
    "GaveWay",
    "enough_frames",
    "enough_texture",
    "enough_held",
    "enough_motion",
    "enough_points",
    "lengths_kept",
    "focal_picked",
    "NO_ANSWER",
]

NO_ANSWER = "the sheet's cone program found no answer ({}): is the focal length right?"


class GaveWay(Exception):
    """A reading gives way: the video gives it nothing to read (``str(error)`` says why)."""


def enough_frames(frames: int, settings: SheetSettings, sheet_given: bool) -> None:
    if frames < settings.min_frames:
        raise GaveWay(f"{frames} frames, fewer than the {settings.min_frames} the sheet's shape needs")
    if not sheet_given and frames < settings.min_frames_by_default:
        raise GaveWay(
            f"{frames} frames, fewer than the {settings.min_frames_by_default} a sheet found by default needs"
        )


def enough_texture(texture: float, settings: SheetSettings) -> None:
    if texture < settings.min_texture:
        raise GaveWay(
            f"the sheet's region has no texture for the flow to follow ({texture:.2f} < {settings.min_texture:g})"
        )


def enough_held(held: float, settings: SheetSettings) -> None:
    if held < settings.min_held:
        raise GaveWay(
            f"the points are found again in only {held:.0%} of the frames (< {settings.min_held:.0%}): "
            "too faint a texture"
        )


def enough_motion(motion: float, settings: SheetSettings) -> None:
    if not motion >= settings.min_motion:
        raise GaveWay(
            f"the video does not move (the points {motion:.2f} px at most from where they start, "
            f"< {settings.min_motion:g})"
        )


def enough_points(count: int, asked: int, settings: SheetSettings, after: str, then: str) -> None:
    """``count`` points ``after`` a step, at least :attr:`~.SheetSettings.min_read` of the ``asked``;
    ``then``: what fewer mean."""
    if count < settings.min_read * asked:
        raise GaveWay(f"{count} points {after}, fewer than {settings.min_read:.0%} of the {asked} asked for: {then}")


def lengths_kept(strain: float, settings: SheetSettings) -> None:
    if strain > settings.max_strain:
        raise GaveWay(
            f"their pairs do not keep their lengths (strain {strain:.4f} > {settings.max_strain:g}): "
            "a sheet that stretches, or tracks that slip"
        )


def focal_picked(contrast: float, settings: SheetSettings) -> None:
    if not contrast >= settings.min_contrast:
        raise GaveWay(
            "no focal length keeps their pairs' lengths better than the others "
            f"(contrast {contrast:.2f} < {settings.min_contrast:g}): no sheet"
        )
