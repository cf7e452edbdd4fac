"""Deforming surfaces of the paper's model (eqs. vdm, vdm_Fourier).

``f(x, t) = E_t(x + d(x, t))`` with ``x`` on the bi-unit square and

    d(x, t) = κ · G_ν(x) · diag(ζ, ζ, 1) · r(x, t)
    r_i(x, t) = Re F⁻¹{ w · G_ξ · G_Σ · cos(t φ_i + θ_i) · e^{iψ_i} }(x) / n

on an M×M frequency grid, ``M = 2 (grid − 1)``, frequencies ``u = k / 4`` cycles
per unit (the field's period is 4 units, twice the patch, so opposite borders
move independently). The exact formulas:

- ``w(u) = 1 − exp(−(|u| / 0.25)²)``, so ``w(0) = 0`` and ``r`` has zero mean;
- ``G_ξ(u) = exp(−|u|² / (2 ξ²))``: more *flexibility* ξ, more high-frequency wrinkles;
- ``G_Σ(u) = exp(−uᵀ Σ u)``: *orientation* of the folds;
- ``φ_i(u) = speeds[i] · ρ_i(u)``, ``ρ_i ~ U[0.5, 1.5]``, ``θ_i, ψ_i ~ U[0, 2π)``, all
  drawn per frequency from ``phase_seed``. ψ is ours: without it the paper's real
  spectrum makes every surface point-symmetric about the patch centre;
- ``n`` normalises each channel to unit RMS on average: κ is the RMS
  displacement (in half-widths of the patch) before envelope and folding;
- ``G_ν(x) = exp(−ν |x|²)``; ``E_t(p) = R(rotation + t · rotation_rate) p + t · drift``,
  ``t = frame / (frames − 1)``.

Frequencies below 1e-4 of the strongest are dropped. The computation is in the
Rust core (rayon): the inverse transform is an FFT (rustfft) or, for a sparse
spectrum, the sums over its frequencies done directly, whichever an operation
count of the spectrum says is cheaper. Every draw comes from a seed and the
same seed gives the same bytes whatever the thread count or CPU.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields
from typing import Any, Mapping, Optional, Sequence, Tuple

import numpy as np

from .. import _core
from ..checks import check_int, check_seed, float_tuple

Vec3 = Tuple[float, float, float]
Interval = Tuple[float, float]

__all__ = [
    "SurfaceParams",
    "SurfaceConfig",
    "sample_surface_params",
    "synthesize_surface",
    "synthesize_surfaces",
    "grid_triangles",
]


@dataclass(frozen=True)
class SurfaceParams:
    """Every parameter of one deforming surface, named as the paper names it.

    Lengths are in half-widths of the patch (the patch is [-1, 1]²), spatial
    frequencies in cycles per unit, angles in radians, time in clips (t = 0 at
    the first frame, 1 at the last). Construction validates every field and
    raises ``ValueError``/``TypeError`` naming the one that is wrong.
    """

    intensity: float
    """κ: RMS displacement of each channel before envelope and folding; [0, 1]."""
    constraint: float
    """ν: border anchoring, envelope ``exp(−ν|x|²)``; [0, 50]."""
    folding: float
    """ζ: factor on the in-plane displacement channels; [0, 2]."""
    flexibility: float
    """ξ: width (cycles per unit) of the frequency Gaussian ``G_ξ``; [0.001, 16]."""
    orientation: Vec3
    """Σ as (Σxx, Σxy, Σyy), symmetric positive definite, entries in [-100, 100]."""
    speeds: Vec3
    """Speed scale (radians per clip) of the dx, dy, dz channels; [-1000, 1000]."""
    phase_seed: int
    """Seed of the per-frequency phases θ, ψ and speed factors ρ; [0, 2**64)."""
    rotation: Vec3 = (0.0, 0.0, 0.0)
    """E_t: rotation vector (axis × angle, radians) at t = 0; each in [-2π, 2π]."""
    rotation_rate: Vec3 = (0.0, 0.0, 0.0)
    """E_t: change of the rotation vector over the clip; each in [-2π, 2π]."""
    drift: Vec3 = (0.0, 0.0, 0.0)
    """E_t: translation over the clip (zero at t = 0); each in [-10, 10]."""

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            name = f"params.{f.name}"
            if f.name == "phase_seed":
                object.__setattr__(self, f.name, check_seed(name, value))
            elif f.type == "Vec3":
                object.__setattr__(self, f.name, float_tuple(name, value, 3))
            else:
                (v,) = float_tuple(name, (value,), 1)
                object.__setattr__(self, f.name, v)
        _core.validate_surface_params(self.as_dict())

    def as_dict(self) -> dict:
        """Plain dict of the fields (JSON-serialisable)."""
        return asdict(self)

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "SurfaceParams":
        return cls(**d)

    @property
    def sigma(self) -> np.ndarray:
        """Σ as a 2×2 matrix."""
        sxx, sxy, syy = self.orientation
        return np.array([[sxx, sxy], [sxy, syy]])


_DEFAULT_CONFIG = _core.default_surface_config()


@dataclass(frozen=True)
class SurfaceConfig:
    """The (lo, hi) ranges :func:`sample_surface_params` draws from, uniformly
    unless noted. The defaults are the Rust core's."""

    intensity: Interval = _DEFAULT_CONFIG["intensity"]
    constraint: Interval = _DEFAULT_CONFIG["constraint"]
    folding: Interval = _DEFAULT_CONFIG["folding"]
    flexibility: Interval = _DEFAULT_CONFIG["flexibility"]
    orientation_eigenvalues: Interval = _DEFAULT_CONFIG["orientation_eigenvalues"]
    """Eigenvalues of Σ, log-uniform; the eigenvector angle is uniform in [0, π)."""
    speed: Interval = _DEFAULT_CONFIG["speed"]
    """Per-channel speed scale, radians per clip."""
    tilt: Interval = _DEFAULT_CONFIG["tilt"]
    """Initial rotation about x and y."""
    spin: Interval = _DEFAULT_CONFIG["spin"]
    """Initial rotation about z (in-plane)."""
    tilt_rate: Interval = _DEFAULT_CONFIG["tilt_rate"]
    spin_rate: Interval = _DEFAULT_CONFIG["spin_rate"]
    drift_xy: Interval = _DEFAULT_CONFIG["drift_xy"]
    drift_z: Interval = _DEFAULT_CONFIG["drift_z"]

    def __post_init__(self) -> None:
        for f in fields(self):
            object.__setattr__(self, f.name, float_tuple(f"config.{f.name}", getattr(self, f.name), 2))
        _core.validate_surface_config(self.as_dict())

    def as_dict(self) -> dict:
        return asdict(self)


