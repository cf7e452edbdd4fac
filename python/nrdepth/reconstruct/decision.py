"""What the sheet stage did (:mod:`.sheet`): whether it used the sheet's
shape or left the network's depth alone, why, and what its checks
measured; the job's log line and ``depth.npz``'s ``sheet``."""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields
from typing import Optional, Tuple

from ..camera import Camera

__all__ = ["SheetDecision"]


@dataclass(frozen=True)
class SheetDecision:
    """What the sheet stage did: ``used`` its shape, or left the network's
    depth alone for ``reason``; the camera's ``focal`` and ``centre``
    (pixels) the shape was read through (None where the stage did not run:
    off, or skipped, the ``reason`` says why), ``guessed`` where no focal length
    was given (then ``focal`` is :meth:`~nrdepth.Camera.guessed`'s, or the
    ``focal_estimate`` where the shape was read through it; the log line
    says ``estimated``), the ``frames`` read, the ``points`` read (after the drop and, held, :data:`~.sheet.KEEP_HELD`),
    the ``texture`` (gray levels, :data:`~.sheet.MIN_TEXTURE`), ``motion``
    (pixels, :data:`~.sheet.MIN_MOTION`) and the share of point-frames ``held``
    its checks measured (None where not reached), the
    ``template`` whose points were read last, with nothing given the
    ``contrast`` with which their strain picks a focal length
    (:data:`~.sheet.MIN_CONTRAST`) and the ``focal_estimate`` it picks (pixels,
    :func:`~nrdepth.isometric.estimate_focal`: 518 px on ``kinect_paper``
    with its roi, the Kinect's 528; with nothing given, the shape is read
    through it where :attr:`~nrdepth.isometric.FocalEstimate.inside`),
    the held points' ``strain``
    under ``refined`` (:data:`~.sheet.MAX_STRAIN`) and the fusion's ``scale`` (a
    fraction of the shorter side) where used. :meth:`line` is the job's log
    line; ``depth.npz`` keeps :meth:`as_dict` as JSON under ``sheet``."""

    used: bool
    reason: str
    focal: Optional[Tuple[float, float]] = None
    centre: Optional[Tuple[float, float]] = None
    frames: int = 0
    guessed: bool = False
    points: int = 0
    texture: Optional[float] = None
    motion: Optional[float] = None
    held: Optional[float] = None
    template: Optional[str] = None
    contrast: Optional[float] = None
    focal_estimate: Optional[float] = None
    strain: Optional[float] = None
    scale: Optional[float] = None

    def as_dict(self) -> dict:
        """The decision as ``depth.npz``'s ``sheet`` keeps it (JSON): its fields and its ``line``."""
        return {**asdict(self), "line": self.line()}

    @classmethod
    def from_dict(cls, saved: dict) -> "SheetDecision":
        """The decision :meth:`as_dict` kept (its ``line`` made again, not read)."""
        names = {f.name for f in fields(cls)}
        return cls(**{key: tuple(value) if isinstance(value, list) else value for key, value in saved.items() if key in names})

    def line(self) -> str:
        what = "the sheet's shape from inextensibility" if self.used else "the network's depth alone"
        measured = "".join(
            f", {name} {value:.{digits}f}"
            for name, value, digits in (
                ("texture", self.texture, 2),
                ("motion px", self.motion, 2),
                ("held", self.held, 2),
                ("contrast", self.contrast, 2),
                ("focal estimate px", self.focal_estimate, 1),
                ("strain", self.strain, 4),
                ("scale", self.scale, 2),
            )
            if value is not None
        )
        template = f", template {self.template}" if self.template else ""
        # read through the estimate: focal was set from focal_estimate itself, so they are equal exactly
        if self.focal is None:  # the stage did not run: no camera, no points
            return f"sheet: {what} ({self.reason}; {self.frames} frames)"
        given = "" if not self.guessed else " estimated" if self.focal[0] == self.focal_estimate else " guessed"
        return (
            f"sheet: {what} ({self.reason}; focal {self.focal[0]:g},{self.focal[1]:g} px{given}, {self.frames} frames, "
            f"{self.points} points{template}{measured})"
        )

    @property
    def camera(self) -> Optional[Camera]:
        """The camera the shape was read through (or would have been), or None where the stage did not run."""
        return None if self.focal is None else Camera(self.focal, self.centre)
