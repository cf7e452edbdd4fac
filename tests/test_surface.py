"""Surface synthesis: each parameter moves what it names, the field is smooth in
space and time, reproducible bit for bit, and bad input is refused by name."""

import dataclasses
import math
import os
import subprocess
import sys

import numpy as np
import pytest

import nrdepth
from nrdepth import SurfaceConfig, SurfaceParams


def still(seed, **changes):
    """Sampled params without rigid motion, so positions − grid = displacement."""
    p = nrdepth.sample_surface_params(seed)
    zero = (0.0, 0.0, 0.0)
    return dataclasses.replace(p, rotation=zero, rotation_rate=zero, drift=zero, **changes)


def base_grid(grid):
    c = np.linspace(-1.0, 1.0, grid)
    x, y = np.meshgrid(c, c)
    return np.stack([x, y, np.zeros_like(x)], axis=-1)


def displacement(params, frames=4, grid=64):
    return nrdepth.synthesize_surface(params, frames, grid).astype(np.float64) - base_grid(grid)


def rms(a):
    return float(np.sqrt(np.mean(np.square(a))))


def sigma_rotated(angle, small=0.02, large=8.0):
    c, s = math.cos(angle), math.sin(angle)
    r = np.array([[c, -s], [s, c]])
    m = r @ np.diag([small, large]) @ r.T
    return (m[0, 0], m[0, 1], m[1, 1])


def test_output_shape_dtype_and_undeformed_layout():
    p = still(0, intensity=0.0)
    pos = nrdepth.synthesize_surface(p, frames=3, grid=10)
    assert pos.shape == (3, 10, 10, 3) and pos.dtype == np.float32 and pos.flags.c_contiguous
    np.testing.assert_allclose(pos, np.broadcast_to(base_grid(10), pos.shape), atol=1e-7)


def test_intensity_scales_the_field_linearly():
    a = displacement(still(1, intensity=0.05))
    b = displacement(still(1, intensity=0.10))
    assert rms(a) > 1e-3
    np.testing.assert_allclose(b, 2.0 * a, rtol=1e-5, atol=1e-6)


def test_more_constraint_shrinks_the_border_relative_to_the_centre():
    grid = 64
    border = np.ones((grid, grid), bool)
    border[8:-8, 8:-8] = False
    centre = np.zeros((grid, grid), bool)
    centre[24:40, 24:40] = True

    def ratio(nu):
        ds = [displacement(still(s, constraint=nu), grid=grid) for s in range(8)]
        return np.mean([rms(d[:, border]) / rms(d[:, centre]) for d in ds])

    loose, tight = ratio(0.0), ratio(3.0)
    assert tight < 0.4 * loose, (loose, tight)


@pytest.mark.parametrize("seed", range(5))
def test_more_flexibility_puts_more_energy_in_high_frequencies(seed):
    # RMS(∇d) / RMS(d) is 2π × the RMS frequency of a smooth field.
    def frequency(xi):
        d = displacement(still(seed, flexibility=xi, constraint=0.0, orientation=(0.02, 0.0, 0.02)))[..., 2]
        gy, gx = np.gradient(d, 2.0 / 63, axis=(1, 2))
        return math.hypot(rms(gx), rms(gy)) / rms(d)

    stiff, soft = frequency(0.4), frequency(1.2)
    assert soft > 1.5 * stiff, (stiff, soft)


def test_more_folding_raises_the_in_plane_to_out_of_plane_ratio():
    def ratio(zeta):
        d = displacement(still(2, folding=zeta))
        return rms(d[..., :2]) / rms(d[..., 2])

    assert ratio(0.0) < 1e-5  # float32 rounding of the grid coordinates only
    assert ratio(0.4) == pytest.approx(4.0 * ratio(0.1), rel=1e-4)
    assert ratio(0.4) > ratio(0.1) > 0.0


