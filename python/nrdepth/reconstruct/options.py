"""The main job's options: one frozen dataclass, defined, defaulted,
documented and checked here.

:func:`~nrdepth.reconstruct` and :func:`~nrdepth.reconstruct_file` take an
:class:`ReconstructOptions` and/or its fields as keywords; ``nrdepth reconstruct``
builds its flags from the fields (:func:`add_flags`). Adding an option
touches its field here and the stage that uses it.

An error names the option the user set: the exception carries it as
``error.option`` (:func:`~nrdepth.checks.option_error`), so the command
line names its flag without reading the message.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
from dataclasses import dataclass, field, fields
from typing import Any, Dict, Optional, Tuple, Union

import numpy as np

from ..camera import GUESSED_VIEW, Camera
from ..checks import is_number, option_error
from ..isometric import DROP, EACH_FRAME, TEMPLATES
from .fine import check_tile
from .sheet.settings import ISOMETRIC_EACH_FRAME, SheetSettings
from .network import PRECISIONS
from .stitch import ALIGNMENTS, COARSE_WEIGHT, TEMPORAL_WEIGHT, WINDOWS, check_stitching

__all__ = ["ReconstructOptions", "SheetSettings", "MAX_SIDE", "FINE_PASSES", "STAGE_TEMPLATES", "ISOMETRIC_DROP", "ISOMETRIC_HOLD", "ISOMETRIC_EACH_FRAME", "UNITS", "PRECISIONS", "add_flags", "options_from_flags"]

MAX_SIDE = 480
"""Default working resolution: a frame's longer side, in pixels. The real
cloth (filmed at 1920×1080) reads best here and the real paper the same at
384 and 528 (docs/reconstruction.md#working-resolution)."""
FINE_PASSES = ("field", "patches")
"""The fine passes, the default first (:mod:`nrdepth.reconstruct.fine`)."""
UNITS = ("standard", "pixels")
STAGE_TEMPLATES = ("auto",) + TEMPLATES
"""The sheet stage's templates: "auto" (the held points through
``refined`` where their pairs keep their lengths, the joint template
otherwise: :func:`~nrdepth.reconstruct.sheet.sheet_depth`), or one of
:data:`nrdepth.isometric.TEMPLATES` alone."""
ISOMETRIC_DROP = DROP
"""With a camera's focal length, the share of the tracked points left out
(:data:`nrdepth.isometric.DROP`)."""

ISOMETRIC_HOLD = False
"""With a camera's focal length, whether the sheet's points are held to
their look in the first frame (:func:`nrdepth.isometric.track_points`'
``hold``). Off: with the warp fitted to the points held, it passed its
rule on 32 fresh relief-free paper-like sheets (−0.0170 ± 0.0040 per
frame against the chained flow), but over ``kinect_paper``'s whole-sheet
box, half background, it steps aside (0.57 of the point-frames held)
and reads the sheet 11 % worse than the flow's tracks, which the rule's
checks forbid; on ``kinect_paper``'s true points the tracks' 95th
percentile falls from 1.86 to 0.65 px (docs/campaign.md, "Held points
on a warp fitted to the points held")."""

def _option(default: Any, help: str, flag: Optional[str] = None, **argparse_kwargs: Any) -> Any:
    """A field of :class:`ReconstructOptions`: its default, its help (the API's and the
    command line's), and how ``nrdepth reconstruct`` takes it (``flag``:
    its name there, ``None``: the field's name with dashes; ``""``: none)."""
    return field(default=default, metadata={"help": help, "flag": flag, "argparse": argparse_kwargs})


def _parse_ints(what: str, count: int):
    def parse(text: str) -> Tuple[int, ...]:
        try:
            values = tuple(int(v) for v in text.split(","))
        except ValueError:
            values = ()
        if len(values) != count:
            raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}")
        return values

    return parse


def _parse_numbers(what: str, counts: Tuple[int, ...]):
    def parse(text: str) -> Union[float, Tuple[float, ...]]:
        try:
            values = tuple(float(v) for v in text.split(","))
        except ValueError:
            values = ()
        if len(values) not in counts:
            raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}")
        return values[0] if len(values) == 1 else values

    return parse


