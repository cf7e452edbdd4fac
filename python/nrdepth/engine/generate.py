"""Training clips: rendered videos of deforming surfaces and their depth videos.

Clip ``i`` is a pure function of ``(config, seed, i)`` (and the texture folder,
if one is given): the same bytes whatever the thread count, batch split or
``start``. A draw whose view window would show background in any frame (or,
in a backdrop clip, too little of the sheet) is redrawn deterministically;
``params[k]["redraws"]`` counts the rejected draws.
"""

from __future__ import annotations

import os
from dataclasses import asdict, dataclass, field, fields, replace
from typing import Any, Dict, List, NamedTuple, Optional, Tuple

import numpy as np

from .. import _core
from ..checks import check_int, check_seed, float_tuple
from .render import CAMERA_Z
from .surface import SurfaceConfig

__all__ = ["GeneratorConfig", "Clips", "generate_clips", "image_points", "observable_depth", "window_widths"]

_DEFAULT = _core.default_generator_config()
Interval = Tuple[float, float]

_RANGES = (
    "window_width",
    "window_offset",
    "light_azimuth",
    "light_elevation",
    "light_intensity",
    "point_light_distance",
    "ambient",
    "diffuse",
    "specular",
    "shininess",
    "noise_std",
    "blur",
    "gamma",
    "sheet_bend_angle",
    "sheet_bend_width",
    "sheet_fold_angle",
    "sheet_fold_width",
    "sheet_centre",
    "sheet_centre_drift",
    "sheet_axis_rate",
    "sheet_relief",
    "backdrop_window_width",
    "backdrop_window_offset",
    "backdrop_brightness",
    "camera_fov",
    "crop_share",
)
_INTS = ("frames", "size", "grid", "supersample", "texture_size", "max_redraws", "sheet_phases")


