"""nrdepth.isometric: the flow tracker follows a known motion, loses the
points that leave the frame and leaves out the points where the motion
breaks, MDH recovers
an exactly inextensible sheet under perspective, its two stages agree, its
answer is reproducible, the fusion is GBR-invariant, and bad input names
its argument."""

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import nrdepth
from nrdepth import isometric
from nrdepth.isometric import least_disagreeing
from nrdepth.isometric.hold import HOLD_WINDOW
from nrdepth.isometric.mdh import _refine, _socp, solve_template
from nrdepth.baselines.tracks import densify

FOCAL = 500.0


def rolled_sheet(frames: int = 8, side: int = 9, start: float = 0.2):
    """Image positions (T, n, 2) and depths (T, n) of a grid on a sheet 2 × 1.6
    rolled about its vertical axis, the curvature growing frame by frame from ``start``
    (arc-length parametrised: no stretch), turning and drifting, 4 units in
    front of a pinhole of focal length FOCAL with its centre at pixel (0, 0)."""
    s, v = (a.ravel() for a in np.meshgrid(np.linspace(-1, 1, side), np.linspace(-0.8, 0.8, side)))
    xy, depth = [], []
    for t in range(frames):
        k = start + (1 - start) * t / (frames - 1)
        x, z = np.sin(k * s) / k, (1 - np.cos(k * s)) / k
        a = 0.3 * np.sin(t)
        x, z = np.cos(a) * x + np.sin(a) * z, -np.sin(a) * x + np.cos(a) * z
        points = np.stack([x, v + 0.05 * t, z + 4.0], axis=1)
        xy.append(FOCAL * points[:, :2] / points[:, 2:])
        depth.append(points[:, 2])
    return np.array(xy), np.array(depth)


def relief_error(depth: np.ndarray, truth: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """Per frame: the error after the GBR fit (a·x + b·y + λ·depth + t) over that of the best plane."""
    out = []
    for d, z, p in zip(depth, truth, xy):
        plane = np.column_stack([p, np.ones(len(z))])
        fitted = np.column_stack([plane, d])
        errors = [np.abs(a @ np.linalg.lstsq(a, z, rcond=None)[0] - z).mean() for a in (fitted, plane)]
        out.append(errors[0] / errors[1])
    return np.array(out)


def test_mdh_reads_a_rolled_sheet():
    xy, truth = rolled_sheet()
    depth = isometric.mdh_depths(xy, FOCAL, (0.0, 0.0), neighbours=8, keyframes=4)
    ratio = relief_error(depth, truth, xy)
    assert (depth > 0).all()
    assert ratio.mean() < 0.5 and ratio[-3:].max() < 0.3, ratio  # the plane is 1; the most bent frames read best
    # the depth grows away from the camera: λ > 0 in the bent half (the first frames are nearly flat)
    for d, z, p in zip(depth[4:], truth[4:], xy[4:]):
        assert np.linalg.lstsq(np.column_stack([p, np.ones(len(z)), d]), z, rcond=None)[0][3] > 0


def test_mdh_reads_a_sheet_exactly_from_its_flat_first_frame():
    # A flat first frame facing the camera gives the template distances: every frame then reads as the truth.
    xy, truth = rolled_sheet(start=1e-4)
    first = isometric.mdh_depths(xy, FOCAL, (0.0, 0.0), neighbours=8, template="first")
    joint = isometric.mdh_depths(xy, FOCAL, (0.0, 0.0), neighbours=8, keyframes=4)
    assert relief_error(first[1:], truth[1:], xy[1:]).max() < 0.02 < relief_error(joint[1:], truth[1:], xy[1:]).mean()
    with pytest.raises(ValueError, match="template"):
        isometric.mdh_depths(xy, FOCAL, (0.0, 0.0), template="last")
    # The true distances (a template), given: every frame reads as the truth, in the template's units.
    pairs = isometric.neighbour_pairs(xy[0], 8)
    points = np.concatenate([xy / FOCAL, np.ones(xy.shape[:2] + (1,))], axis=2) * truth[..., None]
    known = isometric.mdh_depths(xy, FOCAL, (0.0, 0.0), pairs=pairs, template=np.linalg.norm(points[0, pairs[:, 0]] - points[0, pairs[:, 1]], axis=1))
    np.testing.assert_allclose(known, truth, rtol=2e-3)
    with pytest.raises(ValueError, match="pairs"):
        isometric.mdh_depths(xy, FOCAL, (0.0, 0.0), template=np.ones(len(pairs)))
    with pytest.raises(ValueError, match="template"):
        isometric.mdh_depths(xy, FOCAL, (0.0, 0.0), pairs=pairs, template=np.ones(3))


def test_mdh_refined_reads_a_rolled_sheet_the_joint_program_domes():
    # The joint program picks distances that dome every frame; asking each pair to keep its distance in every
    # keyframe gives the roll back, and the truth is a fixed point of that refinement.
    xy, truth = rolled_sheet(start=0.5)
    joint = isometric.mdh_depths(xy, FOCAL, (0.0, 0.0), neighbours=8, keyframes=4)
    refined = isometric.mdh_depths(xy, FOCAL, (0.0, 0.0), neighbours=8, keyframes=4, template="refined")
    assert relief_error(refined, truth, xy).max() < 0.03 < 0.2 < relief_error(joint, truth, xy).mean()
    # A sheet moved rigidly keeps every chord: its depths and distances are a zero of the residuals, kept.
    points = (nrdepth.Camera(FOCAL, (0.0, 0.0)).rays(xy) * truth[..., None])[3]
    moved = np.stack([points @ np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]]) + [0.1 * a, 0, a] for a in (0, 0.3, 0.6)])
    pairs = isometric.neighbour_pairs(moved[0, :, :2] / moved[0, :, 2:], 8)
    distances = np.linalg.norm(points[pairs[:, 0]] - points[pairs[:, 1]], axis=1)
    unit = len(pairs) / distances.sum()  # the refinement's units: Σ D = the number of pairs
    depths, kept = _refine(moved / moved[..., 2:], pairs, moved[..., 2] * unit, distances * unit, 100)
    np.testing.assert_allclose(depths, moved[..., 2] * unit, rtol=1e-9)
    np.testing.assert_allclose(kept, distances * unit, rtol=1e-9)
    assert refined.tobytes() == isometric.mdh_depths(xy, FOCAL, (0.0, 0.0), neighbours=8, keyframes=4, template="refined").tobytes()
    with pytest.raises(ValueError, match="evaluations"):
        isometric.mdh_depths(xy, FOCAL, (0.0, 0.0), template="refined", evaluations=0)


def test_mdh_fixed_distances_give_back_the_joint_solution():
    xy, _ = rolled_sheet(frames=6, side=7)
    pairs = isometric.neighbour_pairs(xy[0], 6)
    rays = nrdepth.Camera(FOCAL, (0.0, 0.0)).rays(xy)
    joint, distances = _socp(rays, pairs, None)
    assert np.isclose(distances.sum(), len(pairs), rtol=1e-6)
    for t in (0, 3, 5):  # given the template distances, the frames are independent
        alone, _ = _socp(rays[t : t + 1], pairs, distances)
        np.testing.assert_allclose(alone[0], joint[t], rtol=1e-4)


@pytest.mark.parametrize("each_frame, every", [("program", 1), ("lengths", 2), ("mirror", 1)])
def test_mdh_is_reproducible_at_any_thread_count(monkeypatch, each_frame, every):
    xy, _ = rolled_sheet(frames=6, side=7)
    read = lambda: isometric.mdh_depths(xy, FOCAL, (0.0, 0.0), neighbours=6, keyframes=3, every=every, each_frame=each_frame)  # noqa: E731
    first = read()
    if each_frame == "lengths":  # every other frame solved: here every solved frame keeps its shape, so the refinement is what is read
        assert not np.array_equal(first, isometric.mdh_depths(xy, FOCAL, (0.0, 0.0), neighbours=6, keyframes=3, every=every))
    assert first.tobytes() == read().tobytes()
    monkeypatch.setattr(isometric.mdh.os, "cpu_count", lambda: 1)  # the frames outside the keyframes one after another
    assert first.tobytes() == read().tobytes()


