"""Rendering and ray casting through the public API: agreement, exact
analytic depth, Phong sanity, and bad input named."""

import numpy as np
import pytest

import nrdepth
from nrdepth import CAMERA_Z, Light, Material


def deformed_grid(seed, grid=48):
    params = nrdepth.sample_surface_params(seed)
    vertices = nrdepth.synthesize_surface(params, frames=1, grid=grid)[0].reshape(-1, 3)
    c = np.linspace(0.0, 1.0, grid)
    u, v = np.meshgrid(c, 1.0 - c)
    return vertices, nrdepth.grid_triangles(grid), np.stack([u, v], -1).reshape(-1, 2)


@pytest.mark.parametrize("seed,supersample", [(0, 1), (1, 1), (2, 2), (3, 4)])
def test_zbuffer_and_ray_cast_depth_agree_at_pixel_centres(seed, supersample):
    vertices, triangles, uv = deformed_grid(seed)
    window = (-0.6, -0.5, 0.55, 0.6)
    texture = nrdepth.procedural_texture("fractal", seed, 64)
    cast = nrdepth.raycast_depth(vertices, triangles, (40, 44), window)
    out = nrdepth.render(vertices, triangles, uv, texture, (40, 44), window, supersample=supersample)
    assert np.array_equal(np.isnan(cast), np.isnan(out.depth))
    np.testing.assert_array_equal(cast[~np.isnan(cast)], out.depth[~np.isnan(cast)])
    assert np.isfinite(cast).mean() > 0.9


@pytest.mark.parametrize("supersample", [1, 2])
def test_a_perspective_camera_agrees_with_its_ray_caster_and_magnifies_what_is_near(supersample):
    vertices, triangles, uv = deformed_grid(4)
    window, pinhole = (-0.6, -0.5, 0.55, 0.6), (0.1, -0.05)
    texture = nrdepth.procedural_texture("fractal", 4, 64)
    cast = nrdepth.raycast_depth(vertices, triangles, (40, 44), window, camera_z=1.5, pinhole=pinhole)
    out = nrdepth.render(vertices, triangles, uv, texture, (40, 44), window, supersample=supersample, camera_z=1.5, pinhole=pinhole)
    assert np.array_equal(np.isnan(cast), np.isnan(out.depth))
    np.testing.assert_array_equal(cast[~np.isnan(cast)], out.depth[~np.isnan(cast)])
    # A flat square at depth d covers (camera_z / d)² the pixels it covers at the plane z = 0.
    square = np.array([[-0.2, -0.2, 0.0], [0.2, -0.2, 0.0], [0.2, 0.2, 0.0], [-0.2, 0.2, 0.0]])
    two = np.array([[0, 1, 2], [0, 2, 3]])
    def covered(z):
        lifted = square + [0.0, 0.0, z]
        return np.isfinite(nrdepth.raycast_depth(lifted, two, (200, 200), (-1, -1, 1, 1), camera_z=1.5, pinhole=(0.0, 0.0))).sum()
    assert covered(0.5) / covered(0.0) == pytest.approx((1.5 / 1.0) ** 2, rel=0.03)


def test_under_perspective_a_relief_and_its_mirror_under_mirrored_light_part_ways():
    # The orthographic camera's ambiguity (why nrdepth needs a light prior): z lit from
    # azimuth a renders as −z lit from a + π. A pinhole sees the near relief magnified, which breaks it.
    grid = 65
    c = np.linspace(-1, 1, grid)
    x, y = np.meshgrid(c, c)
    bump = 0.25 * np.exp(-(x**2 + y**2) / 0.15)
    u, v = np.meshgrid(np.linspace(0, 1, grid), np.linspace(1, 0, grid))
    uv, triangles = np.stack([u, v], -1).reshape(-1, 2), nrdepth.grid_triangles(grid)
    texture = nrdepth.procedural_texture("plaid", 1, 128)
    matte = Material(ambient=0.1, diffuse=0.9, specular=0.0, shininess=1.0)
    def image(sign, light, **camera):
        vertices = np.stack([x, y, sign * bump], -1).reshape(-1, 3)
        return nrdepth.render(vertices, triangles, uv, texture, 64, (-0.8, -0.8, 0.8, 0.8), [light], matte, **camera).image
    above, below = Light(vector=(0.0, 0.6, 0.8)), Light(vector=(0.0, -0.6, 0.8))
    np.testing.assert_allclose(image(1, above), image(-1, below), atol=1e-5)
    pinhole = {"camera_z": 2.0, "pinhole": (0.0, 0.0)}
    assert np.abs(image(1, above, **pinhole) - image(-1, below, **pinhole)).mean() > 0.02


def test_tilted_plane_depth_is_exact():
    grid = 9
    c = np.linspace(-1, 1, grid)
    x, y = np.meshgrid(c, c)
    z = 0.4 * x - 0.25 * y + 0.05
    vertices = np.stack([x, y, z], -1).reshape(-1, 3)
    depth = nrdepth.raycast_depth(vertices, nrdepth.grid_triangles(grid), (16, 24), (-0.9, -0.9, 0.9, 0.9))
    xs = -0.9 + (np.arange(24) + 0.5) * 1.8 / 24
    ys = 0.9 - (np.arange(16) + 0.5) * 1.8 / 16
    expected = CAMERA_Z - (0.4 * xs[None, :] - 0.25 * ys[:, None] + 0.05)
    np.testing.assert_allclose(depth, expected, atol=2e-6)


