"""Rendering and ray casting of any triangle mesh (Rust core, parallel, GIL released).

Conventions: world x right, y up, z toward the camera. The camera is
orthographic and looks down −z from the plane ``z = camera_z``; depth is
``camera_z − z``. With a ``pinhole`` (x, y) it is a perspective camera at
(x, y, ``camera_z``) instead, and the window is what it shows of the plane
z = 0; depth is still ``camera_z − z``, along the optical axis. An (H, W) image covers ``window = (xmin, ymin, xmax, ymax)``;
pixel (i, j) has its centre at ``x = xmin + (j + ½)(xmax − xmin)/W``,
``y = ymax − (i + ½)(ymax − ymin)/H`` (row 0 at the top). Texture coordinates
``(u, v)`` in [0, 1]: u along texture columns, v along rows (row 0 at v = 0).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any, NamedTuple, Optional, Sequence, Tuple

import numpy as np

from .. import _core
from ..checks import check_int, check_seed, float_tuple

__all__ = [
    "CAMERA_Z",
    "Light",
    "Material",
    "Render",
    "render",
    "raycast_depth",
    "procedural_texture",
    "TEXTURE_FAMILIES",
]

CAMERA_Z: float = float(_core.CAMERA_Z)
"""Default camera plane: the undeformed patch (z = 0) lies 2 units in front of it."""

TEXTURE_FAMILIES: Tuple[str, ...] = tuple(_core.texture_families())
"""Procedural texture families: fractal, stripes, plaid, cells, weave."""


@dataclass(frozen=True)
class Light:
    """A light. ``kind="directional"``: ``vector`` points toward the light;
    ``kind="point"``: ``vector`` is its position (no distance fall-off)."""

    kind: str = "directional"
    vector: Tuple[float, float, float] = (0.0, 0.0, 1.0)
    intensity: float = 1.0

    def __post_init__(self) -> None:
        if self.kind not in ("directional", "point"):
            raise ValueError(f"light.kind: expected 'directional' or 'point', got {self.kind!r}")
        object.__setattr__(self, "vector", float_tuple("light.vector", self.vector, 3))
        object.__setattr__(self, "intensity", float_tuple("light.intensity", (self.intensity,), 1)[0])


@dataclass(frozen=True)
class Material:
    """Phong coefficients: ``I = k_a ρ + Σ I_l (k_d ρ max(0, n·l) + k_s max(0, r·v)^α)``."""

    ambient: float = 0.1
    diffuse: float = 0.8
    specular: float = 0.2
    shininess: float = 20.0

    def __post_init__(self) -> None:
        for name in ("ambient", "diffuse", "specular", "shininess"):
            object.__setattr__(self, name, float_tuple(f"material.{name}", (getattr(self, name),), 1)[0])


class Render(NamedTuple):
    image: np.ndarray
    """float32 (H, W) shaded intensity; background contributes 0."""
    coverage: np.ndarray
    """float32 (H, W) fraction of each pixel's subsamples that hit the mesh."""
    depth: np.ndarray
    """float32 (H, W) depth ``camera_z − z`` of the highest hit at each pixel
    centre, NaN on background: ``raycast_depth``'s, bit for bit when
    ``supersample`` is a power of two."""