def test_mdh_refined_is_the_same_at_one_and_two_blas_threads():
    # The refinement's solver takes norms and dot products of long vectors (here 12,900 strains), which a
    # threaded BLAS sums in an order set by its thread count: the same tracks must give the same bytes.
    script = (f"import sys; sys.path.insert(0, {str(Path(__file__).parent)!r}); import hashlib; "
              "from test_isometric import rolled_sheet, FOCAL; from nrdepth import isometric; "
              "xy, _ = rolled_sheet(frames=8, side=12, start=0.5); "
              "print(hashlib.sha1(isometric.mdh_depths(xy, FOCAL, (0.0, 0.0), keyframes=8, template='refined').tobytes()).hexdigest())")
    runs = [subprocess.Popen([sys.executable, "-c", script], env=dict(os.environ, OPENBLAS_NUM_THREADS=threads, OMP_NUM_THREADS=threads),
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for threads in ("1", "2")]  # side by side
    outputs = [run.communicate(timeout=600) for run in runs]
    assert all(run.returncode == 0 for run in runs), [err[-2000:] for _, err in outputs]
    digests = {out for out, _ in outputs}
    assert len(digests) == 1, digests


def test_track_grid_follows_a_shift():
    rng = np.random.default_rng(3)
    from scipy.ndimage import gaussian_filter

    texture = gaussian_filter(rng.random((160, 160)), 2.0)
    texture = np.rint(255 * (texture - texture.min()) / np.ptp(texture)).astype(np.uint8)
    video = np.stack([texture[20 - t : 120 - t, 20 - 2 * t : 120 - 2 * t] for t in range(5)])  # content moves +2 x, +1 y a frame
    mask = np.zeros(video.shape[1:], bool)
    mask[30:70, 30:70] = True
    xy = isometric.track_grid(video, mask, points=25)
    assert 16 <= xy.shape[1] <= 36
    assert mask[xy[0, :, 1].astype(int), xy[0, :, 0].astype(int)].all()
    np.testing.assert_allclose(xy[-1] - xy[0], np.broadcast_to([8.0, 4.0], xy[0].shape), atol=0.15)
    forward = isometric.track_grid(video, mask, points=25, backward=False)  # the forward flow alone follows it too
    np.testing.assert_allclose(forward[-1] - forward[0], np.broadcast_to([8.0, 4.0], xy[0].shape), atol=0.15)
    assert not np.array_equal(forward, xy)  # and the backward flow took part
    assert np.array_equal(isometric.track_points(video, xy[0]), xy)  # the grid's points, followed by track_points
    anywhere = np.array([[37.3, 41.9], [55.5, 33.1]])
    np.testing.assert_allclose(isometric.track_points(video, anywhere)[-1] - anywhere, [[8.0, 4.0]] * 2, atol=0.15)


@pytest.mark.parametrize("hold", [False, True])
def test_a_stride_tracks_every_nth_frame_and_the_last_as_alone_and_is_linear_between(hold):
    video = shifted_texture(frames=8)  # content moves +2 x, +1 y a frame: linear in time
    mask = np.zeros(video.shape[1:], bool)
    mask[30:70, 30:70] = True
    every = isometric.track_grid(video, mask, points=25, drop=0.2, hold=hold)
    strided = isometric.track_grid(video, mask, points=25, drop=0.2, hold=hold, stride=3)
    tracked = [0, 3, 6, 7]  # every third frame and the last
    # The tracked frames are what the tracker gives those frames alone, to the bit; the drop ranks the same steps.
    assert strided.shape == every.shape
    assert np.array_equal(strided[tracked], isometric.track_grid(video[tracked], mask, points=25, drop=0.2, hold=hold))
    np.testing.assert_allclose(strided[1:3], strided[:1] + np.array([[1], [2]])[..., None] / 3 * (strided[3] - strided[0]), atol=1e-12)
    np.testing.assert_allclose(strided - strided[:1], every - every[:1], atol=0.2)  # and they follow the shift as every frame's do
    streamed = isometric.track_grid(iter(list(video)), mask, points=25, drop=0.2, hold=hold, stride=3)
    assert np.array_equal(streamed, strided)
    ending = isometric.track_grid(video[:7], mask, points=25, drop=0.2, hold=hold, stride=3)  # the last is a stride's: 0, 3, 6 alone
    assert np.array_equal(ending[[0, 3, 6]], isometric.track_grid(video[[0, 3, 6]], mask, points=25, drop=0.2, hold=hold))
    with pytest.raises(ValueError, match="stride"):
        isometric.track_grid(video, mask, points=25, stride=0)


def test_a_strided_track_is_nan_between_where_either_end_is():
    xy = np.array([[[0.0, 0.0], [1.0, 1.0]], [[2.0, 4.0], [np.nan, np.nan]]])
    filled = isometric.points._every_frame(xy, [0, 2])
    np.testing.assert_array_equal(filled[:, 0], [[0.0, 0.0], [1.0, 2.0], [2.0, 4.0]])
    assert np.array_equal(filled[0, 1], [1.0, 1.0]) and np.isnan(filled[1:, 1]).all()


def shifted_texture(frames: int = 5, size: int = 160, window: int = 100, blank: int = 0) -> np.ndarray:
    """A smooth random texture whose content moves +2 x, +1 y a frame, (T, window, window) uint8;
    its first ``blank`` columns (of the first frame) a flat gray, as blank paper."""
    from scipy.ndimage import gaussian_filter

    texture = gaussian_filter(np.random.default_rng(3).random((size, size)), 2.0)
    texture = np.rint(255 * (texture - texture.min()) / np.ptp(texture)).astype(np.uint8)
    if blank:
        texture[:, : 20 + blank] = 200
    return np.stack([texture[20 - t : 20 + window - t, 20 - 2 * t : 20 + window - 2 * t] for t in range(frames)])


def test_a_truth_point_off_its_own_look_is_found_and_the_rest_look_like_themselves():
    """``bench_tracks.truth_looks``: a tracker's distance from a truth point that no longer looks like itself is the truth's error."""
    sys.path.insert(0, str(Path(__file__).parents[1] / "benchmarks"))
    from bench_tracks import truth_looks

    video = shifted_texture(frames=5)  # the content moves +2 x, +1 y a frame
    x, y = np.meshgrid(np.arange(25.0, 80, 9), np.arange(25.0, 80, 9))
    uv = np.stack([np.stack([x.ravel() + 2 * t, y.ravel() + t], axis=1) for t in range(5)])
    off = uv.copy()
    off[3, 17] += (5.0, -4.0)  # one truth point a few pixels off the texture's point
    looks, off_looks = truth_looks(video, uv), truth_looks(video, off)
    assert looks.min() > 0.95 and np.array_equal(looks[0], np.ones(len(uv[0])))
    assert off_looks[3, 17] < 0.5
    assert np.delete(off_looks[3], 17).min() > 0.9  # its neighbours still look like themselves: only it is set aside


def test_the_flow_over_the_points_box_follows_as_the_whole_frames_does():
    video = shifted_texture()
    mask = np.zeros(video.shape[1:], bool)
    mask[30:60, 30:60] = True
    whole = isometric.track_grid(video, mask, points=16)
    boxed = isometric.track_grid(video, mask, points=16, margin=24)  # a margin past the flow's window: the same tracks
    np.testing.assert_allclose(boxed, whole, atol=0.01)
    assert not np.array_equal(boxed, whole)  # though the box did change the flow's input
    tight = isometric.track_grid(video, mask, points=16, margin=0)  # none: the box's edge pulls the flow
    assert np.abs(tight - whole).max() > 0.1
    dis = isometric.track_grid(video, mask, points=16, flow="dis", margin=24)  # DIS follows it too
    np.testing.assert_allclose(dis[-1] - dis[0], np.broadcast_to([8.0, 4.0], dis[0].shape), atol=0.25)
    with pytest.raises(ValueError, match="flow"):
        isometric.track_grid(video, mask, flow="lucas")
    with pytest.raises(ValueError, match="margin"):
        isometric.track_grid(video, mask, margin=-1)


def test_the_flow_on_shrunk_frames_moves_points_in_the_frames_own_pixels_and_held_points_land_where_they_would():
    video = shifted_texture(frames=6, size=200, window=140)
    mask = np.zeros(video.shape[1:], bool)
    mask[40:100, 40:100] = True
    for hold in (False, True):
        full = isometric.track_grid(video, mask, points=16, margin=24, hold=hold)
        half = isometric.track_grid(video, mask, points=16, margin=24, hold=hold, flow_scale=0.5)
        assert not np.array_equal(half, full)  # the flow did read other frames
        np.testing.assert_allclose(half[-1] - half[0], np.broadcast_to([10.0, 5.0], half[0].shape), atol=0.3)  # the field scaled back
        if hold:  # found again by their look at the frames' own size: where the full flow's would be
            np.testing.assert_allclose(half, full, atol=0.05)
    np.testing.assert_array_equal(isometric.track_grid(video, mask, points=16, flow_scale=1.0), isometric.track_grid(video, mask, points=16))
    for bad in (0, 1.5, "half", True):
        with pytest.raises(ValueError, match="flow_scale: expected a factor in"):
            isometric.track_grid(video, mask, flow_scale=bad)


class InPlace:
    """An executor that runs what it is given at once, in the caller's thread."""

    def __init__(self, workers):
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False

    def submit(self, function, *args):
        from concurrent.futures import Future

        done = Future()
        done.set_result(function(*args))
        return done


@pytest.mark.parametrize("flow", list(isometric.FLOWS))
def test_the_backward_flow_in_its_own_thread_gives_the_same_tracks_as_in_turn(monkeypatch, flow):
    video = shifted_texture(frames=8)
    mask = np.zeros(video.shape[1:], bool)
    mask[25:75, 25:75] = True
    threaded = isometric.track_grid(video, mask, points=36, flow=flow, drop=0.2, margin=24)
    monkeypatch.setattr(isometric.points, "ThreadPoolExecutor", InPlace)
    assert threaded.tobytes() == isometric.track_grid(video, mask, points=36, flow=flow, drop=0.2, margin=24).tobytes()


def bent_texture(frames: int = 24, size: int = 96, amplitude: float = 6.0) -> np.ndarray:
    """A smooth random texture bent by smooth random displacements (pixels,
    at most ``amplitude``) along a loop that ends where it began: the last
    frame is the first, (T, size, size) uint8."""
    import cv2
    from scipy.ndimage import gaussian_filter

    rng = np.random.default_rng(3)
    texture = gaussian_filter(rng.random((size, size)), 1.5)
    texture = (255 * (texture - texture.min()) / np.ptp(texture)).astype(np.float32)
    rows, cols = np.mgrid[0:size, 0:size].astype(np.float32)
    fields = [gaussian_filter(rng.standard_normal((size, size)), 12) for _ in range(4)]
    fields = [(f / np.abs(f).max()).astype(np.float32) for f in fields]
    video = []
    for t in range(frames):
        a, b = amplitude * np.sin(np.pi * t / (frames - 1)) ** 2, amplitude * np.sin(2 * np.pi * t / (frames - 1))
        dx, dy = a * fields[0] + b * fields[2], a * fields[1] + b * fields[3]
        video.append(cv2.remap(texture, (cols - dx).astype(np.float32), (rows - dy).astype(np.float32), cv2.INTER_CUBIC, borderMode=cv2.BORDER_REFLECT))
    return np.rint(np.stack(video)).clip(0, 255).astype(np.uint8)


def test_held_points_come_back_where_a_loop_ends_and_the_chained_flow_drifts():
    video = bent_texture()
    np.testing.assert_array_equal(video[-1], video[0])
    mask = np.zeros(video.shape[1:], bool)
    mask[24:72, 24:72] = True
    chained = isometric.track_grid(video, mask, points=25)
    held = isometric.track_grid(video, mask, points=25, hold=True)
    assert np.isfinite(held).all()  # nothing hidden, nothing lost
    assert np.median(np.linalg.norm(chained[-1] - chained[0], axis=1)) > 0.05  # the chained flow's drift adds up...
    assert np.linalg.norm(held[-1] - held[0], axis=1).max() < 0.05  # ...the held points' does not
    forward = isometric.track_grid(video, mask, points=25, hold=True, backward=False)  # held, the forward flow is enough
    assert np.linalg.norm(forward[-1] - forward[0], axis=1).max() < 0.05
    quick = isometric.track_grid(video, mask, points=25, hold=True, flow="farneback2")  # and so is a flow of fewer iterations
    assert np.isfinite(quick).all() and np.linalg.norm(quick[-1] - quick[0], axis=1).max() < 0.05


def test_a_held_point_hidden_is_lost_not_dragged_and_found_again():
    video = shifted_texture(frames=9).copy()  # the content moves +2 x, +1 y a frame
    mask = np.zeros(video.shape[1:], bool)
    mask[20:80, 20:80] = True
    card = np.array([57.0, 53.0])  # a flat grey card, 30 px square, in front of the sheet for three frames
    video[3:6, 38:68, 42:72] = 128
    start = isometric.start_grid(mask, video.shape[1:], points=36)
    truth = start + np.arange(9)[:, None, None] * np.array([2.0, 1.0])
    held = isometric.track_points(video, start, hold=True)
    for t in range(3, 6):
        behind = (np.abs(truth[t] - card) < 8).all(axis=1)  # most of the point's window covered
        clear = (np.abs(truth[t] - card) > 15 + 10).any(axis=1)  # none of it
        assert behind.any() and np.isnan(held[t, behind]).all()  # hidden: NaN, not dragged
        assert clear.any()
        np.testing.assert_allclose(held[t, clear], truth[t, clear], atol=0.25)
    np.testing.assert_allclose(held[6], truth[6], atol=0.25)  # the card gone, every point is found again
    after = np.isfinite(held[6:, :, 0])  # later, a point whose way back misses by more than HOLD_FB is lost there, not dragged
    assert after.mean() >= 0.95
    np.testing.assert_allclose(held[6:][after], truth[6:][after], atol=0.25)
    chained = isometric.track_points(video, start)
    assert np.isfinite(chained[3:6]).all() and np.abs(chained[6:] - truth[6:]).max() > 1.0  # the flow alone drags them


def test_the_held_share_counts_points_gone_from_view_apart_from_points_lost():
    from nrdepth.isometric import held_share

    video = shifted_texture(frames=9)  # the content moves +2 x, +1 y a frame: points near the right edge leave
    mask = np.zeros(video.shape[1:], bool)
    mask[30:60, 70:96] = True
    xy = isometric.track_grid(video, mask, points=16, hold=True)
    assert np.isnan(xy[-1]).any()  # gone past the edge
    assert held_share(xy, video.shape[1:]) == 1.0  # but every point in view was held
    noise = np.random.default_rng(0).integers(0, 256, (6, 64, 64), dtype=np.uint8)  # nothing stays from frame to frame
    assert held_share(isometric.track_grid(noise, points=16, hold=True), noise.shape[1:]) < 0.2


def test_points_on_blank_paper_are_rarely_held_and_points_on_print_always():
    from nrdepth.isometric import held_share, point_held_shares

    video = shifted_texture(frames=9, window=140, blank=60)  # the sheet's left 60 columns blank, the rest textured, moving together
    xy = isometric.track_grid(video, points=49, hold=True)
    share = point_held_shares(xy, video.shape[1:])
    counted = isometric.inside(xy[0], video.shape[1:], HOLD_WINDOW)  # the others, if never held, count as gone from view
    blank, printed = counted & (xy[0, :, 0] < 60 - 12), counted & (xy[0, :, 0] > 60 + 12)  # windows clear of the boundary
    assert blank.sum() >= 4 and printed.sum() >= 4
    assert (share[blank] <= 0.2).all() and (share[printed] == 1.0).all()
    assert held_share(xy, video.shape[1:]) < share[printed].mean()  # the whole video's share counts the blank points too
    for bad in (xy[0], np.zeros((0, 4, 2)), xy[..., :1]):
        with pytest.raises(ValueError, match="xy: expected tracks"):
            point_held_shares(bad, video.shape[1:])


def test_bridged_gaps_agree_with_filling_each_short_gap_by_hand():
    """Each gap of at most ``frames`` NaN frames between two found is filled linearly in time, point by point; a longer gap, one
    before a point's first frame found or after its last (out of view), and the found frames stay as they were."""
    rng = np.random.default_rng(5)
    for _ in range(200):
        T, n, frames = int(rng.integers(1, 14)), int(rng.integers(1, 5)), int(rng.integers(0, 5))
        xy = rng.normal(size=(T, n, 2))
        xy[rng.random((T, n)) < 0.45] = np.nan
        by_hand = xy.copy()
        for p in range(n):
            found = [t for t in range(T) if np.isfinite(xy[t, p]).all()]
            for a, b in zip(found, found[1:]):
                if b - a - 1 <= frames:
                    for t in range(a + 1, b):
                        by_hand[t, p] = xy[a, p] + (t - a) / (b - a) * (xy[b, p] - xy[a, p])
        np.testing.assert_allclose(isometric.bridge_gaps(xy, frames), by_hand, rtol=0, atol=1e-12)
    line = np.arange(6.0)[:, None, None] * np.array([[2.0, -1.0]])
    gapped = line.copy()
    gapped[2:4] = np.nan
    np.testing.assert_allclose(isometric.bridge_gaps(gapped, 2), line)  # a point moving steadily is given back exactly
    assert np.isnan(isometric.bridge_gaps(gapped, 1)[2:4]).all()
    for bad, frames, match in ((line[0], 1, "xy: expected tracks"), (line, -1, "frames: expected"), (line, 1.5, "frames: expected")):
        with pytest.raises(ValueError, match=match):
            isometric.bridge_gaps(bad, frames)


def test_held_points_beside_blank_paper_are_not_pulled_by_its_flow():
    """The warp that pulls each frame back is fitted to the points held in the frame before: the flow's guesses on blank paper, where
    no point is found again, would bend it, and the points held beside it would be found through a bent warp (up to 1.2 px off)."""
    video = shifted_texture(frames=9, window=140, blank=60)  # the left 60 columns blank paper, moving with the print
    start = isometric.start_grid(None, video.shape[1:], points=49)
    truth = start + np.arange(9)[:, None, None] * np.array([2.0, 1.0])
    held = isometric.track_points(video, start, hold=True)
    beside = start[:, 0] >= 60  # windows at least half on the print, the nearest 10 px from the blank paper
    found = np.isfinite(held[:, beside]).all(axis=2)
    in_view = np.stack([isometric.inside(frame, video.shape[1:], HOLD_WINDOW) for frame in truth[:, beside]])
    assert found[in_view].all()  # every point whose window is in view is found (near the edge a point may be lost)
    assert np.linalg.norm(held[:, beside] - truth[:, beside], axis=2)[found].max() < 0.5


def test_the_warp_fitted_to_held_points_on_one_line_falls_back_to_every_point_not_a_singular_fit():
    """Where the points held in a frame lie on one line (a coloured-noise video once held just such a row), the affine moving
    least squares has no answer: the warp is fitted to every point instead of raising numpy's LinAlgError."""
    import cv2

    from nrdepth.isometric.hold import Anchor

    video = shifted_texture(frames=2, window=140)
    start = isometric.start_grid(None, video.shape[1:], points=49)
    anchor = Anchor(cv2, video[0], start, margin=48)
    row = np.isclose(start[:, 1], start[0, 1])  # the grid's first row: collinear
    assert row.sum() >= 3
    for fitted in (row, np.eye(len(start), dtype=bool)[0] | np.eye(len(start), dtype=bool)[1]):  # a line; two points
        anchor._fit(fitted)
        assert anchor.fitted.all() and np.isfinite(anchor.to_nodes).all()
    some = row | np.isclose(start[:, 0], start[0, 0])  # a row and a column span the plane: fitted as asked
    anchor._fit(some)
    np.testing.assert_array_equal(anchor.fitted, some)


def test_the_warp_gives_an_affine_map_of_its_points_back_even_where_only_one_point_reaches_a_node():
    """Four points held, one alone and three far off on a line (a coloured-noise video once held just these): at a node by the lone
    point the moments are singular in rounding, and solving them gave numpy's LinAlgError, or nearby a warp that moved a
    translation's nodes 0.3 px wrong. There the node takes its points' mean displacement: every translation comes back at every
    node, and an affine map wherever the moments are well conditioned."""
    from nrdepth.isometric.hold import AFFINE_KEPT, _mls, _weights

    anchors = np.array([[224, 236.8], [44.8, 249.6], [57.6, 249.6], [70.4, 249.6]])
    nodes = np.array([[224.0, 200.0], [60.0, 240.0], [120.0, 230.0], [224.0, 236.8]])
    shift, turn = np.array([3.0, -2.0]), np.array([[np.cos(0.2), -np.sin(0.2)], [np.sin(0.2), np.cos(0.2)]])
    alone = np.array([[1.0, 0.0, 0.0, 0.0]])  # one point's weight alone: moments of rank 1, which numpy refuses to solve
    for at, weights in ((nodes[:1], alone), (nodes, _weights(nodes, anchors, 18.2))):
        matrix, offset = _mls(at, anchors, weights)
        assert np.isfinite(matrix).all() and np.isfinite(offset).all()
        np.testing.assert_allclose(matrix @ (anchors + shift) + offset, at + shift, atol=1e-9)
    kept = (offset == 0).all(axis=1)
    assert kept[2] and not kept[0]  # the node among the points keeps the affine deformation, the one by the lone point does not
    np.testing.assert_allclose((matrix @ (anchors @ turn.T))[kept], (nodes @ turn.T)[kept], atol=AFFINE_KEPT * 10)


def test_points_placed_by_texture_go_on_the_print_with_their_windows_on_the_mask_and_follow_it():
    from nrdepth.isometric import start_texture

    video = shifted_texture(frames=5, window=140, blank=60)  # the left 60 columns blank paper, the rest print, moving together
    mask = np.zeros(video.shape[1:], bool)
    mask[10:130, 10:130] = True
    start = start_texture(video[0], mask, points=49)
    grid = isometric.start_grid(mask, video.shape[1:], points=49)
    assert (grid[:, 0] < 60).sum() >= 10  # the grid puts points on the blank paper...
    assert 20 <= len(start) <= 49 and (start[:, 0] > 60).all()  # ...texture only on the print
    assert (start >= 10 + 10).all() and (start <= 129 - 10).all()  # each 21-pixel window on the mask
    spacing = np.sqrt(mask.sum() / 49)
    distances = np.linalg.norm(start[:, None] - start[None], axis=2) + np.eye(len(start)) * 1e9
    assert distances.min() >= 0.7 * spacing - 1e-6
    xy = isometric.track_grid(video, mask, points=49, place="texture")
    np.testing.assert_array_equal(xy[0], start)
    np.testing.assert_allclose(xy[-1] - xy[0], np.broadcast_to([8.0, 4.0], xy[0].shape), atol=0.15)
    with pytest.raises(ValueError, match="mask: expected texture for at least 4 points"):
        start_texture(np.full((64, 64), 128, np.uint8))
    with pytest.raises(ValueError, match="place: expected one of"):
        isometric.track_grid(video, mask, place="corners")
    with pytest.raises(ValueError, match="first: expected a \\(H, W\\) uint8"):
        start_texture(video)
    with pytest.raises(ValueError, match="window: expected an int >= 3"):
        start_texture(video[0], mask, window=0)


def test_a_stream_of_frames_is_followed_as_the_array_is():
    video = shifted_texture(frames=6)
    mask = np.zeros(video.shape[1:], bool)
    mask[30:60, 30:60] = True
    whole = isometric.track_grid(video, mask, points=16, drop=0.25, margin=24)
    streamed = isometric.track_grid((frame for frame in video), mask, points=16, drop=0.25, margin=24)
    np.testing.assert_array_equal(streamed, whole)
    with pytest.raises(ValueError, match="video: expected uint8 frames of the first one's shape .* at frame 3"):
        isometric.track_grid(iter([*video[:3], video[3, :50]]), mask, points=16)
    with pytest.raises(ValueError, match="video: expected at least 2 frames"):
        isometric.track_grid(iter(video[:1]), mask, points=16)
    with pytest.raises(ValueError, match="video: expected .* got nothing first"):
        isometric.track_grid(iter([]), mask, points=16)


def test_mdh_every_nth_frame_solves_those_and_is_linear_in_time_between():
    xy, _ = rolled_sheet(frames=9)
    xy[6:, :3] = np.nan  # three points leave the view from frame 6
    every_frame = isometric.mdh_depths(xy, FOCAL, (0.0, 0.0), neighbours=8, keyframes=3)
    third = isometric.mdh_depths(xy, FOCAL, (0.0, 0.0), neighbours=8, keyframes=3, every=3)
    solved = [0, 3, 4, 6, 8]  # every third, the keyframes (0, 4, 8) and the last
    np.testing.assert_array_equal(third[solved], every_frame[solved])
    np.testing.assert_allclose(third[1], (2 * third[0] + third[3]) / 3)
    np.testing.assert_allclose(third[5, 3:], (third[4, 3:] + third[6, 3:]) / 2)
    np.testing.assert_array_equal(third[5, :3], third[4, :3])  # in view at 4 only: the nearer solved frame's
    assert np.isnan(third[7, :3]).all()
    with pytest.raises(ValueError, match="every"):
        isometric.mdh_depths(xy, FOCAL, (0.0, 0.0), every=0)


def test_track_points_loses_a_point_that_leaves_the_frame():
    rng = np.random.default_rng(6)
    from scipy.ndimage import gaussian_filter

    texture = gaussian_filter(rng.random((100, 140)), 2.0)
    texture = np.rint(255 * (texture - texture.min()) / np.ptp(texture)).astype(np.uint8)
    video = np.stack([texture[:, 40 - 4 * t : 140 - 4 * t] for t in range(7)])  # content moves +4 x a frame
    start = np.array([[30.0, 50.0], [81.0, 40.0], [81.0, 60.0]])  # the last two at 85, 89, 93, 97, then out at 101
    xy, apart = isometric.track_points(video, start, disagreement=True)
    np.testing.assert_allclose(xy[:, 0] - start[0], [[4.0 * t, 0.0] for t in range(7)], atol=0.15)  # the one inside follows
    np.testing.assert_allclose(xy[:5, 1:, 0] - 81.0, np.broadcast_to(4.0 * np.arange(5)[:, None], (5, 2)), atol=0.25)
    assert np.isnan(xy[5:, 1:]).all() and np.isfinite(xy[:5]).all()  # lost for good from the frame it leaves
    assert np.isfinite(apart).all()  # the flows' disagreement over the steps in view
    near = isometric.track_points(video, start, border=5.0)  # within 5 pixels of the edge counts as gone
    assert np.isfinite(near[:4, 1:]).all() and np.isnan(near[4:, 1:]).all()
    with pytest.raises(ValueError, match="border"):
        isometric.track_points(video, start, border=-1.0)
    # Out of view the point binds nothing: the frame reads as if it had never been tracked.
    sheet, _ = rolled_sheet(frames=6, side=7)
    pairs = isometric.neighbour_pairs(sheet[0], 6)
    distances = np.linalg.norm(nrdepth.Camera(FOCAL, (0.0, 0.0)).rays(sheet)[0, pairs[:, 0]] - nrdepth.Camera(FOCAL, (0.0, 0.0)).rays(sheet)[0, pairs[:, 1]], axis=1)
    gone = np.array([0, 1, 7])  # a corner of the sheet, out of view from frame 3
    lost = sheet.copy()
    lost[3:, gone] = np.nan
    depth = isometric.mdh_depths(lost, FOCAL, (0.0, 0.0), pairs=pairs, template=distances)
    assert np.isnan(depth[3:, gone]).all() and np.isfinite(np.delete(depth, gone, axis=1)).all() and np.isfinite(depth[:3]).all()
    rest = np.setdiff1d(np.arange(sheet.shape[1]), gone)
    ties = ~np.isin(pairs, gone).any(axis=1)
    renumbered = np.searchsorted(rest, pairs[ties])
    without = isometric.mdh_depths(sheet[:, rest], FOCAL, (0.0, 0.0), pairs=renumbered, template=distances[ties])
    np.testing.assert_allclose(depth[3:, rest], without[3:], rtol=1e-5)
    joint = isometric.mdh_depths(lost, FOCAL, (0.0, 0.0), neighbours=6, keyframes=3, template="refined")
    assert np.array_equal(np.isnan(joint), np.isnan(lost[..., 0]))
    dense = densify(lost, depth, (6, 40, 40))
    np.testing.assert_array_equal(dense[4], densify(sheet[:, rest], depth[:, rest], (6, 40, 40))[4])
    few = sheet.copy()
    few[2:, 2:] = np.nan  # two points left in view from frame 2
    with pytest.raises(ValueError, match=r"xy: expected at least 3 points in view .* frames \[2, 3, 4, 5\]"):
        isometric.mdh_depths(few, FOCAL, (0.0, 0.0), neighbours=6)
    with pytest.raises(ValueError, match="finite in the first frame"):
        isometric.mdh_depths(few[2:], FOCAL, (0.0, 0.0), neighbours=6)
    with pytest.raises(ValueError, match="values"):
        densify(lost, np.where(np.arange(sheet.shape[1]) > 1, np.nan, depth), (6, 40, 40))


def test_track_grid_drops_the_points_where_the_motion_breaks():
    rng = np.random.default_rng(4)
    from scipy.ndimage import gaussian_filter

    def texture(size):
        image = gaussian_filter(rng.random((size, size)), 1.5)
        return np.rint(255 * (image - image.min()) / np.ptp(image)).astype(np.uint8)

    background, sheet = texture(96), texture(40)
    video = []
    for t in range(6):  # a textured square slides +2 x a frame over a still textured background
        frame = background.copy()
        frame[28:68, 20 + 2 * t : 60 + 2 * t] = sheet
        video.append(frame)
    video = np.stack(video)
    xy, apart = isometric.track_points(video, isometric.track_grid(video, points=144)[0], disagreement=True)
    assert np.array_equal(xy, isometric.track_grid(video, points=144))  # the same tracks, with or without it
    inside = (xy[0, :, 0] > 20) & (xy[0, :, 0] < 60) & (xy[0, :, 1] > 28) & (xy[0, :, 1] < 68)
    truth = xy[0] + np.where(inside[:, None], [10.0, 0.0], [0.0, 0.0])
    error = np.linalg.norm(xy[-1] - truth, axis=1)
    kept = isometric.track_grid(video, points=144, drop=0.25)
    rows = [int(np.flatnonzero((xy[0] == p).all(axis=1))[0]) for p in kept[0]]
    assert kept.shape[1] == len(xy[0]) - round(0.25 * len(xy[0])) and rows == sorted(rows)
    assert np.array_equal(kept, xy[:, rows])  # a subset of the tracks, in their order
    left_out = np.setdiff1d(np.arange(len(xy[0])), rows)
    assert apart[left_out].min() >= apart[rows].max()  # the flows disagree most on the points left out
    assert least_disagreeing(np.array([3.0, 1.0, 3.0, 0.0]), 0.25).tolist() == [0, 1, 3]  # of two equal, the later goes
    assert error[left_out].mean() > 3 * error[rows].mean()  # the points left out are the ones the flow dragged
    border = np.minimum.reduce([abs(xy[0, :, 0] - 20), abs(xy[0, :, 0] - 60), abs(xy[0, :, 1] - 28), abs(xy[0, :, 1] - 68)])
    assert border[left_out].mean() < border[rows].mean()  # near where the motion breaks
    # Held, the forward flow alone: where it takes each point against where the hold finds it picks them instead.
    held, guessed = isometric.track_points(video, xy[0], backward=False, hold=True, disagreement=True)
    kept = isometric.track_grid(video, points=144, drop=0.25, hold=True, backward=False)
    rows = [int(np.flatnonzero((held[0] == p).all(axis=1))[0]) for p in kept[0]]
    assert np.array_equal(kept, held[:, rows], equal_nan=True)
    left_out = np.setdiff1d(np.arange(len(held[0])), rows)
    assert guessed[left_out].min() >= guessed[rows].max() and border[left_out].mean() < border[rows].mean()
    with pytest.raises(ValueError, match="drop"):
        isometric.track_grid(video, drop=1.0)
    with pytest.raises(ValueError, match="drop"):
        isometric.track_grid(video, drop=0.2, backward=False)
    with pytest.raises(ValueError, match="disagreement"):
        isometric.track_points(video, xy[0], backward=False, disagreement=True)


def test_track_grid_is_the_same_at_any_thread_count():
    import cv2

    rng = np.random.default_rng(5)
    video = np.stack([np.roll(rng.integers(0, 256, (48, 64), dtype=np.uint8), t, axis=1) for t in range(3)])
    threads = cv2.getNumThreads()
    try:
        cv2.setNumThreads(1)
        one = isometric.track_grid(video, points=30)
        cv2.setNumThreads(4)
        four = isometric.track_grid(video, points=30)
    finally:
        cv2.setNumThreads(threads)
    assert one.tobytes() == four.tobytes()


def test_fuse_is_gbr_invariant_and_spans_its_inputs():
    from nrdepth.scores.metrics import gbr_design, gbr_fit

    rng = np.random.default_rng(0)
    depth, iso = rng.normal(size=(2, 3, 24, 32))
    rows, cols = np.mgrid[0:24, 0:32]
    tilt = rng.normal(size=(3, 3, 1, 1))
    planes = tilt[0] * cols + tilt[1] * rows + tilt[2]  # a plane per frame
    # one λ for the video (the sign turned), a plane per frame: the video's GBR, which "video" ignores
    warped = planes - 3.0 * depth
    np.testing.assert_allclose(isometric.fuse(warped, iso, 4.0, relief="video"), isometric.fuse(depth, iso, 4.0, relief="video"), atol=1e-9)
    # a λ per frame: a GBR per frame, which "frame" ignores
    warped = planes + np.array([-3.0, 0.5, 2.0])[:, None, None] * depth
    np.testing.assert_allclose(isometric.fuse(warped, iso, 4.0), isometric.fuse(depth, iso, 4.0), atol=1e-9)
    np.testing.assert_array_equal(isometric.fuse(depth, iso, 0.0), iso)
    # far above the frame's size the fusion is the network's depth fitted to the isometric one
    each = [gbr_fit(d, i) for d, i in zip(depth, iso)]
    shared = np.median([fit[2] for fit in each])
    by_frame = np.stack([(gbr_design(d) @ fit).reshape(d.shape) for d, fit in zip(depth, each)])
    np.testing.assert_allclose(isometric.fuse(depth, iso, 1e4), by_frame, atol=1e-6)
    video = isometric.fuse(depth, iso, 1e4, relief="video") - shared * depth  # one λ, the median of the frames': a plane per frame is left
    for frame in video:
        plane = np.column_stack([cols.ravel(), rows.ravel(), np.ones(cols.size)])
        np.testing.assert_allclose(plane @ np.linalg.lstsq(plane, frame.ravel(), rcond=None)[0], frame.ravel(), atol=1e-6)
    # against scipy's direct Gaussian, the mask's outside left out (normalised convolution)
    from scipy.ndimage import gaussian_filter

    mask = np.ones(depth.shape, bool)
    mask[:, :6, :10] = False
    mask[1, 20:, 25:] = False  # a frame's own mask between two that share one: each is weighed by its own
    aligned = [(gbr_design(d) @ gbr_fit(d, i, m)).reshape(d.shape) for d, i, m in zip(depth, iso, mask)]
    smooth = lambda a: gaussian_filter(a, 2.0, mode="constant", truncate=8.0)  # noqa: E731
    brute = [a + smooth(np.where(m, i - a, 0.0)) / smooth(m.astype(float)) for a, i, m in zip(aligned, iso, mask)]
    np.testing.assert_allclose(isometric.fuse(depth, iso, 2.0, mask=mask), brute, atol=1e-6)  # the FFT pads by 4σ


def test_densify_agrees_with_brute_force():
    from scipy.interpolate import griddata

    rng = np.random.default_rng(5)
    for n, frame in ((12, (36, 48)), (300, (90, 70))):  # a few points, and more than the pixels of a row
        xy = rng.uniform(8, 40, (3, n, 2)) * np.array(frame[::-1]) / 48
        values = rng.normal(size=(3, n))
        xy[1, 4] = np.nan  # out of view in one frame: no part in it
        dense = densify(xy, values, (3,) + frame)
        rows, cols = np.mgrid[0 : frame[0], 0 : frame[1]]
        for t in range(3):
            seen = np.isfinite(xy[t]).all(axis=1)
            linear = griddata(xy[t, seen], values[t, seen], (cols, rows), method="linear")  # inside the points' hull
            nearest = values[t, seen][np.argmin(np.linalg.norm(np.stack([cols, rows], -1)[..., None, :] - xy[t, seen], axis=-1), axis=-1)]
            np.testing.assert_allclose(dense[t], np.where(np.isnan(linear), nearest, linear), rtol=0, atol=1e-12)
    line = np.stack([np.linspace(5, 30, 6), np.linspace(2, 12, 6)], axis=1)[None]
    with pytest.raises(ValueError, match="xy: expected points in frame 0 that span the plane"):
        densify(line, np.ones((1, 6)), (1, 20, 20))


def test_neighbour_pairs_agree_with_brute_force():
    xy = np.random.default_rng(3).random((60, 2)) * 100
    order = np.argsort(np.linalg.norm(xy[:, None] - xy[None], axis=2), axis=1)  # column r: each point's rank-r nearest
    for neighbours, far, reach in ((6, 0, 0), (4, 5, 30), (5, 3, 200)):
        ranks = list(range(1, neighbours + 1)) + ([int(r) for r in np.rint(np.linspace(2 * neighbours, reach, far))] if far else [])
        ranks = [r for r in ranks if r < len(xy)]
        brute = {tuple(sorted((i, int(order[i, r])))) for i in range(len(xy)) for r in ranks}
        assert {tuple(p) for p in isometric.neighbour_pairs(xy, neighbours, far, reach)} == brute


def test_the_mirror_turns_the_bend_over_on_the_same_rays_and_keeps_a_plane():
    xy, truth = rolled_sheet()
    rays = nrdepth.Camera(FOCAL, (0.0, 0.0)).rays(xy[-1])
    points = rays * truth[-1, :, None]
    plane = np.linalg.lstsq(np.column_stack([points[:, :2], np.ones(len(points))]), points[:, 2], rcond=None)[0]
    height = lambda p: p[:, 2] - np.column_stack([p[:, :2], np.ones(len(p))]) @ plane  # noqa: E731
    mirrored = rays * isometric.mirror_depths(rays, truth[-1])[:, None]
    assert np.allclose(height(mirrored), -height(points), atol=1e-9)
    assert np.allclose(mirrored[:, :2] / mirrored[:, 2:], points[:, :2] / points[:, 2:])  # the same image
    flat = 4.0 / (1 - 0.3 * rays[:, 0] + 0.2 * rays[:, 1])  # the plane Z = 4 + 0.3 X − 0.2 Y along the rays
    assert np.allclose(isometric.mirror_depths(rays, flat), flat)
    assert not isometric.shape_kept(rays, truth[-1], isometric.mirror_depths(rays, truth[-1]))
    assert isometric.shape_kept(rays, truth[-1], 2 * truth[-1] * (1 + 0.01 * np.sin(np.arange(len(rays)))))
    assert isometric.shape_kept(rays, flat, truth[-1]) and isometric.shape_kept(rays, truth[-1], flat)  # a plane keeps any shape


def test_shape_kept_is_the_heights_correlation_against_a_threshold():
    xy, truth = rolled_sheet()
    rays = nrdepth.Camera(FOCAL, (0.0, 0.0)).rays(xy[-1])
    rng = np.random.default_rng(5)
    for wobble in (0.01, 0.05, 0.2):
        other = truth[-1] * (1 + wobble * rng.standard_normal(len(rays)))
        heights = [p[:, 2] - np.column_stack([p[:, :2], np.ones(len(p))]) @ np.linalg.lstsq(np.column_stack([p[:, :2], np.ones(len(p))]), p[:, 2], rcond=None)[0]
                   for p in (rays * truth[-1, :, None], rays * other[:, None])]
        correlation = np.corrcoef(*heights)[0, 1]  # brute force
        for threshold in (correlation - 1e-6, correlation + 1e-6):
            assert isometric.shape_kept(rays, truth[-1], other, threshold) is bool(threshold <= correlation)


def last_frame_with_lengths():
    """The rolled sheet (its image positions and depths), and its last frame's rays, 8 neighbours' pairs and their true distances."""
    xy, truth = rolled_sheet()
    rays = nrdepth.Camera(FOCAL, (0.0, 0.0)).rays(xy[-1])
    pairs = isometric.neighbour_pairs(xy[-1], 8)
    points = rays * truth[-1, :, None]
    return xy, truth, rays, pairs, np.linalg.norm(points[pairs[:, 0]] - points[pairs[:, 1]], axis=1)


def test_the_frame_that_keeps_its_lengths_is_the_truth_not_its_mirror():
    # Through a pinhole a bent sheet and its mirror differ: from either, keeping the pairs' lengths gives back the truth.
    xy, truth, rays, pairs, distances = last_frame_with_lengths()
    kept, strain = isometric.keep_lengths(rays, pairs, truth[-1] * (1 + 0.02 * np.sin(np.arange(len(rays)))), distances)
    assert strain < 1e-4 and np.allclose(kept, truth[-1], rtol=1e-3)
    for start, mirrored in ((truth[-1], False), (isometric.mirror_depths(rays, truth[-1]), True)):
        depths, was_mirror = isometric.mirror_or_not(rays, pairs, start, distances)
        assert was_mirror is mirrored and np.allclose(depths, truth[-1], rtol=1e-3)
    _, mirror_strain = isometric.keep_lengths(rays, pairs, isometric.mirror_depths(rays, truth[-1]), distances, evaluations=1)
    assert mirror_strain > 10 * strain  # the mirror does not keep them


def test_an_anchored_frame_minimises_strains_and_pull_together_and_stays_nearer_its_start():
    # Keeping the lengths of a frame that starts off the truth, with each depth pulled towards its start by each weight.
    xy, truth, rays, pairs, distances = last_frame_with_lengths()
    start = truth[-1] * (1 + 0.05 * np.sin(np.arange(len(rays))))

    def objective(z, anchor):
        strains = np.linalg.norm(z[pairs[:, 0], None] * rays[pairs[:, 0]] - z[pairs[:, 1], None] * rays[pairs[:, 1]], axis=1) / distances - 1
        return np.sum(strains**2) + anchor * np.sum(((z - start) / start.mean()) ** 2)

    anchors = (0.0, 1.0, 100.0, 1e6)
    kept = [isometric.keep_lengths(rays, pairs, start, distances, evaluations=500, anchor=a) for a in anchors]
    moved = [np.linalg.norm(z - start) for z, _ in kept]
    strains = [strain for _, strain in kept]
    assert all(a >= b for a, b in zip(moved, moved[1:])) and all(a <= b for a, b in zip(strains, strains[1:]))
    assert moved[-1] < 0.05 * moved[0] and strains[0] < 1e-4  # held at its start; free, the truth's lengths
    for a, (z, _) in zip(anchors, kept):  # each the least of its own objective, against the others' answers and the start
        assert all(objective(z, a) <= objective(other, a) * (1 + 1e-6) + 1e-12 for other in [start] + [y for y, _ in kept])
    for bad in (-1.0, float("nan"), "1"):
        with pytest.raises(ValueError, match="anchor"):
            isometric.keep_lengths(rays, pairs, start, distances, anchor=bad)
        with pytest.raises(ValueError, match="anchor"):
            isometric.mdh_depths(xy, FOCAL, (0.0, 0.0), each_frame="lengths", anchor=bad)
    for each_frame in ("program", "mirror"):  # an anchor only "lengths" would use is not silently ignored
        with pytest.raises(ValueError, match="anchor"):
            isometric.mdh_depths(xy, FOCAL, (0.0, 0.0), each_frame=each_frame, anchor=1.0)


def test_mdh_each_frame_keeps_the_lengths_the_program_only_bounds():
    xy, truth = rolled_sheet()
    # Every other frame solved: the nearly flat second frame, whose refinement does not keep its shape, is not among them.
    program = isometric.mdh_depths(xy, FOCAL, (0.0, 0.0), neighbours=8, keyframes=4, every=2)
    kept = isometric.mdh_depths(xy, FOCAL, (0.0, 0.0), neighbours=8, keyframes=4, every=2, each_frame="lengths")
    assert relief_error(kept, truth, xy)[2:].mean() < 0.7 * relief_error(program, truth, xy)[2:].mean()  # the bent frames
    # The program bends this roll the right way, so "mirror" takes the refinement from it in every frame, as "lengths" does.
    mirror = isometric.mdh_depths(xy, FOCAL, (0.0, 0.0), neighbours=8, keyframes=4, every=2, each_frame="mirror")
    assert np.array_equal(kept, mirror)
    with pytest.raises(ValueError, match="each_frame"):
        isometric.mdh_depths(xy, FOCAL, (0.0, 0.0), each_frame="best")


def test_mdh_lengths_refines_every_frame_or_none(monkeypatch):
    # Where a frame barely bends, keeping its lengths can bend it anew (the cloth's flat start): then no frame is refined,
    # so that the relief's depth does not jump between refined frames and the program's.
    from nrdepth.isometric import mdh

    xy, _ = rolled_sheet()
    rays = nrdepth.Camera(FOCAL, (0.0, 0.0)).rays(xy)
    program = isometric.mdh_depths(xy, FOCAL, (0.0, 0.0), neighbours=8, keyframes=4)
    mirror = isometric.mdh_depths(xy, FOCAL, (0.0, 0.0), neighbours=8, keyframes=4, each_frame="mirror")
    kept_shape = [isometric.shape_kept(r, p, m) for r, p, m in zip(rays, program, mirror)]
    assert 0 < sum(kept_shape) < len(xy)  # all solved here: the second frame's refinement turns its shape
    assert np.array_equal(isometric.mdh_depths(xy, FOCAL, (0.0, 0.0), neighbours=8, keyframes=4, each_frame="lengths"), program)
    # A refinement that keeps every frame's shape (here a scaling) is taken in every frame; one that turns any over, in none.
    monkeypatch.setattr(mdh, "keep_lengths", lambda rays, pairs, depths, distances, **_: (1.5 * depths, 0.0))
    assert np.array_equal(isometric.mdh_depths(xy, FOCAL, (0.0, 0.0), neighbours=8, keyframes=4, each_frame="lengths"), 1.5 * program)
    last_over = lambda rays, pairs, depths, distances, **_: (isometric.mirror_depths(rays, depths) if depths[0] == program[-1, 0] else 1.5 * depths, 0.0)
    monkeypatch.setattr(mdh, "keep_lengths", last_over)  # the last frame's turned over, every other scaled
    assert np.array_equal(isometric.mdh_depths(xy, FOCAL, (0.0, 0.0), neighbours=8, keyframes=4, each_frame="lengths"), program)


def test_bad_input_names_the_argument():
    xy, _ = rolled_sheet(frames=4, side=5)
    video = np.zeros((3, 32, 32), np.uint8)
    with pytest.raises(ValueError, match="focal"):
        isometric.mdh_depths(xy, -1.0, (0.0, 0.0))
    with pytest.raises(ValueError, match="focal"):
        isometric.mdh_depths(xy, (FOCAL, FOCAL, FOCAL), (0.0, 0.0))
    with pytest.raises(ValueError, match="centre"):
        isometric.mdh_depths(xy, FOCAL, (0.0,))
    with pytest.raises(ValueError, match="centre"):
        isometric.mdh_depths(xy, FOCAL, "middle")
    with pytest.raises(ValueError, match="xy"):
        isometric.mdh_depths(xy[..., 0], FOCAL, (0.0, 0.0))
    with pytest.raises(ValueError, match="pairs"):
        isometric.mdh_depths(xy, FOCAL, (0.0, 0.0), pairs=np.array([[0, 99]]))
    with pytest.raises(ValueError, match="keyframes"):
        isometric.mdh_depths(xy, FOCAL, (0.0, 0.0), keyframes=1)
    rays, pairs = np.column_stack([xy[0] / FOCAL, np.ones(len(xy[0]))]), isometric.neighbour_pairs(xy[0], 4)
    with pytest.raises(ValueError, match="rays"):
        isometric.mirror_depths(rays[:, :2], np.ones(len(rays)))
    with pytest.raises(ValueError, match="depths"):
        isometric.mirror_depths(rays, np.ones(len(rays) - 1))
    with pytest.raises(ValueError, match="depths: expected at least 3"):
        isometric.mirror_depths(rays, np.r_[1.0, 1.0, np.full(len(rays) - 2, np.nan)])
    with pytest.raises(ValueError, match="pairs"):
        isometric.keep_lengths(rays, pairs + len(rays), np.ones(len(rays)), np.ones(len(pairs)))
    with pytest.raises(ValueError, match="distances"):
        isometric.keep_lengths(rays, pairs, np.ones(len(rays)), -np.ones(len(pairs)))
    with pytest.raises(ValueError, match="evaluations"):
        isometric.mirror_or_not(rays, pairs, np.ones(len(rays)), np.ones(len(pairs)), evaluations=0)
    with pytest.raises(ValueError, match="other"):
        isometric.shape_kept(rays, np.ones(len(rays)), np.r_[np.nan, np.ones(len(rays) - 1)])
    with pytest.raises(ValueError, match="correlation"):
        isometric.shape_kept(rays, np.ones(len(rays)), np.ones(len(rays)), correlation=2.0)
    with pytest.raises(ValueError, match="correlation"):
        isometric.shape_kept(rays, np.ones(len(rays)), np.ones(len(rays)), correlation=True)
    with pytest.raises(ValueError, match="scale"):
        isometric.fuse(np.zeros((1, 8, 8)), np.zeros((1, 8, 8)), -1.0)
    with pytest.raises(ValueError, match="depth, isometric"):
        isometric.fuse(np.zeros((1, 8, 8)), np.zeros((1, 8, 9)), 1.0)
    with pytest.raises(ValueError, match="depth, isometric: expected finite"):
        isometric.fuse(np.full((1, 8, 8), np.nan), np.zeros((1, 8, 8)), 1.0)
    with pytest.raises(ValueError, match="relief"):
        isometric.fuse(np.zeros((1, 8, 8)), np.zeros((1, 8, 8)), 1.0, relief="pixel")
    with pytest.raises(ValueError, match="window"):
        isometric.track_grid(video, window=1)
    with pytest.raises(ValueError, match="start"):
        isometric.track_points(video, np.zeros((4, 3)))
    with pytest.raises(ValueError, match="hold: expected a bool"):
        isometric.track_grid(video, hold="yes")
    with pytest.raises(ValueError, match="far"):
        isometric.neighbour_pairs(xy[0], 4, far=-1)
    with pytest.raises(ValueError, match="reach"):
        isometric.neighbour_pairs(xy[0], 4, far=3, reach=5)


def test_pair_strain_agrees_with_brute_force_and_refined_reads_a_stretch_the_isometric_sheet_lacks():
    xy, truth = rolled_sheet(start=0.5)
    camera = nrdepth.Camera(FOCAL, (0.0, 0.0))
    pairs = isometric.neighbour_pairs(xy[0], 8)
    points = camera.rays(xy) * truth[..., None]
    distances = np.linalg.norm(points[0, pairs[:, 0]] - points[0, pairs[:, 1]], axis=1)
    turn = lambda a: np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])  # noqa: E731
    moved = np.stack([points[0] @ turn(a) + [0.1 * a, 0, a] for a in (0, 0.3, 0.6)])  # rigidly: every chord at its length
    assert isometric.pair_strain(FOCAL * moved[..., :2] / moved[..., 2:], moved[..., 2], camera, pairs, distances) < 1e-12
    # Each frame's depths scaled by s: its every chord by s, its every strain s − 1; a point out of view ties no pair.
    scaled = truth * np.linspace(0.9, 1.2, len(truth))[:, None]
    hidden = xy.copy()
    hidden[2, 5] = np.nan
    strains = [np.linalg.norm(scaled[t, i] * camera.rays(hidden[t, i]) - scaled[t, j] * camera.rays(hidden[t, j])) / d - 1
               for t in range(len(xy)) for (i, j), d in zip(pairs, distances) if np.isfinite(hidden[t, [i, j]]).all()]
    assert isometric.pair_strain(hidden, np.where(np.isfinite(hidden[..., 0]), scaled, np.nan), camera, pairs, distances) == pytest.approx(
        np.sqrt(np.mean(np.square(strains))), rel=1e-12)
    # refined's keyframes keep a rolling sheet's lengths, not those of one stretched 20 % across as it rolls
    stretch = 1 + 0.2 * np.linspace(0, 1, len(xy))[:, None, None] * np.array([1.0, 0.0, 0.0])
    grown = points * stretch + (1 - stretch) * points.mean(axis=1, keepdims=True)
    for sheet, expected in ((points, lambda s: s < 2e-3), (grown, lambda s: s > 1e-2)):
        image = FOCAL * sheet[..., :2] / sheet[..., 2:]
        depths, kept = isometric.mdh_depths(image, camera, neighbours=8, keyframes=4, template="refined", with_distances=True)
        keys = isometric.keyframe_indices(len(image), 4)
        strain = isometric.template_strain(image, depths, camera, kept, 4, 8)
        assert expected(strain) and strain == isometric.pair_strain(image[keys], depths[keys], camera, isometric.neighbour_pairs(image[0], 8), kept)
    with pytest.raises(ValueError, match="depths"):
        isometric.pair_strain(xy, truth[:, :3], camera, pairs, distances)
    with pytest.raises(ValueError, match="distances"):
        isometric.pair_strain(xy, truth, camera, pairs, distances[:3])


