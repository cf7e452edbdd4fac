"""The sheet stage's tunable values, in one typed object.

Each field says what it bounds, the rule that chose it and the data it was
chosen on (the rules, written before their data were read, are in
docs/sheet-stage.md; the runs behind them in git history). A field that is
a bound of cost, not a rule's choice, says so. The stage reads these and
nothing else: a test, a benchmark or a user passes a
:class:`SheetSettings` (``ReconstructOptions(sheet_settings=...)``, or
``--sheet-settings key=value:key=value`` on the command line), never a
module global.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, fields
from typing import Any, Optional

from ...checks import is_number, option_error

__all__ = ["SheetSettings", "ISOMETRIC_EACH_FRAME"]

ISOMETRIC_EACH_FRAME = "lengths"
"""With a camera's focal length, what each solved frame's depths are
(:func:`nrdepth.isometric.mdh_depths`' ``each_frame``): refined so that
each pair keeps its template distance, in every frame or, where one
refined frame would change its shape, in none. By the rule fixed
beforehand, on 32 generated paper-like sheets −0.0129 ± 0.0059 per frame
against the program's; both real videos read as the program's, every
frame falling back (docs/campaign.md, "Sheets that bend as real sheets
do, and each frame's lengths kept")."""

_INTS = ("flow_margin", "track_side", "keyframes", "every", "neighbours", "min_frames", "min_frames_by_default", "bridge")
_SHARES = ("min_held", "min_read", "moving_share", "keep_held")


@dataclass(frozen=True, repr=False)
class SheetSettings:
    """The sheet stage's tunable values (:mod:`nrdepth.reconstruct.sheet`)."""

    flow_margin: int = 48
    """Pixels: the points are followed by the flow over their box and this
    margin, not over the whole frame: the same tracks for a fraction of the
    cost (a bound of cost)."""
    track_side: int = 640
    """Pixels: the points are followed in frames shrunk (area-averaged) to this
    longer side at most, their places scaled back to the video's. A bound of
    cost: the flow's cost grows with the pixels, and no rule read a larger
    frame."""
    keyframes: int = 8
    """The joint cone program's keyframes (with :attr:`every` and
    :attr:`neighbours`, the cheapest setting that read 32 generated long
    sheets as 24 keyframes, every frame and 20 neighbours did; a rule of
    cost fixed before it was read). Templates other than ``joint`` and the
    held ``refined`` reading keep 24, 1 and 20."""
    every: int = 4
    """Only every this-many-th other frame's program is solved, the frames
    between linear in time (see :attr:`keyframes`)."""
    neighbours: int = 8
    """Each point is tied to this many nearest points (see :attr:`keyframes`)."""
    min_frames: int = 16
    """Fewer selected frames and the stage keeps the network's depth: the
    shortest clips a sheet's shape was read on (16 frames barely bend one)."""
    min_frames_by_default: int = 32
    """With neither ``focal`` nor ``sheet`` given, fewer frames and the stage
    keeps the network's depth: on 16-frame coloured-noise videos the default
    read worse than the network alone, and a short clip reads as a dome."""
    min_texture: float = 1.0
    """Gray levels: the step between neighbouring pixels of the region in the
    first frame that a tenth of them must reach, or the flow has nothing to
    follow (a uniform or blurred region). A tenth, not half: print on white
    paper is flat between its lines."""
    min_motion: float = 0.5
    """Pixels: the median over the points read of the farthest each moves
    from where it starts, below which the video does not move; half the
    flow's own median error on kinect_paper's true points (read off that
    video, not chosen by a rule)."""
    min_held: float = 0.8
    """With held points and ``focal`` or ``sheet`` given: fewer of the
    point-frames in view found again than this share and the reading gives
    way (too faint a texture: most generated sheets)."""
    min_read: float = 0.1
    """To find the sheet: fewer points read (held in :attr:`keep_held` of their
    frames and in every frame, moving, keeping their lengths) than this share
    of ``isometric_points`` and the reading gives way. Counted in place of
    :attr:`min_held`: over a region that holds more than a sheet, the
    background's points are lost and the sheet's held."""
    moving_share: float = 0.2
    """To find the sheet: only points that move at least :attr:`min_motion`
    and this share of the median moving point's farthest motion are the
    sheet's (a still backdrop's points by the sheet's edge move a little).
    With :attr:`trim`, the nearest of three ways to the points that start on
    the sheet, on 32 generated paper-like sheets."""
    trim: float = 3.0
    """To find the sheet: points whose pairs stray from their lengths more than
    this many times the points' median are left out (a pair with one point
    off the sheet does not keep its length; see :attr:`moving_share`)."""
    jump: Optional[float] = 3.0
    """To find the sheet: with :attr:`trim`, points whose pairs' median depth
    step passes this many median template distances are left out too (an
    intruder keeps its lengths by sitting at the camera or far behind). A
    geometric bound with margin (a pair's depth step is at most its length),
    adopted by a rule that let it cost 32 fresh generated sheets at most
    +0.002 per frame: +0.0007 ± 0.0007. None: no such trim."""
    min_contrast: float = 2.0
    """To find the sheet: where the strain of the points read picks out no
    focal length (:func:`~nrdepth.isometric.estimate_focal`'s contrast under
    this) the reading gives way: coloured noise keeps its lengths through
    any camera, a sheet only through its own. Of 15 candidates, the one that
    read 32 generated sheets best while 32 coloured-noise videos stayed
    within +0.005 of the network (1.35 let 4 through); checked on 64 fresh
    videos."""
    keep_held: float = 0.8
    """With held points, only those found again in this share of their frames
    in view are read (a point on blank paper is rarely found): on 32
    generated print sheets −0.0146 ± 0.0089 per frame against every held
    point."""
    bridge: int = 0
    """Frames: a held point's gaps of at most this many frames between two
    where it is found are filled in, linearly in time, before the points
    found in every frame are counted (:func:`~nrdepth.isometric.bridge_gaps`;
    noise loses a point for a frame at a time). 0: none bridged."""
    read_smooth: float = 1.0
    """Frames: the points read are smoothed in time by a Gaussian this wide
    before the shape that is fused is solved; every gate reads them as
    tracked. Adopted by a rule on 32 fresh sheets (−0.00003 ± 0.00013, within
    its bound) with 32 noise videos read as before. 0: not smoothed."""
    max_strain: float = 0.0107
    """The held points' ``refined`` template is read where its keyframes' pairs
    keep their lengths to this RMS strain: the 90th percentile over 20
    generated inextensible sheets whose points are held (a rule fixed
    beforehand; a real print reads 0.0031, a real cloth 0.0110)."""
    joint_scale: float = 0.3
    """The length (a fraction of the frame's shorter side) above which the
    shape read through the joint template is kept, the network's relief
    below it: picked by a rule on 64 generated sheets."""
    refined_scale: float = 0.1
    """The same through the held points' ``refined`` template: of 0.3, 0.2,
    0.1 and 0.05 the best on 32 generated paper-like sheets by a rule fixed
    beforehand."""

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if f.name == "jump" and value is None:
                continue
            if f.name in _INTS:
                # a program needs two keyframes
                least = {"flow_margin": 0, "track_side": 8, "keyframes": 2, "bridge": 0}.get(f.name, 1)
                ok = not isinstance(value, bool) and isinstance(value, int) and value >= least
                expected = f"an integer ≥ {least}"
            elif f.name in _SHARES:
                ok, expected = is_number(value) and 0 <= value <= 1, "a share in [0, 1]"
            else:
                ok, expected = is_number(value) and 0 <= value < float("inf"), "a finite number ≥ 0"
            if not ok:
                raise option_error("sheet_settings", f"{f.name}: expected {expected}, got {value!r}")

    @classmethod
    def parse(cls, text: str) -> "SheetSettings":
        """The settings ``key=value`` pairs joined by ``:`` set (``jump=none``:
        no depth trim), the rest at their defaults: the command line's
        ``--sheet-settings`` and the benchmarks' settings."""
        given: dict = {}
        names = {f.name: f for f in fields(cls)}
        for item in filter(None, str(text).split(":")):
            key, _, value = item.partition("=")
            key = key.strip().replace("-", "_")
            if key not in names or not value:
                raise option_error(
                    "sheet_settings",
                    f"expected key=value pairs joined by ':', the keys {', '.join(names)}; got {item!r}",
                )
            try:
                given[key] = (
                    None if key == "jump" and value.lower() == "none" else int(value) if key in _INTS else float(value)
                )
            except ValueError:
                raise option_error("sheet_settings", f"{key}: expected a number, got {value!r}") from None
        return cls(**given)

    def changed(self) -> dict:
        """The fields that differ from their defaults."""
        return {f.name: getattr(self, f.name) for f in fields(self) if getattr(self, f.name) != f.default}

    def text(self) -> str:
        """The settings that differ from the defaults as :meth:`parse` reads them ("" for the defaults)."""
        return ":".join(f"{key}={'none' if value is None else value}" for key, value in self.changed().items())

    def __repr__(self) -> str:  # the settings that differ from the defaults, as they were given
        return f"SheetSettings({', '.join(f'{key}={value!r}' for key, value in self.changed().items())})"

    def replace(self, **changes: Any) -> "SheetSettings":
        return dataclasses.replace(self, **changes)