def _float_array(name: str, a: Any, columns: Optional[int], ndim: int = 2) -> np.ndarray:
    arr = np.asarray(a)
    if arr.dtype.kind != "f":
        raise TypeError(f"{name}: expected a floating-point array, got dtype {arr.dtype}")
    if arr.ndim != ndim or (columns is not None and arr.shape[-1] != columns):
        want = f"(n, {columns})" if columns is not None else f"{ndim} dimensions"
        raise ValueError(f"{name}: expected shape {want}, got {arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError(f"{name}: expected finite values (found NaN or inf)")
    return np.ascontiguousarray(arr, dtype=np.float32)


def _index_array(name: str, a: Any) -> np.ndarray:
    arr = np.asarray(a)
    if arr.dtype.kind not in "iu":
        raise TypeError(f"{name}: expected an integer array, got dtype {arr.dtype}")
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise ValueError(f"{name}: expected shape (F, 3), got {arr.shape}")
    if arr.size and (arr.min() < 0 or arr.max() >= 2**32):
        raise ValueError(f"{name}: indices must lie in [0, 2**32), got [{arr.min()}, {arr.max()}]")
    return np.ascontiguousarray(arr, dtype=np.uint32)


def _size(size: Any) -> Tuple[int, int]:
    if isinstance(size, (int, np.integer)) and not isinstance(size, bool):
        size = (size, size)
    try:
        h, w = size
    except (TypeError, ValueError):
        raise TypeError(f"size: expected (H, W) or an int, got {size!r}") from None
    return check_int("size", h), check_int("size", w)


def _window(window: Any) -> Tuple[float, float, float, float]:
    return float_tuple("window", window, 4)  # type: ignore[return-value]


def _pinhole(pinhole: Any) -> Optional[Tuple[float, float]]:
    return None if pinhole is None else float_tuple("pinhole", pinhole, 2)  # type: ignore[return-value]


def render(
    vertices: np.ndarray,
    triangles: np.ndarray,
    uv: np.ndarray,
    texture: np.ndarray,
    size: Any,
    window: Sequence[float],
    lights: Optional[Sequence[Light]] = None,
    material: Optional[Material] = None,
    supersample: int = 2,
    camera_z: float = CAMERA_Z,
    shading: str = "phong",
    pinhole: Optional[Sequence[float]] = None,
) -> Render:
    """Render a textured mesh with Phong reflectance and s×s supersampling.

    ``vertices`` (V, 3) float, ``triangles`` (F, 3) int, ``uv`` (V, 2) float,
    ``texture`` (h, w) float albedo in [0, 1], ``size`` (H, W), ``window``
    (xmin, ymin, xmax, ymax). Lighting is two-sided; normals are smooth
    (area-weighted per vertex). Albedo is sampled at every subsample; the
    light terms once per pixel, at its centre: ``shading="phong"`` with the
    interpolated normal there, ``"gouraud"`` interpolating lighting computed
    at the vertices (blurs highlights smaller than a triangle). Default: one
    light along +z, ``Material()``. ``pinhole`` (x, y): a perspective camera
    with its pinhole at (x, y, ``camera_z``), ``camera_z > 0``, whose image
    shows ``window`` of the plane z = 0; depth is then ``camera_z − z`` along
    the optical axis, and every vertex must lie in front of the pinhole.
    """
    lights = [Light()] if lights is None else list(lights)
    for i, light in enumerate(lights):
        if not isinstance(light, Light):
            raise TypeError(f"lights[{i}]: expected a Light, got {type(light).__name__}")
    material = Material() if material is None else material
    if not isinstance(material, Material):
        raise TypeError(f"material: expected a Material, got {type(material).__name__}")
    if not isinstance(shading, str):
        raise TypeError(f"shading: expected 'phong' or 'gouraud', got {type(shading).__name__}")
    return Render(
        *_core.render(
            _float_array("vertices", vertices, 3),
            _index_array("triangles", triangles),
            _float_array("uv", uv, 2),
            _float_array("texture", texture, None),
            _size(size),
            _window(window),
            [asdict(light) for light in lights],
            {k: float(v) for k, v in asdict(material).items()},
            check_int("supersample", supersample),
            float_tuple("camera_z", (camera_z,), 1)[0],
            shading,
            _pinhole(pinhole),
        )
    )


def raycast_depth(
    vertices: np.ndarray,
    triangles: np.ndarray,
    size: Any,
    window: Sequence[float],
    camera_z: float = CAMERA_Z,
    pinhole: Optional[Sequence[float]] = None,
) -> np.ndarray:
    """Depth (H, W) float32 of the first hit of one ray per pixel centre
    (``camera_z − z``), NaN where the ray misses: orthographic rays, or with
    ``pinhole`` (x, y) the rays of a perspective camera (as :func:`render`).
    A BVH (median split) is built over the triangles; rays are cast in
    8×8-pixel packets."""
    return _core.raycast_depth(
        _float_array("vertices", vertices, 3),
        _index_array("triangles", triangles),
        _size(size),
        _window(window),
        float_tuple("camera_z", (camera_z,), 1)[0],
        _pinhole(pinhole),
    )


def procedural_texture(family: str, seed: int = 0, size: int = 256) -> np.ndarray:
    """A (size, size) float32 albedo texture in [0, 1] of one of
    :data:`TEXTURE_FAMILIES`; a pure function of (family, seed, size)."""
    if not isinstance(family, str):
        raise TypeError(f"family: expected a str, got {type(family).__name__}")
    return _core.procedural_texture(family, check_seed("seed", seed), check_int("size", size))