def test_the_focal_length_whose_refined_template_keeps_the_lengths_best_is_the_camera_s_at_any_thread_count(monkeypatch):
    xy, _ = rolled_sheet(start=0.2)
    estimate = isometric.estimate_focal(xy, (300, 300), (0.0, 0.0), keyframes=4)
    assert estimate.focal == pytest.approx(FOCAL, rel=0.03) and estimate.contrast > 3
    assert min(estimate.strains) == estimate.strain and len(estimate.focals) == isometric.focal.STEPS
    monkeypatch.setattr(os, "cpu_count", lambda: 1)  # one focal length after another
    assert isometric.estimate_focal(xy, (300, 300), (0.0, 0.0), keyframes=4) == estimate
    with pytest.raises(ValueError, match="xy"):
        isometric.estimate_focal(np.where(np.arange(xy.shape[1])[None, :, None] == 3, np.nan, xy), (300, 300))
    with pytest.raises(ValueError, match="views"):
        isometric.estimate_focal(xy, (300, 300), views=(90.0, 30.0))
    with pytest.raises(ValueError, match="steps"):
        isometric.estimate_focal(xy, (300, 300), steps=2)
    with pytest.raises(ValueError, match="evaluations"):
        isometric.estimate_focal(xy, (300, 300), evaluations=0)