def _parse_frames(text: str) -> slice:
    try:
        parts = [int(v) if v else None for v in text.split(":")]
        if not 2 <= len(parts) <= 3:
            raise ValueError
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected START:STOP[:STEP] (Python slice), got {text!r}") from None
    return slice(*parts)


def _parse_side(text: str) -> Optional[int]:
    try:
        side = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
    return side or None


_ROI = _parse_ints("X,Y,W,H in pixels", 4)


@dataclass(frozen=True, eq=False)
class ReconstructOptions:
    """How :func:`~nrdepth.reconstruct` and :func:`~nrdepth.reconstruct_file`
    reconstruct a video. Every field is checked when the options are made;
    what depends on the video (a region inside its frame, a mask of its
    size) is checked when it is read. The fields:
    """

    # What to reconstruct.
    roi: Optional[Tuple[int, int, int, int]] = _option(None, "the region X,Y,W,H in pixels of the video's frames", type=_ROI, metavar="X,Y,W,H")
    frames: Optional[slice] = _option(None, "the frames START:STOP[:STEP] (a Python slice)", type=_parse_frames, metavar="A:B[:S]")
    max_side: Optional[int] = _option(
        MAX_SIDE, "reconstruct at a working size whose longer side is at most this many pixels, the depth resized back; None (0 on the "
        "command line): the video's own size (the network reads relief at the scale of 64-pixel patches; docs/reconstruction.md)", type=_parse_side, metavar="N")
    mask: Union[None, np.ndarray, str, "os.PathLike[str]"] = _option(
        None, "the surface's pixels: bool (H, W) or (T, H, W) of the video as given, or (reconstruct_file, the command line) a file: one image "
        "for every frame, or a video, image folder or .npy of the input's frames, white (128 or more of 255) on the surface. Off it the depth "
        "is NaN (black in the videos, 0 in the PNGs, no PLY point, a hole in the viewer) and takes no part in the alignments: for a "
        "background that moves on its own")
    # The network.
    device: str = _option("auto", "auto | cpu | cuda | cuda:N")
    precision: str = _option(PRECISIONS[0], "the fine pass's arithmetic: auto (bfloat16 autocast on CUDA and on CPUs that compute it, "
                             "AVX512-BF16 or AMX: half the network's time on two cores, generated and real videos read as in float32 to the "
                             "fourth decimal; float32 elsewhere), float32 or bfloat16 (docs/reconstruction.md)", choices=PRECISIONS)
    batch_size: int = _option(8, "clips per network call in the coarse pass (and with fine='patches')", type=int)
    fine: str = _option(FINE_PASSES[0], "the fine pass: field (the network once over the video, in tiles) or patches (every 64×64×16 "
                        "window on its own, as the paper: 8× the work)", choices=FINE_PASSES)
    tile: Optional[Tuple[int, int, int]] = _option(None, "the field pass's tile core (frames, rows, columns; rows and columns multiples "
                                                   "of 8); None: (32, 320, 320) on the CPU, (64, 512, 512) on CUDA", flag="")
    units: str = _option(UNITS[0], "the depth's scale: standard (unit standard deviation over the video) or pixels (the relief's scale as a "
                         "model trained with --amplitude reads it; without a model, the shipped one that learnt it)", choices=UNITS)
    # The stitch.
    alignment: str = _option(ALIGNMENTS[0], "how the windows are aligned: joint (all together, agreeing where they overlap, tied to the coarse "
                             "pass by coarse_weight) or coarse (each on its own to the coarse pass, as the paper)", choices=ALIGNMENTS)
    coarse_weight: float = _option(COARSE_WEIGHT, "the joint alignment's weight on the coarse pass (smaller trusts the windows' agreement more)",
                                   type=float)
    temporal_weight: float = _option(TEMPORAL_WEIGHT, "the joint alignment's tie of each window's GBR to the frame before, as much as the "
                                     "window holds still (0: frames on their own)", type=float)
    window: str = _option(WINDOWS[0], "the overlap-add window: hann (no seams) or triangle (the paper's; the paper's stitch is "
                          "alignment coarse, window triangle)", choices=WINDOWS)
    temporal: bool = _option(False, "give every frame frame 0's plane and relief norm (nrdepth.temporal_align): for models trained with "
                             "per-frame losses only", flag="--temporal-align", action="store_true")
    # A sheet: its shape from inextensibility.
    sheet_stage: bool = _option(
        True, "the sheet stage (nrdepth.reconstruct.sheet). With neither focal nor sheet given, on a video of at least 32 frames: points over "
        f"the roi (the whole frame without one) are held to their look in the first frame and seen through a pinhole guessed to see {GUESSED_VIEW:g}°; "
        "of those held in every frame, the ones that move and whose pairs keep their lengths are taken for the sheet's, and where enough are "
        "left, their strain picks out a focal length and stays small, the shape of a sheet (paper, cloth) comes from inextensibility, "
        "through the focal length the strain picks where it lies well inside the range tried (else through the guess); "
        "elsewhere the network's depth stays (the log line and depth.npz's sheet say which, and why). Off (--no-sheet): the network's depth alone",
        flag="--no-sheet", action="store_false")
    focal: Union[None, float, Tuple[float, float], Camera] = _option(
        None, "for a sheet (paper, cloth) filmed by a perspective camera: its focal length in pixels of the video's frames, F or FX,FY "
        "(or a nrdepth.Camera, whose principal point comes with it). The "
        "shape above isometric_scale then comes from inextensibility (points followed over the sheet; nrdepth.isometric), "
        "the relief below it from the network, and on a long video that bends the sheet many ways the relief's sign too (a short clip reads "
        f"as a dome). Without it, a sheet given (sheet) is seen through a pinhole guessed to see {GUESSED_VIEW:g}° across the frame's longer "
        "side (nrdepth.Camera.guessed). The sheet stage holds two frames at a time; on kinect_paper's 191 frames of 640×480 it "
        "costs about 28 s on two threads (docs/reconstruction.md)", type=_parse_numbers("F or FX,FY in pixels", (1, 2)), metavar="F[,FY]")
    centre: Optional[Tuple[float, float]] = _option(None, "the sheet stage's camera: the principal point in the video's frames (default: their centre)",
                                                    type=_parse_numbers("CX,CY in pixels", (2,)), metavar="CX,CY")
    sheet: Union[None, np.ndarray, Tuple[int, int, int, int]] = _option(
        None, "a sheet (paper, cloth) in the video, whose shape then comes from inextensibility as with focal (without focal, through a "
        "guessed pinhole): where the points are spread in the first selected frame, on the sheet only (not the background or the hands): a "
        "box X,Y,W,H in the video's pixels, or bool (H, W). With focal and no sheet, the sheet is first looked for over the roi (the whole "
        "frame without one) as with neither given, then the roi is read as the sheet", type=_ROI, metavar="X,Y,W,H")
    isometric_scale: Optional[float] = _option(None, "the sheet stage: the length below which the network's relief is kept, as a fraction of the "
                                               "frame's shorter side (0: the isometric depth alone; default: sheet_settings' refined_scale, "
                                               f"{SheetSettings.refined_scale}, through the held points' refined template, its joint_scale, "
                                               f"{SheetSettings.joint_scale}, through the others)", type=float)
    isometric_template: str = _option(STAGE_TEMPLATES[0], "the sheet stage: the pairs' template distances (nrdepth.isometric.mdh_depths): auto (points "
                                      "held to the first frame through refined where their pairs keep their lengths; with focal or sheet given, the joint "
                                      "template otherwise), joint, "
                                      "refined (each pair held to its distance in every keyframe), first (the first frame a flat sheet facing the camera)",
                                      choices=STAGE_TEMPLATES)
    isometric_each_frame: str = _option(ISOMETRIC_EACH_FRAME, "the sheet stage: each frame's depths (nrdepth.isometric.mdh_depths' each_frame): program "
                                        "(the maximum-depth program's), lengths (refined so that each pair keeps its template distance: every frame, or none where one "
                                        "would change its shape), "
                                        "mirror (the same, from the program's answer or its mirror, whichever keeps the lengths better)",
                                        choices=EACH_FRAME)
    isometric_drop: float = _option(ISOMETRIC_DROP, "the sheet stage: the share of the points left out where the flow's two directions disagree most",
                                    type=float)
    isometric_hold: bool = _option(ISOMETRIC_HOLD, "the sheet stage: each point found again after every step of the flow by its look in the "
                                   "first frame, lost (not dragged) where it is not (nrdepth.isometric.track_points' hold); the stage then "
                                   "reads only the points held in at least 0.8 of their frames, and steps aside where too few are held; with the template auto and "
                                   "focal or sheet given, the points read through the joint template where the held points through refined give way",
                                   action="store_true")
    isometric_points: int = _option(400, "the sheet stage: about how many points are followed over the sheet (a square grid)", type=int)
    sheet_settings: SheetSettings = _option(
        SheetSettings(), "the sheet stage's tunable values (nrdepth.reconstruct.sheet.SheetSettings: its thresholds, keyframes, scales), each "
        "chosen by a rule on generated sheets (docs/sheet-stage.md); on the command line KEY=VALUE pairs joined by ':' "
        "(min_contrast=1.5:read_smooth=0), the rest at their defaults", type=SheetSettings.parse, metavar="KEY=VALUE[:...]")
    # The outputs.
    flip: bool = _option(False, "negate the depth: the other convex/concave reading (the model assumes light from above; use it for a video "
                         "lit from below)", action="store_true")
    png16: bool = _option(False, "reconstruct_file: also write 16-bit PNG depth frames (0: no depth; 1 … 65535 span depth.npz's png16_range)",
                          action="store_true")
    ply: bool = _option(False, "reconstruct_file: also write a PLY point cloud per frame", action="store_true")
    ply_relief: Optional[float] = _option(None, "reconstruct_file: the PLYs' depth standard deviation in frame widths (default: 0.073, as the "
                                          "training surfaces; one frame width per pixel with units pixels)", type=float)
    viewer: bool = _option(True, "reconstruct_file: write viewer.html, the 3-D page of the depth video (off: nrdepth view OUT writes it later)",
                           flag="--no-viewer", action="store_false")
    overwrite: bool = _option(False, "reconstruct_file: replace the output folder if it exists", action="store_true")

    def __post_init__(self) -> None:
        _check(self)

    @property
    def sheet_given(self) -> bool:
        """Whether the user asked for the sheet's shape: ``focal`` or ``sheet`` given."""
        return self.focal is not None or self.sheet is not None

    @property
    def sheet_mode(self) -> bool:
        """Whether the sheet stage runs: ``focal`` or ``sheet`` given, or by
        default (``sheet_stage``) where its shape can join the depth (``units``
        standard, ``temporal`` off)."""
        return self.sheet_given or (self.sheet_stage and self.units == "standard" and not self.temporal)

    def sheet_camera(self, frame: Tuple[int, int]) -> Camera:
        """The sheet's camera for the video's frames of ``frame`` (H, W): ``focal`` and
        ``centre``, or without ``focal`` a guessed one (:meth:`~nrdepth.Camera.guessed`)."""
        return Camera.guessed(frame, self.centre) if self.focal is None else Camera(self.focal, self.centre).at(frame)

    @classmethod
    def of(cls, options: Optional["ReconstructOptions"] = None, **settings: Any) -> "ReconstructOptions":
        """``options`` (default: the defaults) with the fields in ``settings`` replaced; TypeError naming an unknown one."""
        if options is not None and not isinstance(options, cls):
            raise TypeError(f"options: expected nrdepth.ReconstructOptions or None, got {type(options).__name__}")
        names = {f.name for f in fields(cls)}
        for name in settings:
            if name not in names:
                raise TypeError(f"{name}: not an option of the main job; the options are nrdepth.ReconstructOptions' fields: {', '.join(sorted(names))}")
        return dataclasses.replace(options or cls(), **settings)

    def changed(self) -> Dict[str, Any]:
        """The fields that differ from their defaults."""
        return {f.name: getattr(self, f.name) for f in fields(self) if _differs(getattr(self, f.name), f.default)}