def sample_surface_params(seed: int, config: Optional[SurfaceConfig] = None) -> SurfaceParams:
    """Draw a :class:`SurfaceParams` from ``config`` (default ranges if None);
    a pure function of ``(config, seed)``."""
    seed = check_seed("seed", seed)
    config = _check_config(config)
    return SurfaceParams.from_dict(_core.sample_surface_params(seed, config.as_dict()))


def _check_config(config: Optional[SurfaceConfig]) -> SurfaceConfig:
    if config is None:
        return SurfaceConfig()
    if not isinstance(config, SurfaceConfig):
        raise TypeError(f"config: expected a SurfaceConfig or None, got {type(config).__name__}")
    return config


def _check_params(name: str, params: Any) -> SurfaceParams:
    if not isinstance(params, SurfaceParams):
        raise TypeError(f"{name}: expected a SurfaceParams, got {type(params).__name__}")
    return params


def synthesize_surface(params: SurfaceParams, frames: int = 16, grid: int = 64) -> np.ndarray:
    """Vertex positions of one deforming surface clip.

    Returns float32 of shape ``(frames, grid, grid, 3)``: ``[t, jy, jx] = (x, y, z)``
    of grid vertex (row ``jy``, column ``jx``), whose undeformed position is
    ``(−1 + 2 jx / (grid − 1), −1 + 2 jy / (grid − 1), 0)``. Triangles:
    :func:`grid_triangles`.
    """
    params = _check_params("params", params)
    return _core.synthesize_surface(params.as_dict(), check_int("frames", frames), check_int("grid", grid))


def synthesize_surfaces(params: Sequence[SurfaceParams], frames: int = 16, grid: int = 64) -> np.ndarray:
    """Many clips in parallel (Rust threads, GIL released): float32
    ``(len(params), frames, grid, grid, 3)``; entry i equals
    ``synthesize_surface(params[i], frames, grid)`` bit for bit."""
    if isinstance(params, SurfaceParams) or not isinstance(params, Sequence):
        raise TypeError(f"params: expected a sequence of SurfaceParams, got {type(params).__name__}")
    dicts = [_check_params(f"params[{i}]", p).as_dict() for i, p in enumerate(params)]
    return _core.synthesize_surfaces(dicts, check_int("frames", frames), check_int("grid", grid))


def grid_triangles(grid: int = 64) -> np.ndarray:
    """uint32 ``(2 (grid − 1)², 3)`` triangle indices of the grid mesh; vertex
    index ``jy · grid + jx``; counter-clockwise seen from the camera (+z)."""
    return _core.grid_triangles(check_int("grid", grid))