def slowly_rolled_sheet(frames: int = 48, side: int = 9) -> np.ndarray:
    """Image positions (T, n, 2) of :func:`rolled_sheet`'s grid rolled and turned slowly, at most 3 px a frame."""
    s, v = (a.ravel() for a in np.meshgrid(np.linspace(-1, 1, side), np.linspace(-0.8, 0.8, side)))
    xy = []
    for t in range(frames):
        k = 0.2 + 0.8 * t / (frames - 1)
        x, z = np.sin(k * s) / k, (1 - np.cos(k * s)) / k
        a = 0.3 * np.sin(t / 8)
        x, z = np.cos(a) * x + np.sin(a) * z, -np.sin(a) * x + np.cos(a) * z
        points = np.stack([x, v + 0.01 * t, z + 4.0], axis=1)
        xy.append(FOCAL * points[:, :2] / points[:, 2:])
    return np.array(xy)


def test_tracks_smoothed_in_time_give_back_the_focal_length_that_the_trackers_noise_hides():
    xy = slowly_rolled_sheet()
    closer, gains = 0, []
    for seed in range(6):  # a property of the draws, not of one: a refinement's basin turns on small changes of its tracks
        noisy = xy + np.random.default_rng(seed).normal(0, 0.2, xy.shape)  # 0.2 px in every frame floors the strain and flattens its valley
        raw, smoothed = (isometric.estimate_focal(noisy, (300, 300), (0.0, 0.0), keyframes=4, smooth=s, evaluations=30) for s in (0, 1))
        closer += abs(smoothed.focal - FOCAL) < abs(raw.focal - FOCAL)
        gains.append(smoothed.contrast / raw.contrast)
    assert closer >= 5 and np.median(gains) > 2
    clean = isometric.estimate_focal(xy, (300, 300), (0.0, 0.0), keyframes=4, smooth=1, evaluations=30)  # the sheet's own motion barely blurred
    assert clean.focal == pytest.approx(FOCAL, rel=0.03) and clean.contrast > 3
    for bad in (-1.0, float("nan"), float("inf"), "1"):
        with pytest.raises(ValueError, match="smooth"):
            isometric.estimate_focal(xy, (300, 300), smooth=bad)


