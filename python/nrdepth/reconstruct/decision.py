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
    depth alone for ``reason`` (a check that gave way, an error inside the
    stage, or why the stage did not run). The camera's ``focal`` and
    ``centre`` (pixels) it read through, None where it did not run;
    ``guessed`` where no focal length was given (``focal`` is then the
    guessed pinhole's, or the ``focal_estimate`` where the shape was read
    through it: the line says ``estimated``). What the deciding reading
    measured, None where not reached, each against its
    :class:`~nrdepth.SheetSettings` bound: the ``frames``, the ``points``
    read, the ``texture`` (``min_texture``), the ``motion`` in pixels
    (``min_motion``), the share of point-frames ``held`` (``min_held``), the
    ``template``, the ``contrast`` with which the points' strain picks a
    focal length (``min_contrast``) and the ``focal_estimate`` it picks, the
    held points' ``strain`` under ``refined`` (``max_strain``), and the
    fusion's ``scale`` (a fraction of the shorter side) where used.
    :meth:`line` is the job's log line; ``depth.npz`` keeps :meth:`as_dict`
    as JSON under ``sheet``; :attr:`camera` is the camera as a
    :class:`~nrdepth.Camera`."""

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