def _differs(value: Any, default: Any) -> bool:
    return value is not default and (isinstance(value, np.ndarray) or value != default)


_DEFAULTS = {f.name: f.default for f in fields(ReconstructOptions)}
FILE_ONLY = ("png16", "ply", "ply_relief", "viewer", "overwrite")
"""The options that say what :func:`~nrdepth.reconstruct_file` writes."""


def _check(o: ReconstructOptions) -> None:
    """Every check of :class:`ReconstructOptions` that needs no video, in field order; normalises tuples in place."""
    set_ = lambda name, value: object.__setattr__(o, name, value)  # noqa: E731  (a frozen dataclass normalises in __post_init__)
    if o.roi is not None:
        try:
            set_("roi", tuple(int(v) for v in o.roi if not isinstance(v, bool) and float(v) == int(v)))
            if len(o.roi) != 4:
                raise ValueError
        except (TypeError, ValueError):
            raise option_error("roi", f"expected four integers (x, y, width, height), got {o.roi!r}") from None
    if o.frames is not None:
        if not isinstance(o.frames, slice):
            raise option_error("frames", f"expected a slice, got {type(o.frames).__name__}", TypeError)
        if o.frames.step is not None and o.frames.step <= 0:
            raise option_error("frames", f"expected a positive step, got {o.frames.step}")
    if o.max_side is not None and (isinstance(o.max_side, bool) or not isinstance(o.max_side, (int, np.integer)) or o.max_side < 8):
        raise option_error("max_side", f"expected an integer ≥ 8, or None (0 on the command line) for the video's own size, got {o.max_side!r}")
    if o.mask is not None and not isinstance(o.mask, (str, os.PathLike)):
        mask = np.asarray(o.mask)
        if mask.dtype != bool:
            raise option_error("mask", f"expected a bool array (True on the surface), got dtype {mask.dtype}", TypeError)
    if not isinstance(o.device, str):
        raise option_error("device", f"expected 'auto', 'cpu', 'cuda' or 'cuda:N', got {o.device!r}", TypeError)
    if isinstance(o.batch_size, bool) or not isinstance(o.batch_size, (int, np.integer)) or o.batch_size < 1:
        raise option_error("batch_size", f"expected a positive integer, got {o.batch_size!r}")
    if o.units not in UNITS:
        raise option_error("units", f"expected 'standard' or 'pixels', got {o.units!r}")
    if o.fine not in FINE_PASSES:
        raise option_error("fine", f"expected one of {FINE_PASSES}, got {o.fine!r}")
    if o.precision not in PRECISIONS:
        raise option_error("precision", f"expected one of {PRECISIONS}, got {o.precision!r}")
    if o.tile is not None:
        set_("tile", check_tile(o.tile))
    check_stitching(o.alignment, o.coarse_weight, o.window, o.temporal_weight)
    _check_sheet(o)
    if o.mask is not None:
        if o.alignment != "joint":
            raise option_error("mask", "the paper's alignment fits every pixel of a patch, padding included; use alignment='joint'")
        if o.temporal or o.units != "standard":
            raise option_error("mask", "works with temporal=False and units='standard'")
    if o.ply_relief is not None and not (is_number(o.ply_relief) and 0 < o.ply_relief < math.inf):
        raise option_error("ply_relief", f"expected a positive finite number, got {o.ply_relief!r}")