def test_a_refined_template_pulled_towards_its_cone_program_strays_less_the_harder_it_is_pulled():
    xy = slowly_rolled_sheet()[::12] + np.random.default_rng(1).normal(0, 0.2, (4, 81, 2))
    rays, pairs = nrdepth.Camera(FOCAL, (0.0, 0.0)).rays(xy), isometric.neighbour_pairs(xy[0], 8)
    program, _ = solve_template(rays, pairs)
    free = solve_template(rays, pairs, refined=True)
    assert all(np.array_equal(a, b) for a, b in zip(solve_template(rays, pairs, refined=True, anchor=0.0), free))
    strays = [np.abs(solve_template(rays, pairs, refined=True, anchor=a)[0] - program).mean() for a in (0.0, 0.01, 1.0)]
    assert strays[0] > strays[1] > strays[2]
    with pytest.raises(ValueError, match="anchor"):
        solve_template(rays, pairs, refined=True, anchor=-0.1)
    with pytest.raises(ValueError, match="anchor"):
        isometric.estimate_focal(xy, (300, 300), anchor=float("nan"))


def test_the_points_that_move_are_kept_and_the_backdrops_by_the_sheets_edge_left_out():
    xy, _ = rolled_sheet()
    T, n, _ = xy.shape
    backdrop = np.repeat(xy[:1, :4] + 3.0, T, axis=0)  # still, 3 px beside the sheet's first points
    edge = backdrop + np.linspace(0, 1.5, T)[:, None, None]  # by the edge: dragged a little, 1.5 px at most
    lost = np.full((T, 1, 2), np.nan)  # lost from the first frame on: never seen to move
    tracks = np.concatenate([xy, backdrop, edge, lost], axis=1)
    farthest = np.linalg.norm(xy - xy[:1], axis=2).max(axis=0)
    assert np.median(farthest) > 5 * 1.5  # the sheet moves far more than the edge's points
    kept = isometric.moving_points(tracks)
    np.testing.assert_array_equal(kept, np.r_[farthest >= 0.2 * np.median(farthest), np.zeros(9, bool)])
    assert kept[:n].mean() > 0.9
    np.testing.assert_array_equal(isometric.moving_points(tracks, share=0.0), np.r_[farthest >= 0.5, np.zeros(4, bool), np.ones(4, bool), False])
    assert not isometric.moving_points(backdrop).any()  # nothing moves: nothing kept
    for bad in ({"least": -1.0}, {"share": 1.5}, {"share": "a fifth"}):
        with pytest.raises(ValueError, match=f"^{next(iter(bad))}: expected"):
            isometric.moving_points(tracks, **bad)
    with pytest.raises(ValueError, match="^xy: expected"):
        isometric.moving_points(tracks[0])