@dataclass(frozen=True)
class GeneratorConfig:
    """Everything a clip is drawn from. Units: world lengths in half-widths of
    the undeformed patch (the patch is [-1, 1]²), angles in radians, intensity
    in [0, 1] = black to white. (lo, hi) ranges are drawn uniformly, shininess
    log-uniformly. Construction validates every field and names a bad one."""

    frames: int = _DEFAULT["frames"]
    size: int = _DEFAULT["size"]
    """Image side H = W in pixels (up to 1024)."""
    grid: int = _DEFAULT["grid"]
    """Mesh vertices per side."""
    supersample: int = _DEFAULT["supersample"]
    """Subsamples per pixel side (anti-aliasing)."""
    surface: SurfaceConfig = field(default_factory=SurfaceConfig)
    window_width: Interval = _DEFAULT["window_width"]
    """Side of the square view window in world units."""
    window_offset: Interval = _DEFAULT["window_offset"]
    """Offset of the window centre from the patch centre (x and y each)."""
    light_count: Tuple[int, int] = _DEFAULT["light_count"]
    light_azimuth: Interval = _DEFAULT["light_azimuth"]
    """Azimuth of a light in image coordinates: 0 is image-up (toward row 0),
    +π/2 image-right. The default ±70° about image-up is a light-from-above
    prior: under an orthographic camera a relief and its mirror image under
    mirrored lights (azimuth + π) render identically, so only a prior that
    excludes the mirrored lights makes convex and concave distinguishable.
    ``(-math.pi, math.pi)`` draws uniformly (the sign is then unobservable)."""
    light_elevation: Interval = _DEFAULT["light_elevation"]
    """Elevation of a light above the surface plane."""
    light_intensity: Interval = _DEFAULT["light_intensity"]
    """Sum of the lights' intensities."""
    point_light_probability: float = _DEFAULT["point_light_probability"]
    point_light_distance: Interval = _DEFAULT["point_light_distance"]
    ambient: Interval = _DEFAULT["ambient"]
    diffuse: Interval = _DEFAULT["diffuse"]
    specular: Interval = _DEFAULT["specular"]
    shininess: Interval = _DEFAULT["shininess"]
    shading: str = _DEFAULT["shading"]
    """"phong" (lit per pixel with the interpolated normal) or "gouraud" (lit per vertex, interpolated)."""
    texture_families: Tuple[str, ...] = tuple(_DEFAULT["texture_families"])
    texture_size: int = _DEFAULT["texture_size"]
    noise_std: Interval = _DEFAULT["noise_std"]
    """Standard deviation of the additive Gaussian noise."""
    blur: Interval = _DEFAULT["blur"]
    """Standard deviation of the camera's Gaussian blur in pixels (0: none),
    applied to the rendered frame before the response and the noise."""
    gamma: Interval = _DEFAULT["gamma"]
    """Exponent of the camera's response ``v ↦ v**gamma`` (1: linear; a
    camera's encoded output is about ``v**0.45`` of the light it received).
    Blur and response are off by default (docs/findings.md measures
    ``blur=(0, 1.5)``, ``gamma=(0.4, 1.2)``)."""
    max_redraws: int = _DEFAULT["max_redraws"]
    sheet_probability: float = _DEFAULT["sheet_probability"]
    """Share of clips that are sheets: the patch bent isometrically (rolls,
    bends, folds about an axis that turns, their curvature changing over the
    clip), with the coloured-noise relief scaled by ``sheet_relief``. 0 (the
    default) keeps every clip as before. Each term ``j`` of the curvature
    across the axis turns the sheet by an angle (drawn at the clip's start
    and end from ``sheet_bend_angle`` / ``sheet_fold_angle``) spread over a
    Gaussian of width ``sheet_bend_width`` / ``sheet_fold_width`` about a
    centre (``sheet_centre``, moving by ``sheet_centre_drift``). Stretch
    under 0.5 % at the default mesh (``cargo test sheet``)."""
    sheet_bends: Tuple[int, int] = _DEFAULT["sheet_bends"]
    """Number of wide terms (bends and rolls) of a sheet, inclusive."""
    sheet_fold_probability: float = _DEFAULT["sheet_fold_probability"]
    """Probability that a sheet also has one narrow term (a fold)."""
    sheet_bend_angle: Interval = _DEFAULT["sheet_bend_angle"]
    sheet_bend_width: Interval = _DEFAULT["sheet_bend_width"]
    sheet_fold_angle: Interval = _DEFAULT["sheet_fold_angle"]
    sheet_fold_width: Interval = _DEFAULT["sheet_fold_width"]
    sheet_centre: Interval = _DEFAULT["sheet_centre"]
    sheet_centre_drift: Interval = _DEFAULT["sheet_centre_drift"]
    sheet_axis_rate: Interval = _DEFAULT["sheet_axis_rate"]
    """Change of the bend axis's in-plane angle over the clip (radians)."""
    sheet_relief: Interval = _DEFAULT["sheet_relief"]
    """Factor on the surface's coloured-noise intensity for a sheet."""
    sheet_phases: int = _DEFAULT["sheet_phases"]
    """Spans a sheet's clip is cut into, each bending it a new way: the
    angles at every span's end drawn afresh, the centres moved by a further
    ``sheet_centre_drift`` (kept inside ``sheet_centre``), the axis turned by
    a further ``sheet_axis_rate``, linear in between. 1 (the default) moves
    from the clip's start to its end; more suit long videos (the isometric
    shape needs a sheet bent many ways: docs/reconstruction.md)."""
    sheet_flat_start: bool = _DEFAULT["sheet_flat_start"]
    """Whether a sheet starts flat (every turn 0 at the clip's start, its
    relief aside), as a real video of paper often does; everything else is
    drawn as without it."""
    backdrop_probability: float = _DEFAULT["backdrop_probability"]
    """Share of clips whose view is wider than the sheet, so that its border
    shows and a background behind it: a window of side
    ``backdrop_window_width`` offset by ``backdrop_window_offset``, over a
    static background, flat (with ``backdrop_flat_probability``) or one of
    ``texture_families`` at one texel per pixel, scaled by
    ``backdrop_brightness``. Their depth is NaN off the sheet (the mask the
    losses and metrics use); a draw is redrawn until every frame has
    ``backdrop_min_cover`` of its pixels on the sheet. 0 (the default) keeps
    every clip as before."""
    backdrop_window_width: Interval = _DEFAULT["backdrop_window_width"]
    backdrop_window_offset: Interval = _DEFAULT["backdrop_window_offset"]
    backdrop_min_cover: float = _DEFAULT["backdrop_min_cover"]
    backdrop_brightness: Interval = _DEFAULT["backdrop_brightness"]
    backdrop_flat_probability: float = _DEFAULT["backdrop_flat_probability"]
    camera_fov: Interval = _DEFAULT["camera_fov"]
    """A perspective camera: the field of view (radians, up to 2.8) across the
    width of the frame a clip is cut from; the clip's window is
    ``crop_share`` of that width, at a uniform place in the frame, as a patch
    of a real frame is (share 1: the whole frame, as the coarse pass sees
    it). The pinhole sits at ``camera_z`` = half the frame's width over
    ``tan(fov / 2)`` above the plane z = 0, and depth is ``camera_z − z``
    along the optical axis (``params[k]["pinhole"]``). Under perspective a
    relief and its mirror image no longer render alike, and motion along the
    optical axis scales the image. A draw that brings the surface nearer the
    pinhole than half that distance is redrawn. (0, 0), the default, is the
    design's orthographic camera: every clip as before."""
    crop_share: Interval = _DEFAULT["crop_share"]
    camera_probability: float = _DEFAULT["camera_probability"]
    """With ``camera_fov``: the share of clips seen through the pinhole; the
    others are orthographic. It is drawn after the pinhole, so the clips
    seen through it are those a share of 1 (the default) draws."""
    textures: Optional[str] = None
    """A folder of PNG/JPEG images to crop textures from instead of the procedural families."""

    def __post_init__(self) -> None:
        for name in _INTS:
            object.__setattr__(self, name, check_int(f"config.{name}", getattr(self, name)))
        for name in _RANGES:
            object.__setattr__(self, name, float_tuple(f"config.{name}", getattr(self, name), 2))
        lo, hi = float_tuple("config.light_count", self.light_count, 2)
        if lo != int(lo) or hi != int(hi):
            raise ValueError(f"config.light_count: expected two integers, got {self.light_count}")
        object.__setattr__(self, "light_count", (int(lo), int(hi)))
        lo, hi = float_tuple("config.sheet_bends", self.sheet_bends, 2)
        if lo != int(lo) or hi != int(hi):
            raise ValueError(f"config.sheet_bends: expected two integers, got {self.sheet_bends}")
        object.__setattr__(self, "sheet_bends", (int(lo), int(hi)))
        if not isinstance(self.sheet_flat_start, bool):
            raise TypeError(f"config.sheet_flat_start: expected a bool, got {type(self.sheet_flat_start).__name__}")
        if not isinstance(self.surface, SurfaceConfig):
            raise TypeError(f"config.surface: expected a SurfaceConfig, got {type(self.surface).__name__}")
        if isinstance(self.texture_families, str):
            raise TypeError("config.texture_families: expected a sequence of family names, got a str")
        object.__setattr__(self, "texture_families", tuple(self.texture_families))
        if self.textures is not None:
            path = os.fspath(self.textures)
            if not os.path.isdir(path):
                raise ValueError(f"config.textures: not a folder: {path}")
            object.__setattr__(self, "textures", path)
        _core.validate_generator_config(self._core_dict())

    def _core_dict(self) -> Dict[str, Any]:
        d = {f.name: getattr(self, f.name) for f in fields(self) if f.name not in ("surface", "textures")}
        d["surface"] = self.surface.as_dict()
        d["texture_families"] = list(self.texture_families)
        return d

    def as_dict(self) -> Dict[str, Any]:
        """JSON-serialisable dict of every field."""
        d = asdict(self)
        d["surface"] = self.surface.as_dict()
        return d

    @classmethod
    def from_dict(cls, d: Dict[str, Any]) -> "GeneratorConfig":
        d = dict(d)
        surface = SurfaceConfig(**d.pop("surface", {}))
        return cls(surface=surface, **d)

    def replace(self, **changes: Any) -> "GeneratorConfig":
        return replace(self, **changes)