@pytest.mark.parametrize("degrees", [0, 30, 60, 90, 135])
def test_sigma_turns_the_dominant_fold_direction(degrees):
    # Σ's small-eigenvalue direction e lets the spectrum extend along e, so depth
    # varies along e: the principal axis of the gradient structure tensor is ±e.
    angle = math.radians(degrees)
    p = still(4, orientation=sigma_rotated(angle), constraint=0.0, flexibility=1.0)
    z = displacement(p, frames=8)[..., 2]
    gy, gx = np.gradient(z, axis=(1, 2))
    tensor = np.array([[np.mean(gx * gx), np.mean(gx * gy)], [np.mean(gx * gy), np.mean(gy * gy)]])
    evals, evecs = np.linalg.eigh(tensor)
    principal = evecs[:, 1]
    cos_err = abs(principal @ np.array([math.cos(angle), math.sin(angle)]))
    assert math.degrees(math.acos(min(cos_err, 1.0))) < 15
    assert evals[1] > 4 * evals[0]


def test_frames_change_smoothly_and_sample_one_continuous_motion():
    p = still(6, speeds=(2.0, 2.0, 2.0))
    d16 = displacement(p, frames=16)
    d31 = displacement(p, frames=31)
    # Frame j of 16 and frame 2j of 31 are the same t.
    np.testing.assert_allclose(d31[::2], d16, atol=2e-5)
    step = np.diff(d16, axis=0)
    assert rms(step) > 1e-3 * rms(d16), "the surface must move"
    assert rms(np.diff(d16, n=2, axis=0)) < 0.3 * rms(step)
    assert rms(d16[-1] - d16[0]) > 2 * rms(step)


def test_field_is_smooth_in_space():
    p = still(7, constraint=0.0)
    coarse, fine = displacement(p, grid=64), displacement(p, grid=127)
    np.testing.assert_allclose(fine[:, ::2, ::2], coarse, atol=2e-5)

    def curvature(d):
        return np.abs(np.diff(d, n=2, axis=2)).max()

    # Second differences of a smooth field scale with h²: halving h quarters them.
    assert curvature(fine) < 0.35 * curvature(coarse)


def test_surface_is_not_point_symmetric_about_the_centre():
    d = displacement(still(3, constraint=0.0))[..., 2]
    flipped = d[:, ::-1, ::-1]
    assert rms(d - flipped) > 0.5 * rms(d)


def test_sampling_is_a_pure_function_of_seed_and_config():
    assert nrdepth.sample_surface_params(11) == nrdepth.sample_surface_params(11)
    assert nrdepth.sample_surface_params(11) != nrdepth.sample_surface_params(12)
    narrow = SurfaceConfig(intensity=(0.2, 0.2), flexibility=(0.5, 0.6))
    p = nrdepth.sample_surface_params(11, narrow)
    assert p.intensity == 0.2 and 0.5 <= p.flexibility <= 0.6
    assert SurfaceParams.from_dict(p.as_dict()) == p


def test_batch_equals_single_bit_for_bit():
    params = [nrdepth.sample_surface_params(s) for s in range(6)]
    batch = nrdepth.synthesize_surfaces(params, frames=5, grid=20)
    assert batch.shape == (6, 5, 20, 20, 3)
    for i, p in enumerate(params):
        assert batch[i].tobytes() == nrdepth.synthesize_surface(p, frames=5, grid=20).tobytes()


_DIGEST = """
import hashlib, nrdepth
ps = [nrdepth.sample_surface_params(s) for s in range(12)]
h = hashlib.sha256(nrdepth.synthesize_surfaces(ps, 16, 48).tobytes())
h.update(nrdepth.synthesize_surface(ps[3], 7, 33).tobytes())
print(h.hexdigest())
"""


def test_same_bytes_with_one_and_two_threads():
    digests = []
    for threads in ("1", "2"):
        env = dict(os.environ, RAYON_NUM_THREADS=threads)
        out = subprocess.run([sys.executable, "-c", _DIGEST], env=env, capture_output=True, text=True, check=True)
        digests.append(out.stdout.strip())
    assert digests[0] == digests[1] and len(digests[0]) == 64