def test_a_face_toward_the_light_is_brighter():
    corners = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], float)
    uv = (corners + 1) / 2
    triangles = np.array([[0, 1, 2], [0, 2, 3]])
    white = np.ones((4, 4))
    matte = Material(ambient=0.0, diffuse=1.0, specular=0.0, shininess=1.0)

    def brightness(tilt):
        vertices = np.column_stack([corners[:, 0] * np.cos(tilt), corners[:, 1], -corners[:, 0] * np.sin(tilt)])
        out = nrdepth.render(vertices, triangles, uv, white, 8, (-0.3, -0.3, 0.3, 0.3), [Light()], matte)
        return out.image.mean()

    assert brightness(0.0) == pytest.approx(1.0, abs=1e-5)
    assert brightness(0.7) == pytest.approx(np.cos(0.7), abs=1e-4)


def test_point_light_and_supersampling_give_finite_partial_coverage_at_the_border():
    vertices, triangles, uv = deformed_grid(1, 24)
    out = nrdepth.render(
        vertices, triangles, uv, np.full((8, 8), 0.5), (30, 30), (-1.5, -1.5, 1.5, 1.5),
        [Light("point", (1.0, 1.0, 3.0), 0.8), Light("directional", (0, 1, 1), 0.3)], supersample=3,
    )
    assert out.image.shape == (30, 30) and out.depth.shape == (30, 30)
    assert np.isfinite(out.image).all()
    edge = (out.coverage > 0) & (out.coverage < 1)
    assert edge.any() and (out.coverage == 0).any() and (out.coverage == 1).any()
    # Partly covered pixels average their subsamples: darker than their covered part alone.
    assert out.image[out.coverage == 0].max() == 0.0


def test_procedural_textures():
    assert set(nrdepth.TEXTURE_FAMILIES) == {"fractal", "stripes", "plaid", "cells", "weave", "print"}
    for family in nrdepth.TEXTURE_FAMILIES:
        t = nrdepth.procedural_texture(family, 3, 32)
        assert t.shape == (32, 32) and t.dtype == np.float32
        assert t.min() >= 0 and t.max() <= 1 and t.std() > 0.02
        np.testing.assert_array_equal(t, nrdepth.procedural_texture(family, 3, 32))


_V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32)
_T = np.array([[0, 1, 2]])
_UV = np.zeros((3, 2))
_TEX = np.ones((2, 2))
_W = (0, 0, 1, 1)


@pytest.mark.parametrize(
    "call, error, name",
    [
        (lambda: nrdepth.raycast_depth(_V.astype(int), _T, 4, _W), TypeError, "vertices"),
        (lambda: nrdepth.raycast_depth(_V[:, :2], _T, 4, _W), ValueError, "vertices"),
        (lambda: nrdepth.raycast_depth(np.where(_V == 1, np.nan, _V), _T, 4, _W), ValueError, "vertices"),
        (lambda: nrdepth.raycast_depth(np.zeros((0, 3)), np.zeros((0, 3), int), 4, _W), ValueError, "vertices"),
        (lambda: nrdepth.raycast_depth(_V, np.zeros((0, 3), int), 4, _W), ValueError, "triangles"),
        (lambda: nrdepth.raycast_depth(_V, [[0, 1, 3]], 4, _W), ValueError, "triangles"),
        (lambda: nrdepth.raycast_depth(_V, [[0, 1, -1]], 4, _W), ValueError, "triangles"),
        (lambda: nrdepth.raycast_depth(_V, _T.astype(float), 4, _W), TypeError, "triangles"),
        (lambda: nrdepth.raycast_depth(_V, _T, (0, 4), _W), ValueError, "size"),
        (lambda: nrdepth.raycast_depth(_V, _T, 4, _W, pinhole=(0.0,)), ValueError, "pinhole"),
        (lambda: nrdepth.raycast_depth(_V, _T, 4, _W, camera_z=-1.0, pinhole=(0.0, 0.0)), ValueError, "camera_z"),
        (lambda: nrdepth.raycast_depth(_V + [0, 0, 1], _T, 4, _W, camera_z=0.5, pinhole=(0.0, 0.0)), ValueError, "vertices"),
        (lambda: nrdepth.raycast_depth(_V, _T, "big", _W), TypeError, "size"),
        (lambda: nrdepth.raycast_depth(_V, _T, 4, (0, 0, 0, 1)), ValueError, "window"),
        (lambda: nrdepth.raycast_depth(_V, _T, 4, (0, 0, 1)), ValueError, "window"),
        (lambda: nrdepth.render(_V, _T, _UV[:2], _TEX, 4, _W), ValueError, "uv"),
        (lambda: nrdepth.render(_V, _T, _UV, np.ones(4), 4, _W), ValueError, "texture"),
        (lambda: nrdepth.render(_V, _T, _UV, _TEX, 4, _W, supersample=0), ValueError, "supersample"),
        (lambda: nrdepth.render(_V + [0, 0, 1], _T, _UV, _TEX, 4, _W, camera_z=0.5, pinhole=(0.0, 0.0)), ValueError, "vertices"),
        (lambda: nrdepth.render(_V, _T, _UV, _TEX, 4, _W, pinhole=(float("nan"), 0.0)), ValueError, "pinhole"),
        (lambda: nrdepth.render(_V, _T, _UV, _TEX, 4, _W, [Light(vector=(0, 0, 0))]), ValueError, "lights[0]"),
        (lambda: nrdepth.render(_V, _T, _UV, _TEX, 4, _W, [{"kind": "point"}]), TypeError, "lights[0]"),
        (lambda: nrdepth.render(_V, _T, _UV, _TEX, 4, _W, material=Material(shininess=-1)), ValueError, "material.shininess"),
        (lambda: Light(kind="spot"), ValueError, "light.kind"),
        (lambda: nrdepth.procedural_texture("velvet"), ValueError, "family"),
    ],
)
def test_bad_input_is_named(call, error, name):
    with pytest.raises(error) as info:
        call()
    assert str(info.value).startswith(name), str(info.value)
