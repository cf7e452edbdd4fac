"""NRSfM baselines: the benchmark's 3-D error, the camera upgrade, CSF2."""

from pathlib import Path

import numpy as np
import pytest

from nrdepth.baselines.nrsfm import _spaces, cameras, csf2, dct_basis, error_3d, kernel_basis, ksta

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "nrsfm"
PTA = {"drink": 0.0250, "pickup": 0.2369, "yoga": 0.1625, "stretch": 0.1088, "dance": 0.2956}


@pytest.mark.skipif(not DATA.is_dir(), reason="needs ../shared/data/nrsfm")
@pytest.mark.parametrize("name", sorted(PTA))
def test_error_3d_reproduces_the_published_pta_errors(name):
    from scipy.io import loadmat

    m = loadmat(DATA / f"{name}.mat")
    assert round(error_3d(m["Shat"] / float(np.squeeze(m["scale"])), m["S"]), 4) == PTA[name]


def rotations(T, seed=0):
    from scipy.spatial.transform import Rotation

    s = np.linspace(0, 1, T)
    rng = np.random.default_rng(seed)
    a = rng.uniform(0.5, 1.5, 3)
    return Rotation.from_rotvec(np.column_stack([a[0] * np.sin(3 * s), 2.5 * a[1] * s, a[2] * np.cos(2 * s)])).as_matrix()


def test_the_camera_upgrade_recovers_orthographic_cameras():
    T, n = 50, 15
    rng = np.random.default_rng(0)
    R = rotations(T)
    # A mean shape and a deformation mode with smooth weights: W has rank 6.
    shapes = rng.normal(size=(3, n))[None] + 0.3 * rng.normal(size=(3, n))[None] * np.sin(np.linspace(0, 3, T))[:, None, None]
    W = np.einsum("tab,tbn->tan", R[:, :2], shapes).reshape(2 * T, n)
    found = cameras(W).reshape(T, 2, 3)
    # Orthographic: rows of unit length and orthogonal, up to one global rotation of the true cameras.
    assert np.abs(np.einsum("tab,tcb->tac", found, found) - np.eye(2)).max() < 1e-6
    Y, *_ = np.linalg.lstsq(found.reshape(-1, 3), R[:, :2].reshape(-1, 3), rcond=None)
    assert np.abs(found.reshape(-1, 3) @ Y - R[:, :2].reshape(-1, 3)).max() < 2e-3


def deforming(T=40, n=12, seed=1):
    """World-frame shapes (T, 3, n): a mean shape plus two smooth deformation modes, and their tracks."""
    rng = np.random.default_rng(seed)
    s = np.linspace(0, 1, T)
    shapes = rng.normal(size=(3, n))[None] + 0.4 * np.sin(2 * s)[:, None, None] * rng.normal(size=(3, n)) + 0.3 * np.cos(3 * s)[:, None, None] * rng.normal(size=(3, n))
    return shapes, np.einsum("tab,tbn->tan", rotations(T, seed)[:, :2], shapes).reshape(2 * T, n)


def test_csf2_recovers_a_rigid_object_and_more_spaces_fit_a_deforming_one_better():
    T, n = 40, 12
    rigid = np.repeat(np.random.default_rng(3).normal(size=(1, 3, n)), T, axis=0)
    W = np.einsum("tab,tbn->tan", rotations(T, 3)[:, :2], rigid).reshape(2 * T, n)
    result = csf2(W, K=1, d=3)
    assert result.rmse < 1e-8 and error_3d(result.shapes, rigid.reshape(3 * T, n)) < 1e-6
    shapes, W = deforming(T, n)
    errors = [error_3d(csf2(W, K=K, d=6).shapes, shapes.reshape(3 * T, n)) for K in (1, 3)]
    assert errors[1] < 0.5 * errors[0], errors
    kernel = ksta(W, K=3, d=6)
    assert np.isfinite(kernel.shapes).all() and error_3d(kernel.shapes, shapes.reshape(3 * T, n)) < 0.5 * errors[0]


def test_the_kernel_basis_spans_smooth_functions_of_the_shape_space():
    s = np.linspace(0, 1, 30)
    points = np.column_stack([np.cos(2 * s), np.sin(2 * s)])
    B = kernel_basis(points, 5)
    assert B.shape == (30, 5) and np.isfinite(B).all()
    # A smooth function of the points is nearly in the basis's span.
    target = np.cos(3 * s)
    coeffs, *_ = np.linalg.lstsq(B, target, rcond=None)
    assert np.abs(B @ coeffs - target).max() < 0.1
    noise = np.random.default_rng(0).normal(size=30)
    coeffs, *_ = np.linalg.lstsq(B, noise, rcond=None)
    assert np.abs(B @ coeffs - noise).std() > 0.5 * noise.std()


