"""The rendered-sheets benchmark's scenes: isometric bends, drawn from their
seed alone, and (where Mitsuba is installed) a render whose truth agrees with
the pinhole the scene says it has."""

import math

import numpy as np
import pytest

from nrdepth.scores import rendered


def grid_lengths(points: np.ndarray) -> np.ndarray:
    grid = points.reshape(rendered.GRID[1], rendered.GRID[0], 3)
    return np.concatenate([np.linalg.norm(np.diff(grid, axis=0), axis=2).ravel(), np.linalg.norm(np.diff(grid, axis=1), axis=2).ravel()])


@pytest.mark.parametrize("seed", range(6))
def test_every_frame_of_a_scene_bends_the_sheet_without_stretching_it(seed):
    scene = rendered.scene_of(seed, frames=16)
    flat = grid_lengths(rendered.sheet_vertices(dataclass_replace(scene, curvature=0.0, tilt=(0.0, 0.0)), 0.0))
    bends = []
    for t in np.linspace(0, 1, 9):
        points = rendered.sheet_vertices(scene, t)
        np.testing.assert_allclose(grid_lengths(points), flat, rtol=2e-3)  # chords of an arc: within 0.2 % at this grid
        bends.append(rendered.curvature_at(scene, t))
        assert points[:, 2].min() > 0.2 * scene.distance  # in front of the camera
    bends = np.array(bends)
    assert {"away": (bends > 0).all(), "toward": (bends < 0).all(), "turning": (bends > 0).any() and (bends < 0).any()}[scene.bend]


def dataclass_replace(scene, **changes):
    import dataclasses

    return dataclasses.replace(scene, **changes)


def test_scenes_come_from_their_seed_alone_and_the_split_was_fixed_by_the_seed():
    assert rendered.scene_of(7) == rendered.scene_of(7) and rendered.scene_of(7) != rendered.scene_of(8)
    assert [rendered.split_of(s) for s in range(4)] == ["selection", "report", "selection", "report"]
    scenes = [rendered.scene_of(s) for s in range(48)]
    for field, values in (("bend", rendered.BENDS), ("light", rendered.LIGHTS), ("background", rendered.BACKGROUNDS), ("print_kind", rendered.PRINTS)):
        assert {getattr(s, field) for s in scenes} == set(values)  # 48 seeds draw every kind
    assert all(30 <= s.fov <= 75 for s in scenes)


def test_a_render_shows_the_sheet_where_the_scenes_pinhole_puts_it(tmp_path):
    pytest.importorskip("mitsuba")
    scene = rendered.scene_of(2, frames=2, size=(48, 64), spp=2)
    saved = np.load(rendered.render_video(scene, tmp_path / "sheet.npz"))
    video, depth, sheet = saved["video"], saved["depth"], saved["sheet"]
    assert video.shape == depth.shape == sheet.shape == (2, 48, 64) and video.dtype == np.uint8 and sheet[0].sum() > 100
    points = rendered.sheet_vertices(scene, 0.0)
    f = 0.5 * 64 / math.tan(math.radians(scene.fov) / 2)
    assert float(saved["focal"]) == pytest.approx(f)
    u, v = f * points[:, 0] / points[:, 2] + 31.5, f * points[:, 1] / points[:, 2] + 23.5
    ys, xs = np.nonzero(sheet[0])
    inside = lambda lo, hi, n: (max(lo, 0.0), min(hi, n - 1.0))  # noqa: E731 (the sheet may run out of the frame)
    top, bottom = inside(v.min(), v.max(), 48)
    assert abs(ys.min() - top) < 2.5 and abs(ys.max() - bottom) < 2.5  # row 0 at the top: the pinhole's y grows downward
    left, right = inside(u.min(), u.max(), 64)
    assert abs(xs.min() - left) < 2.5 and abs(xs.max() - right) < 2.5
    z = depth[0][sheet[0]]
    assert points[:, 2].min() - 1e-3 <= z.min() and z.max() <= points[:, 2].max() + 1e-3  # the depth along the axis, on the sheet


def test_true_tracks_carry_the_sheets_own_vertices_and_leave_points_off_it_out():
    """A start on a vertex of the sheet's mesh is that vertex in every frame (its projection through the scene's pinhole);
    a start off the sheet is NaN throughout."""
    scene = rendered.scene_of(3, frames=5, size=(64, 80))
    first = rendered.sheet_vertices(scene, 0.0)
    picked = np.array([rendered.GRID[0] * row + col for row in (5, 20, 40) for col in (3, 20, 37)])  # inside the grid
    project = lambda p: np.stack([scene.focal * p[:, 0] / p[:, 2] + 39.5, scene.focal * p[:, 1] / p[:, 2] + 31.5], axis=1)  # noqa: E731
    start = np.concatenate([project(first[picked]), [[-500.0, -500.0]]])
    tracks = rendered.true_tracks(scene, start)
    for t in range(scene.frames):
        np.testing.assert_allclose(tracks[t, :-1], project(rendered.sheet_vertices(scene, t / 4)[picked]), atol=1e-6)
    assert np.isnan(tracks[:, -1]).all()
