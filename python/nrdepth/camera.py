"""The pinhole camera a video of a sheet was filmed with.

Intrinsics only, in pixels of the video's frames as given (before ``roi``
and the working resolution): focal lengths ``(f_x, f_y)`` and the principal
point ``(c_x, c_y)``, x to the right and y down, pixel centres at integer
coordinates. A point (X, Y, Z) in the camera's frame (Z along the optical
axis, away from the camera) is seen at ``(f_x·X/Z + c_x, f_y·Y/Z + c_y)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Optional, Tuple

import numpy as np

from .checks import is_number, option_error

__all__ = ["Camera", "WIDEST", "NARROWEST", "GUESSED_VIEW"]

WIDEST = 170.0
"""Degrees: the widest view across a frame a pinhole camera is taken to have (wider is a fisheye, or a mistaken focal length)."""

NARROWEST = 1.0
"""Degrees: the narrowest view across a frame a camera is taken to have: narrower, its rays are all but parallel, there is no
perspective to read a sheet's shape by (the cone program may find no answer, or a wrong one), and the focal length is a mistake."""

GUESSED_VIEW = 40.0
"""Degrees: the view across a frame's longer side of the pinhole :meth:`Camera.guessed` takes where no focal length is given.
Chosen by a rule fixed before it was read, on 32 generated paper-like sheets filmed through pinholes of 40–80°: of 40°, 50°
and 60°, the one that read them best, −0.0065 ± 0.0042 per frame against their true cameras (a focal length 1.02–2.30× the
truth: a guess too long costs a sheet's shape less than one too short); kept by a second rule that added 32 sheets filmed at
80–100° (−0.0114 ± 0.0046 over the 64). The real cloth, filmed at 89°, is read worse through it than by the network alone
(docs/campaign.md, "A guessed pinhole where no focal length is given" and "The guess over wide-angle sheets")."""


def _pair(value: Any, name: str, what: str, positive: bool) -> Tuple[float, float]:
    """Two finite numbers (positive ones with ``positive``, where one number stands for both), not strings or bools."""
    if isinstance(value, np.ndarray) and value.ndim == 0:
        value = value.item()
    items = (value, value) if positive and is_number(value) else value
    try:
        items = tuple(items)
    except TypeError:
        items = ()
    if len(items) != 2 or not all(is_number(v) and math.isfinite(v) and (v > 0 or not positive) for v in items):
        raise option_error(name, f"expected {what}, got {value!r}")
    return float(items[0]), float(items[1])


@dataclass(frozen=True)
class Camera:
    """A pinhole camera's intrinsics, checked once.

    ``focal``: (f_x, f_y) in pixels, or one number for both; ``centre``:
    the principal point (c_x, c_y) in pixels, or None for the centre of the
    frame it is used with (:meth:`principal_point`)."""

    focal: Tuple[float, float]
    centre: Optional[Tuple[float, float]] = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "focal", _pair(self.focal, "focal", "the camera's focal length in pixels, one positive number or (f_x, f_y)", True))
        if self.centre is not None:
            object.__setattr__(self, "centre", _pair(self.centre, "centre", "the principal point (c_x, c_y) in pixels", False))

    @classmethod
    def from_matrix(cls, K: Any) -> "Camera":
        """The camera of a 3×3 intrinsic matrix ``[[f_x, s, c_x], [0, f_y, c_y], [0, 0, 1]]`` (no skew)."""
        K = np.asarray(K, np.float64)
        if K.shape != (3, 3) or not np.all(np.isfinite(K)) or K[0, 1] != 0 or K[1, 0] != 0 or not np.array_equal(K[2], [0, 0, 1]):
            raise ValueError(f"K: expected a 3×3 intrinsic matrix [[f_x, 0, c_x], [0, f_y, c_y], [0, 0, 1]], got {K.tolist()}")
        return cls((K[0, 0], K[1, 1]), (K[0, 2], K[1, 2]))

    @classmethod
    def guessed(cls, frame: Tuple[int, int], centre: Optional[Tuple[float, float]] = None, view: float = GUESSED_VIEW) -> "Camera":
        """A pinhole that sees ``view`` degrees (default :data:`GUESSED_VIEW`)
        across the longer side of frames of ``frame`` (H, W) pixels, its
        principal point ``centre`` or the frame's centre: for a video whose
        focal length is not known."""
        if not (is_number(view) and 0 < view < 180):
            raise ValueError(f"view: expected degrees across the frame in (0, 180), got {view!r}")
        f = max(frame) / 2 / math.tan(math.radians(view) / 2)
        return cls(f, centre).at(frame)

    def principal_point(self, frame: Tuple[int, int]) -> Tuple[float, float]:
        """(c_x, c_y): ``centre``, or the centre of a frame of ``frame`` (H, W) pixels."""
        if self.centre is not None:
            return self.centre
        h, w = frame
        return (w - 1) / 2, (h - 1) / 2

    def at(self, frame: Tuple[int, int]) -> "Camera":
        """This camera with its principal point fixed for frames of ``frame``
        (H, W) pixels; refused if it would see more than :data:`WIDEST` across
        them (no pinhole does: a focal length that small is a mistake), or
        less than :data:`NARROWEST` (no perspective to read)."""
        h, w = frame
        for side, f, axis in ((w, self.focal[0], "f_x"), (h, self.focal[1], "f_y")):
            seen = 2 * math.degrees(math.atan(side / 2 / f))
            if seen > WIDEST:
                raise option_error("focal", f"{axis} = {f:g} px sees {seen:.1f}° across the frame's {side} pixels; a pinhole camera sees under "
                                   f"{WIDEST:g}° (a focal length above {side / 2 / math.tan(math.radians(WIDEST / 2)):.1f} px)")
            if seen < NARROWEST:
                raise option_error("focal", f"{axis} = {f:g} px sees {seen:.2g}° across the frame's {side} pixels; the sheet's shape needs "
                                   f"perspective: a view of at least {NARROWEST:g}° (a focal length below "
                                   f"{side / 2 / math.tan(math.radians(NARROWEST / 2)):.0f} px)")
        return Camera(self.focal, self.principal_point(frame))

    def rays(self, xy: np.ndarray, frame: Optional[Tuple[int, int]] = None) -> np.ndarray:
        """The rays (…, 3) through image points ``xy`` (…, 2), scaled to z = 1
        (``frame``: (H, W), for the default principal point)."""
        if self.centre is None and frame is None:
            raise ValueError("frame: the camera has no principal point; give the frame's (H, W)")
        (fx, fy), (cx, cy) = self.focal, self.principal_point(frame)  # type: ignore[arg-type]
        return np.stack([(xy[..., 0] - cx) / fx, (xy[..., 1] - cy) / fy, np.ones(xy.shape[:-1])], axis=-1)