STAGE_OPTIONS = ("centre", "isometric_scale", "isometric_template", "isometric_each_frame", "isometric_drop", "isometric_points", "isometric_hold",
                 "sheet_settings")
"""The sheet stage's options beside ``focal`` and ``sheet``: they shape its reading, and act only where it runs."""


def _check_sheet(o: ReconstructOptions) -> None:
    if isinstance(o.sheet_settings, str):  # as the command line writes it
        object.__setattr__(o, "sheet_settings", SheetSettings.parse(o.sheet_settings))
    if not isinstance(o.sheet_settings, SheetSettings):
        raise option_error("sheet_settings", f"expected a nrdepth.SheetSettings, got {type(o.sheet_settings).__name__}", TypeError)
    if not isinstance(o.sheet_stage, (bool, np.bool_)):
        raise option_error("sheet_stage", f"expected a bool, got {o.sheet_stage!r}", TypeError)
    if o.sheet_given and not o.sheet_stage:
        raise option_error("sheet_stage", f"the sheet stage is off, yet {'focal' if o.focal is not None else 'sheet'} asks for the sheet's shape")
    if not o.sheet_mode:
        given = [name for name in STAGE_OPTIONS if _differs(getattr(o, name), _DEFAULTS[name])]
        if given and not o.sheet_stage:
            raise option_error("sheet_stage", f"the sheet stage is off, yet its options are set ({', '.join(given)})")
        if given:
            raise option_error(given[0], "the sheet stage, whose option this is, runs with units='standard' and temporal off only")
        return
    if isinstance(o.focal, Camera):  # a camera as itself: its focal length, and its principal point unless centre says otherwise
        camera = o.focal
        object.__setattr__(o, "focal", camera.focal)
        object.__setattr__(o, "centre", o.centre if o.centre is not None else camera.centre)
    Camera(1.0 if o.focal is None else o.focal, o.centre)  # raises naming focal or centre (a guessed focal length: the centre alone)
    if o.isometric_scale is not None and not (is_number(o.isometric_scale) and np.isfinite(o.isometric_scale) and o.isometric_scale >= 0):
        raise option_error("isometric_scale", f"expected a fraction of the frame's shorter side >= 0, got {o.isometric_scale!r}")
    if o.units != "standard" or o.temporal:  # given: the default stage steps aside here (sheet_mode)
        raise option_error("focal" if o.focal is not None else "sheet", "the isometric shape comes with units='standard' and temporal off only")
    if o.isometric_template not in STAGE_TEMPLATES:
        raise option_error("isometric_template", f"expected one of {STAGE_TEMPLATES}, got {o.isometric_template!r}")
    if o.isometric_each_frame not in EACH_FRAME:
        raise option_error("isometric_each_frame", f"expected one of {EACH_FRAME}, got {o.isometric_each_frame!r}")
    if not (is_number(o.isometric_drop) and 0 <= o.isometric_drop < 1):
        raise option_error("isometric_drop", f"expected a share of the points in [0, 1), got {o.isometric_drop!r}")
    if isinstance(o.isometric_points, bool) or not isinstance(o.isometric_points, (int, np.integer)) or o.isometric_points < 4:
        raise option_error("isometric_points", f"expected an integer ≥ 4, got {o.isometric_points!r}")
    if not isinstance(o.isometric_hold, (bool, np.bool_)):
        raise option_error("isometric_hold", f"expected a bool, got {o.isometric_hold!r}", TypeError)