def test_grid_triangles():
    tris = nrdepth.grid_triangles(5)
    assert tris.dtype == np.uint32 and tris.shape == (32, 3)
    assert tris.max() == 24 and tris.min() == 0
    # Every interior edge is shared by exactly two triangles, boundary edges by one.
    edges = {}
    for t in tris.tolist():
        for a, b in ((t[0], t[1]), (t[1], t[2]), (t[2], t[0])):
            edges[frozenset((a, b))] = edges.get(frozenset((a, b)), 0) + 1
    assert sorted(set(edges.values())) == [1, 2]
    assert sum(1 for v in edges.values() if v == 1) == 4 * 4


# ---------------------------------------------------------------- bad input


def _params(**changes):
    return dataclasses.replace(nrdepth.sample_surface_params(0), **changes)


@pytest.mark.parametrize(
    "make, error, name",
    [
        (lambda: _params(intensity=float("nan")), ValueError, "params.intensity"),
        (lambda: _params(flexibility=float("inf")), ValueError, "params.flexibility"),
        (lambda: _params(folding=-0.1), ValueError, "params.folding"),
        (lambda: _params(orientation=(1.0, 2.0, 1.0)), ValueError, "params.orientation"),
        (lambda: _params(orientation=(1.0, 0.0)), ValueError, "params.orientation"),
        (lambda: _params(speeds="abc"), TypeError, "params.speeds"),
        (lambda: _params(phase_seed=-1), ValueError, "params.phase_seed"),
        (lambda: _params(phase_seed=1.5), TypeError, "params.phase_seed"),
        (lambda: _params(drift=(0.0, 0.0, 1e9)), ValueError, "params.drift"),
        (lambda: SurfaceConfig(flexibility=(2.0, 1.0)), ValueError, "config.flexibility"),
        (lambda: SurfaceConfig(intensity=(0.0, float("nan"))), ValueError, "config.intensity"),
        (lambda: nrdepth.sample_surface_params(-3), ValueError, "seed"),
        (lambda: nrdepth.sample_surface_params(2**64), ValueError, "seed"),
        (lambda: nrdepth.sample_surface_params("0"), TypeError, "seed"),
        (lambda: nrdepth.sample_surface_params(0, config={"intensity": (0, 1)}), TypeError, "config"),
        (lambda: nrdepth.synthesize_surface(_params(), frames=0), ValueError, "frames"),
        (lambda: nrdepth.synthesize_surface(_params(), frames=-5), ValueError, "frames"),
        (lambda: nrdepth.synthesize_surface(_params(), frames=2.0), TypeError, "frames"),
        (lambda: nrdepth.synthesize_surface(_params(), grid=1), ValueError, "grid"),
        (lambda: nrdepth.synthesize_surface(_params(), grid=10**9), ValueError, "grid"),
        (lambda: nrdepth.synthesize_surface(_params(), grid=True), TypeError, "grid"),
        (lambda: nrdepth.synthesize_surface({"intensity": 0.1}), TypeError, "params"),
        (lambda: nrdepth.synthesize_surfaces(_params()), TypeError, "params"),
        (lambda: nrdepth.synthesize_surfaces([_params(), None]), TypeError, "params[1]"),
        (lambda: nrdepth.synthesize_surfaces([_params()] * 4, frames=4096, grid=4096), ValueError, "grid"),
        (lambda: nrdepth.synthesize_surfaces([_params()] * 4, frames=16, grid=4096), ValueError, "params"),
        (lambda: nrdepth.grid_triangles(0), ValueError, "grid"),
    ],
)
def test_bad_input_raises_a_clear_error_naming_the_argument(make, error, name):
    with pytest.raises(error) as info:
        make()
    assert str(info.value).startswith(name), str(info.value)


def test_extreme_but_valid_params_give_finite_output():
    p = _params(flexibility=16.0, orientation=(1e-3, 0.0, 1e-3), speeds=(1000.0, -1000.0, 0.0), constraint=50.0)
    assert np.isfinite(nrdepth.synthesize_surface(p, frames=3, grid=16)).all()
    p = _params(flexibility=1e-3)
    assert np.isfinite(nrdepth.synthesize_surface(p, frames=3, grid=16)).all()


def test_empty_batch():
    assert nrdepth.synthesize_surfaces([], frames=2, grid=4).shape == (0, 2, 4, 4, 3)