class Clips(NamedTuple):
    video: np.ndarray
    """uint8 (n, T, H, W) rendered grayscale frames."""
    depth: np.ndarray
    """float32 (n, T, H, W) depth ``camera_z − z`` at pixel centres; NaN off
    the sheet in a backdrop clip (``backdrop_probability``), never otherwise."""
    params: List[Dict[str, Any]]
    """Per clip: surface, window, lights, material, texture, noise_std, noise_seed, blur, gamma, sheet (None, or its axis, terms and relief), backdrop (None, or
    its background's family (None: flat), seed and brightness), pinhole (None: orthographic, or its ``xy`` and ``camera_z``), redraws."""
    vertices: Optional[np.ndarray] = None
    """With ``generate_clips(…, vertices=True)``: float32 (n, T, grid, grid, 3)
    each clip's mesh in world coordinates, frame by frame; vertex ``[j, k]``
    is the same point of the surface in every frame, at ``x = −1 + 2k/(grid − 1)``,
    ``y = −1 + 2j/(grid − 1)`` before it deforms. Else None."""


def generate_clips(n: int, seed: int = 0, config: Optional[GeneratorConfig] = None, start: int = 0,
                   vertices: bool = False) -> Clips:
    """Generate clips ``start .. start + n`` of the run ``(config, seed)``, in
    parallel (Rust threads, GIL released). Safe in forked DataLoader workers.
    ``vertices``: also return each clip's mesh (``Clips.vertices``; with
    :func:`image_points`, ground-truth tracks of every point of the surface)."""
    config = GeneratorConfig() if config is None else config
    if not isinstance(config, GeneratorConfig):
        raise TypeError(f"config: expected a GeneratorConfig or None, got {type(config).__name__}")
    n = check_int("n", n)
    if n < 0:
        raise ValueError(f"n: expected a non-negative number of clips, got {n}")
    start = check_seed("start", start)
    if not isinstance(vertices, bool):
        raise TypeError(f"vertices: expected a bool, got {type(vertices).__name__}")
    return Clips(*_core.generate_clips(n, check_seed("seed", seed), start, config._core_dict(), config.textures, vertices))


