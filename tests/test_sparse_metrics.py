"""The real videos' scores beside their references: the sparse-ground-truth
MAE (kinect_paper's fair score), its sign rate, and the shape-blind
references, each against what it must give on constructed truths."""

from __future__ import annotations

import numpy as np
import pytest

from nrdepth.scores.metrics import _bilinear, dense_baselines, sparse_baselines, sparse_mae, sparse_sign_rate


def scene(frames=3, points=50, seed=0):
    rng = np.random.default_rng(seed)
    h, w = 40, 60
    y, x = np.mgrid[0:h, 0:w]
    depth = np.stack([np.sin(0.2 * x + k) * np.cos(0.15 * y) + 0.01 * x * y for k in range(frames)])
    uv = np.stack([rng.uniform(0, w - 1, (frames, points)), rng.uniform(0, h - 1, (frames, points))], axis=1)
    return depth, uv


def test_a_gbr_of_the_sampled_depth_scores_zero_and_its_sign_is_read():
    depth, uv = scene()
    z = np.stack([2.0 * _bilinear(d, u, v) + 0.1 * u - 0.3 * v + 5 for d, (u, v) in zip(depth, uv)])
    assert sparse_mae(depth, uv, z) < 1e-9 and sparse_mae(-depth, uv, z) < 1e-9
    assert sparse_sign_rate(depth, uv, z) == 1.0 and sparse_sign_rate(-depth, uv, z) == 0.0
    noisy = z + np.random.default_rng(1).normal(0, 1, z.shape)
    assert 0.5 < sparse_mae(depth, uv, noisy) < 1.0  # E|N(0, 1)| = 0.80, less what the fit absorbs


def test_a_mask_keeps_only_its_points_and_bad_input_is_named():
    depth, uv = scene()
    z = np.stack([_bilinear(d, u, v) for d, (u, v) in zip(depth, uv)])
    z[:, :10] += 100.0  # outliers, masked out
    mask = np.ones(z.shape, bool)
    mask[:, :10] = False
    assert sparse_mae(depth, uv, z, mask=mask) < 1e-9 < sparse_mae(depth, uv, z)
    with pytest.raises(ValueError, match="^uv: points outside"):
        sparse_mae(depth, uv + 100, z)
    with pytest.raises(ValueError, match="^mask:"):
        sparse_mae(depth, uv, z, mask=np.zeros(z.shape, bool))
    with pytest.raises(ValueError, match="^uv, z:"):
        sparse_mae(depth, uv[:2], z)


def test_the_references_fit_what_they_can_and_only_that():
    _, uv = scene()
    u, v = uv[:, 0], uv[:, 1]
    bowl = 3.0 * ((u - 7) ** 2 + (v - 11) ** 2) + 0.5 * u + 2
    base = sparse_baselines(uv, bowl)
    assert base["bowl"] < 1e-6 and base["quadratic"] < 1e-6 and base["plane"] > 10
    saddle = u * v
    base = sparse_baselines(uv, saddle)
    assert base["quadratic"] < 1e-8 < base["bowl"]


def test_dense_references_fit_a_bowl_and_a_quadratic_exactly():
    t, h, w = 4, 30, 40
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    bowl = np.stack([(1 + k) * ((x - 5) ** 2 + (y - 9) ** 2) + k * x for k in range(t)])
    base = dense_baselines(bowl)
    assert base["bowl"] < 1e-9 and base["quadratic"] < 1e-9 and base["plane"] > 0.1
    saddle = np.stack([x * y + k * x for k in range(t)])
    mask = np.ones(saddle.shape, bool)
    mask[:, :5] = False
    base = dense_baselines(np.where(mask, saddle, np.nan), mask=mask)
    assert base["quadratic"] < 1e-9 < base["bowl"]