def test_the_points_whose_pairs_keep_their_lengths_are_the_sheets_and_not_intruders_beside_it_whatever_the_noise():
    xy, _ = rolled_sheet()
    T, n, _ = xy.shape
    beside = xy[:1, [10, 40, 70]] + 4.0  # three intruders 4 px from sheet points, pairs with it that cannot keep their lengths
    intruders = {"still": np.repeat(beside, T, axis=0), "moving their own way": beside + np.arange(T)[:, None, None] * np.array([8.0, -6.0])}
    camera = nrdepth.Camera(FOCAL, (0.0, 0.0))
    for name, other in intruders.items():
        for seed in range(4):  # a tracker's error of 0.1 px: without any, the sheet's strain is rounding, and 3 times its median a few of them
            tracks = np.concatenate([xy, other], axis=1) + np.random.default_rng(seed).normal(0, 0.1, (T, n + 3, 2))
            # the strain alone can miss them (the refined template puts them at the camera or far behind, their pairs spanning
            # depth); their depth steps from their neighbours cannot
            kept = isometric.unstrained_points(tracks, camera, keyframes=8, jump=3.0)
            assert not kept[n:].any() and kept[:n].mean() >= 0.8, (name, seed)
    for jump in (None, 3.0):  # a sheet alone keeps all of its points
        assert isometric.unstrained_points(tracks[:, :n], camera, keyframes=8, jump=jump).all()
    np.testing.assert_array_equal(isometric.unstrained_points(tracks[:, :8], camera, neighbours=8), np.ones(8, bool))  # too few to tie: all kept
    with pytest.raises(ValueError, match="^xy: expected tracks"):
        isometric.unstrained_points(np.where(np.arange(n + 3)[None, :, None] == 3, np.nan, tracks), camera)
    with pytest.raises(ValueError, match="^factor: expected"):
        isometric.unstrained_points(tracks, camera, factor=0.5)
    with pytest.raises(ValueError, match="^passes: expected"):
        isometric.unstrained_points(tracks, camera, passes=0)
    for jump in (0.0, -1.0, np.inf, "3"):
        with pytest.raises(ValueError, match="^jump: expected"):
            isometric.unstrained_points(tracks, camera, jump=jump)


def test_each_points_median_over_its_pairs_agrees_with_brute_force():
    from nrdepth.isometric.found import _median_by_point

    rng = np.random.default_rng(5)
    for _ in range(50):
        n = int(rng.integers(1, 12))
        pairs = rng.integers(0, n, (int(rng.integers(1, 30)), 2))
        pairs = pairs[pairs[:, 0] != pairs[:, 1]]  # neighbour pairs never tie a point to itself
        values = rng.normal(size=len(pairs))
        brute = [np.median(values[(pairs == k).any(axis=1)]) if (pairs == k).any() else 0.0 for k in range(n)]
        np.testing.assert_allclose(_median_by_point(pairs, values, n), brute, rtol=0, atol=1e-15)