def flag_of(name: str) -> str:
    """The command line's flag of option ``name`` (``--roi``; ``--no-viewer`` for ``viewer``); ``--name`` for a name that is no field."""
    meta = {f.name: f.metadata for f in fields(ReconstructOptions)}.get(name, {})
    return meta.get("flag") or f"--{name.replace('_', '-')}"


def add_flags(parser: argparse.ArgumentParser, leave_out: Tuple[str, ...] = ()) -> None:
    """``nrdepth reconstruct``'s flags, one per field of :class:`ReconstructOptions` that has one (but ``leave_out``), with its help."""
    for f in fields(ReconstructOptions):
        if f.metadata.get("flag") == "" or f.name in leave_out:
            continue
        parser.add_argument(flag_of(f.name), dest=f.name, default=f.default, help=f.metadata["help"], **f.metadata["argparse"])


def options_from_flags(args: argparse.Namespace) -> ReconstructOptions:
    """The :class:`ReconstructOptions` of parsed ``nrdepth reconstruct`` flags (a field without its flag keeps its default)."""
    return ReconstructOptions.of(**{f.name: getattr(args, f.name) for f in fields(ReconstructOptions) if f.metadata.get("flag") != "" and hasattr(args, f.name)})


ReconstructOptions.__doc__ = (ReconstructOptions.__doc__ or "") + "".join(
    f"\n    - ``{f.name}`` (default ``{'None' if f.default is None else repr(f.default)}``): {f.metadata['help']}." for f in fields(ReconstructOptions)
)