def image_points(vertices: np.ndarray, params: Dict[str, Any], size: int) -> np.ndarray:
    """Where world points ``vertices`` (..., 3) appear in a clip's frames of
    ``size`` pixels (``params`` one of ``Clips.params``): float64 (..., 3)
    of column, row (pixel centres at integers, as :mod:`nrdepth.isometric`
    counts them) and depth (distance along the optical axis, as
    ``Clips.depth``), through the clip's pinhole or its orthographic camera.
    Visibility is not checked: a point behind a fold projects all the same."""
    vertices = np.asarray(vertices, np.float64)
    if vertices.ndim < 1 or vertices.shape[-1] != 3:
        raise ValueError(f"vertices: expected points (..., 3), got shape {vertices.shape}")
    size = check_int("size", size)
    if size < 1:
        raise ValueError(f"size: expected the frames' side in pixels >= 1, got {size}")
    if not (isinstance(params, dict) and np.shape(params.get("window")) == (4,)):
        raise ValueError("params: expected one of Clips.params (a dict with its clip's window and pinhole)")
    x0, y0, x1, y1 = params["window"]
    x, y, z = np.moveaxis(vertices, -1, 0)
    pinhole = params.get("pinhole")
    if pinhole is None:
        depth, (cx, cy), k = CAMERA_Z - z, (x0, y0), 1.0
    else:  # the perspective camera's window is what it shows of the plane z = 0
        (cx, cy), camera_z = pinhole["xy"], pinhole["camera_z"]
        depth = camera_z - z
        k = camera_z / depth
    column = (cx + (x - cx) * k - x0) * size / (x1 - x0) - 0.5
    row = (y1 - cy - (y - cy) * k) * size / (y1 - y0) - 0.5
    return np.stack([column, row, depth], axis=-1)


def observable_depth(depth: np.ndarray, params: Dict[str, Any]) -> np.ndarray:
    """A clip's depth (T, H, W) without what its video cannot show: the
    surface's translation along the optical axis, ``t · drift_z`` at frame
    ``t = k / (T − 1)`` (``params["surface"]["drift"][2]``, ``params`` one of
    ``Clips.params``). Under the orthographic camera, moving the surface along
    z changes no pixel under directional lights (and barely any under the
    generator's distant point lights), so no network can predict it; a
    training target without it asks only for what the frames hold
    (``nrdepth train --target observable``). A clip seen through a pinhole
    (``camera_fov``) shows that motion, as its image grows or shrinks, so its
    depth is returned as it is."""
    depth = np.asarray(depth)
    if depth.ndim != 3:
        raise ValueError(f"depth: expected one clip's (T, H, W) depth, got shape {depth.shape}")
    if params.get("pinhole") is not None:
        return depth
    drift_z = float(params["surface"]["drift"][2])
    t = np.linspace(0.0, 1.0, depth.shape[0]) if depth.shape[0] > 1 else np.zeros(1)
    # depth = camera_z − z and z grows by t · drift_z: adding it back removes the motion.
    return (depth + (drift_z * t)[:, None, None]).astype(depth.dtype)


def window_widths(params: list) -> np.ndarray:
    """The view window's side in world units of each clip of ``params`` (a
    list of ``Clips.params`` entries): float32 (B,)."""
    return np.array([p["window"][2] - p["window"][0] for p in params], dtype=np.float32)