def test_the_csf2_gradient_matches_finite_differences():
    # The descent uses the exact gradient of f = ‖R_K‖² / (4Tn); checked by finite differences.
    rng = np.random.default_rng(2)
    T, n, K, d = 10, 6, 3, 4
    Wc = rng.normal(size=(2 * T, n))
    Rs, B = rng.normal(size=(2 * T, 3)), dct_basis(T, d)
    X = rng.normal(size=(d, K))
    c = 1 / (2 * T * n)

    def f(X):
        return (_spaces(X, B, Rs, Wc)[3][-1] ** 2).sum() * c / 2

    numeric = np.zeros_like(X)
    for i in range(d):
        for k in range(K):
            e = np.zeros_like(X)
            e[i, k] = 1e-6
            numeric[i, k] = (f(X + e) - f(X - e)) / 2e-6
    # The gradient csf2's descent uses, from its own helper.
    from nrdepth.baselines import nrsfm

    Ms, pinvs, Ss, Rk = _spaces(X, B, Rs, Wc)
    Bnr = np.concatenate([np.repeat(B[:, i], 2)[:, None] * Rs for i in range(d)], axis=1).reshape(2 * T, d, 3)
    g = nrsfm._gradient(Bnr, Ms, pinvs, Ss, Rk, c)
    assert np.abs(g - numeric).max() < 1e-8 * max(1.0, np.abs(numeric).max()) + 1e-9


@pytest.mark.parametrize(
    "kwargs, name",
    [
        ({"W": np.zeros((5, 10))}, "W"),
        ({"W": np.full((8, 10), np.nan)}, "W"),
        ({"W": np.zeros((8, 3))}, "W"),
        ({"K": 0}, "K"),
        ({"K": 5, "d": 3}, "K"),
        ({"d": 11}, "d"),
        ({"Rs": np.zeros((4, 3))}, "Rs"),
        ({"start": np.zeros((2, 1))}, "start"),
    ],
)
def test_bad_input_is_named(kwargs, name):
    args = {"W": np.random.default_rng(0).normal(size=(20, 10)), "K": 1, "d": 3, **kwargs}
    with pytest.raises(ValueError, match=f"^{name}:"):
        csf2(**args)


def test_tracks_follow_the_vertices_and_dense_exact_depths_come_back():
    import nrdepth
    from nrdepth.baselines.tracks import clip_tracks, densify

    config = nrdepth.GeneratorConfig(size=64, frames=4, grid=32, texture_size=64)
    clip = nrdepth.generate_clips(1, seed=4, config=config)
    tracks = clip_tracks(clip.params[0], config, points=9)
    T, n, _ = tracks.xy.shape
    assert T == 4 and 20 <= n <= 81
    assert ((tracks.xy >= 0) & (tracks.xy <= 63)).all()
    # The rendered (ray-cast) depth at the pixel nearest a track is that vertex's depth, to the slope over half a pixel.
    nearest = np.rint(tracks.xy).astype(int)
    rendered = clip.depth[0][np.arange(T)[:, None], nearest[..., 1], nearest[..., 0]]
    assert np.abs(rendered - tracks.depth).max() < 0.02
    # Interpolating exact depths given at every pixel centre gives the depth map back.
    rows, cols = np.mgrid[0:64, 0:64]
    xy = np.broadcast_to(np.stack([cols.ravel(), rows.ravel()], -1).astype(float), (T, 64 * 64, 2))
    dense = densify(xy, clip.depth[0].reshape(T, -1), (T, 64, 64))
    assert np.abs(dense - clip.depth[0]).max() < 1e-6


def moving_texture_video(frames: int = 6, size: int = 96):
    """A smooth random texture under a known drifting rotation and scaling: (video, true position of a pixel of frame 0 in each frame)."""
    from scipy.ndimage import affine_transform, gaussian_filter

    texture = gaussian_filter(np.random.default_rng(7).random((size, size)), 1.5)
    texture = (texture - texture.min()) / np.ptp(texture)
    centre = np.array([size / 2, size / 2])
    warps = []
    for t in range(frames):
        angle, scale = 0.01 * t, 1 + 0.006 * t
        A = scale * np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])  # acts on (row, column)
        b = centre - A @ centre + np.array([0.7 * t, -0.45 * t])
        warps.append((A, b))
    # frame t at q shows texture at A⁻¹ (q − b): a texture point p moves to A p + b.
    video = np.stack([affine_transform(texture, np.linalg.inv(A), -np.linalg.inv(A) @ b, order=3, mode="reflect") for A, b in warps])

    def truth(xy0: np.ndarray) -> np.ndarray:
        rc = xy0[:, ::-1]
        return np.stack([(rc @ A.T + b)[:, ::-1] for A, b in warps])

    return np.rint(video.clip(0, 1) * 255).astype(np.uint8), truth


def test_tracked_corners_follow_a_known_motion_and_lost_points_are_dropped():
    from nrdepth.baselines.tracks import track_video

    video, truth = moving_texture_video()
    xy = track_video(video, max_points=200, mask=np.pad(np.ones((64, 64), bool), 16))
    error = np.linalg.norm(xy - truth(xy[0]), axis=-1)
    assert xy.shape[0] == 6 and xy.shape[1] >= 100
    assert np.median(error) < 0.1 and error.max() < 0.5
    # Points in a patch that goes blank halfway are gone; the rest keep their tracks.
    hidden = video.copy()
    hidden[3:, 20:50, 20:50] = 128
    kept = track_video(hidden, max_points=200, mask=np.pad(np.ones((64, 64), bool), 16))
    deep = np.abs(truth(kept[0])[3] - 35).max(axis=1) < 4  # a whole LK window (21 px) inside the blank square
    assert not deep.any() and (np.abs(truth(xy[0])[3] - 35).max(axis=1) < 4).any()
    assert 0.3 * xy.shape[1] < kept.shape[1] < xy.shape[1]
    with pytest.raises(ValueError, match="^frames:"):
        track_video(video.astype(np.float32))
    with pytest.raises(ValueError, match="^mask:"):
        track_video(video, mask=np.ones((5, 5), bool))
