"""COLA stitching: windows sum to one; GBR-distorted true patches stitch back
to the truth; any size works; reconstruct runs end to end."""

import json
import re

import numpy as np
import pytest
import torch

import nrdepth
import nrdepth.model
from nrdepth.scores.metrics import grid_contrast
from nrdepth.reconstruct.stitch import PATCH, TEMPORAL_WEIGHT


def smooth_video(shape, seed=0):
    rng = np.random.default_rng(seed)
    t, h, w = shape
    tt, yy, xx = np.meshgrid(np.arange(t) / 16, np.arange(h) / 64, np.arange(w) / 64, indexing="ij")
    z = np.zeros(shape)
    for _ in range(5):
        k = rng.normal(size=4) * 3
        z += np.sin(k[0] * xx + k[1] * yy + k[2] * tt + k[3])
    return z.astype(np.float32)


def cut(video, layout):
    back = [layout.padded[a] - layout.shape[a] - layout.pad[a] for a in range(3)]
    padded = np.pad(video, [(layout.pad[a], back[a]) for a in range(3)], mode="symmetric")
    lt, ly, lx = layout.patch
    return np.stack([padded[t : t + lt, y : y + ly, x : x + lx] for t, y, x in layout.origins])


def distorted_patches(truth, layout, seed=1):
    """The truth's patches, each frame of each seen through its own random GBR."""
    patches = cut(truth, layout)
    rng = np.random.default_rng(seed)
    ly, lx = PATCH[1:]
    yy, xx = np.mgrid[0:ly, 0:lx]
    for p in patches:
        for frame in p:
            # Slopes in depth units per pixel, like the surface's own.
            a, b, tau = rng.normal(size=3) * (0.05, 0.05, 2.0)
            frame[:] = a * xx + b * yy + rng.uniform(0.2, 5) * frame + tau
    return patches


@pytest.mark.parametrize("window", ["hann", "triangle"])
@pytest.mark.parametrize("alignment", ["joint", "coarse"])
@pytest.mark.parametrize("shape", [(16, 64, 64), (24, 100, 70), (9, 33, 130), (3, 20, 20)])
def test_gbr_distorted_true_patches_stitch_back_to_the_truth(shape, alignment, window):
    # Each frame of each patch under its own GBR: frames solved on their own
    # (the tie would hold a patch's GBRs together, which these patches'
    # arbitrary per-frame GBRs do not allow; the next test has it on).
    truth = smooth_video(shape, seed=sum(shape))
    layout = nrdepth.patch_layout(shape)
    patches = distorted_patches(truth, layout)
    out = nrdepth.stitch(patches, truth, layout, alignment=alignment, window=window, temporal_weight=0.0)
    assert out.shape == shape and out.dtype == np.float32
    assert nrdepth.mae_sn(out, truth) < 1e-3
    np.testing.assert_allclose(out, truth, atol=2e-3)


@pytest.mark.parametrize("window", ["hann", "triangle"])
@pytest.mark.parametrize("shape", [(40, 64, 64), (24, 100, 70), (9, 33, 130)])
def test_the_temporal_tie_keeps_a_consistent_reading_of_a_still_surface_exact(shape, window):
    # A still surface, each patch under one GBR for all its frames: the
    # frames of a patch are one reading, the GBRs that give back the truth
    # are the same in every frame, and the tie (at full strength, ρ = 1)
    # costs nothing.
    truth = np.repeat(smooth_video((1, *shape[1:]), seed=sum(shape)), shape[0], axis=0)
    layout = nrdepth.patch_layout(shape)
    patches = cut(truth, layout)
    rng = np.random.default_rng(5)
    yy, xx = np.mgrid[0 : PATCH[1], 0 : PATCH[2]]
    for p in patches:
        a, b, tau = rng.normal(size=3) * (0.05, 0.05, 2.0)
        p[:] = a * xx + b * yy + rng.uniform(0.2, 5) * (-1) ** rng.integers(2) * p + tau
    out = nrdepth.stitch(patches, truth, layout, window=window, temporal_weight=TEMPORAL_WEIGHT)
    np.testing.assert_allclose(out, truth, atol=2e-3)


def test_joint_alignment_recovers_from_the_patches_what_the_coarse_depth_lacks():
    # The coarse depth is a blurred, tilted, flattened guess; the patches are
    # the truth under random GBRs. Aligned on their own to the guess (the
    # paper), the patches inherit its errors; aligned jointly they agree with
    # one another, and at a small coarse weight give back the truth (frames
    # on their own: these patches' GBRs change arbitrarily frame to frame).
    shape = (16, 128, 160)
    truth = smooth_video(shape, seed=3)
    # Fine relief, which the blur below removes.
    truth = (truth + 0.3 * np.sin(np.arange(160) / 6.0)[None, None, :] * np.cos(np.arange(128) / 5.0)[None, :, None]).astype(np.float32)
    layout = nrdepth.patch_layout(shape)
    patches = distorted_patches(truth, layout)
    k = np.ones(15) / 15
    blurred = np.apply_along_axis(lambda v: np.convolve(np.pad(v, 7, mode="edge"), k, "valid"), 2, truth)
    blurred = np.apply_along_axis(lambda v: np.convolve(np.pad(v, 7, mode="edge"), k, "valid"), 1, blurred)
    guess = (0.5 * blurred + 0.01 * np.arange(160)).astype(np.float32)
    score = {name: nrdepth.mae_sn(nrdepth.stitch(patches, guess, layout, **kw), truth)
             for name, kw in {"paper": {"alignment": "coarse", "window": "triangle"}, "joint": {"temporal_weight": 0.0},
                              "small": {"coarse_weight": 1e-5, "temporal_weight": 0.0}}.items()}
    assert score["small"] < 0.01 < 0.5 * score["paper"], score  # measured: 0.0009 and 0.065
    assert score["joint"] < 0.9 * score["paper"], score  # measured: 0.050


def test_the_temporal_tie_steadies_the_reading_of_a_still_surface():
    # A still surface, each patch reading it the same in every frame through
    # a GBR and a smooth error of its own; the coarse pass, as a network's
    # does, flickers: each frame's carries its own smooth error. Frames solved
    # on their own (temporal_weight=0) follow the flicker; the tie holds each
    # patch's reading while its depth holds still, so the stitched video is
    # stiller and closer to the truth.
    shape = (32, 96, 96)
    truth = np.repeat(smooth_video((1, *shape[1:]), seed=4), shape[0], axis=0)
    layout = nrdepth.patch_layout(shape)
    patches = cut(truth, layout)
    rng = np.random.default_rng(2)
    yy, xx = np.mgrid[0 : PATCH[1], 0 : PATCH[2]] / PATCH[1] - 0.5
    for p in patches:
        a, b, c, tau = rng.normal(size=4) * (1.0, 1.0, 0.5, 2.0)
        p[:] = a * xx + b * yy + (1.5 + abs(c)) * (p + c * (xx**2 + yy * xx)) + tau
    flicker = np.concatenate([smooth_video((1, *shape[1:]), seed=100 + t) for t in range(shape[0])])
    coarse = (0.5 * truth + 0.2 * flicker).astype(np.float32)
    change = lambda d: float(np.abs(np.diff(d, axis=0)).mean() / d.std())  # noqa: E731
    free, tied = (nrdepth.stitch(patches, coarse, layout, temporal_weight=nu) for nu in (0.0, TEMPORAL_WEIGHT))
    assert change(tied) < 0.5 * change(free), (change(tied), change(free))  # measured: 0.042 and 0.311
    assert nrdepth.mae_sn(tied, truth) < nrdepth.mae_sn(free, truth), (nrdepth.mae_sn(tied, truth), nrdepth.mae_sn(free, truth))  # 0.031 and 0.097


def test_joint_stitcher_needs_every_patch_once_and_names_bad_arguments():
    shape = (16, 64, 64)
    layout = nrdepth.patch_layout(shape)
    patches = cut(smooth_video(shape), layout)
    coarse = np.zeros(shape, np.float32)
    for bad in (0.0, -1.0, float("nan"), float("inf"), True, "0.1"):
        with pytest.raises(ValueError, match="^coarse_weight:"):
            nrdepth.stitch(patches, coarse, layout, alignment="joint", coarse_weight=bad)
        with pytest.raises(ValueError, match="^coarse_weight:"):
            nrdepth.reconstruct(np.zeros(shape, np.uint8), alignment="joint", coarse_weight=bad)
    for bad in (-1.0, float("nan"), float("inf"), True, "0.1"):
        with pytest.raises(ValueError, match="^temporal_weight:"):
            nrdepth.stitch(patches, coarse, layout, temporal_weight=bad)
        with pytest.raises(ValueError, match="^temporal_weight:"):
            nrdepth.reconstruct(np.zeros(shape, np.uint8), temporal_weight=bad)
    for args in ((None, 0.5), (0.01, -0.5)):  # the paper's alignment has no tie; a negative tie
        with pytest.raises(ValueError, match="^temporal_weight:"):
            nrdepth._core.Stitcher(coarse, layout.patch, "hann", *args)
    with pytest.raises(ValueError, match="^alignment:"):
        nrdepth.stitch(patches, coarse, layout, alignment="paper")
    with pytest.raises(ValueError, match="^alignment:"):
        nrdepth.reconstruct(np.zeros(shape, np.uint8), alignment="global")
    for bad in ("hanning", "Hann", None):
        with pytest.raises(ValueError, match="^window:"):
            nrdepth.stitch(patches, coarse, layout, window=bad)
        with pytest.raises(ValueError, match="^window:"):
            nrdepth.reconstruct(np.zeros(shape, np.uint8), window=bad)
    with pytest.raises(ValueError, match="^window:"):
        nrdepth._core.Stitcher(coarse, layout.patch, "bartlett")
    stitcher = nrdepth._core.Stitcher(coarse, layout.patch, "hann", 0.01)
    with pytest.raises(ValueError, match="^origins:"):
        stitcher.add(patches[:1], layout.origins[:1] + 1)  # off the layout's grid
    with pytest.raises(ValueError, match="^origins:"):
        stitcher.add(patches[:2], layout.origins[[0, 0]])
    stitcher.add(patches[:1], layout.origins[:1])
    with pytest.raises(ValueError, match="^origins:"):
        stitcher.add(patches[:1], layout.origins[:1])
    with pytest.raises(ValueError, match="^patches:.*never added"):
        stitcher.finish()


def test_grid_contrast_sees_planted_seams_is_gbr_invariant_and_names_a_bad_period():
    depth = nrdepth.generate_clips(3, seed=5, config=nrdepth.GeneratorConfig(size=128, frames=4)).depth.astype(np.float64)
    ridges = (np.arange(128) % 32 < 2).astype(float)  # a seam every 32 pixels, 2 wide, on both axes
    seams = ridges[None, None, :] + ridges[None, :, None]
    y, x = np.mgrid[0:128, 0:128]
    for z in depth:
        smooth = grid_contrast(z)
        assert 0.9 < smooth < 1.1
        assert grid_contrast(z + 0.05 * z.std() * seams) > 1.5  # seams of 5 % of the depth's std
        gbr = np.stack([-2.5 * f + 0.3 * x - 0.1 * y + 7 for f in z])  # any GBR of each frame, λ < 0 too
        assert grid_contrast(gbr) == pytest.approx(smooth, rel=1e-9)
    with pytest.raises(ValueError, match="period"):
        grid_contrast(depth[0], period=24)
    with pytest.raises(ValueError, match="depth"):  # tilted planes: no relief, no contrast
        grid_contrast(np.stack([0.3 * x - 0.1 * y] * 2))


@pytest.mark.parametrize("window", ["hann", "triangle"])
def test_windows_sum_to_one_in_space_and_time(window):
    shape = (20, 50, 90)
    layout = nrdepth.patch_layout(shape)
    ones = np.ones((len(layout.origins), *PATCH), np.float32)
    np.testing.assert_allclose(nrdepth.stitch(ones, np.ones(shape, np.float32), layout, window=window), 1.0, atol=1e-5)


@pytest.mark.parametrize("seed", range(4))
def test_hann_windows_blend_disagreeing_patches_without_kinks(seed):
    # Patches that each misread the relief by their own smooth error: the
    # triangle's slope turns at every multiple of the 32-pixel hop, so the
    # stitched error bends there (a grid); the Hann window's slope is
    # continuous, and the error bends alike everywhere.
    shape = (16, 192, 192)
    truth = smooth_video(shape, seed=seed)
    layout = nrdepth.patch_layout(shape)
    patches = cut(truth, layout)
    rng = np.random.default_rng(seed)
    f = np.fft.fftfreq(64)
    lowpass = np.exp(-(f[:, None] ** 2 + f[None] ** 2) * (2 * np.pi * 6) ** 2 / 2)  # Gaussian, σ = 6 pixels
    for p in patches:
        e = np.fft.ifft2(np.fft.fft2(rng.normal(size=(64, 64))) * lowpass).real
        p += (0.3 * truth.std() / e.std() * e)[None].astype(np.float32)
    bend = {}
    for window in ("hann", "triangle"):
        # Inside the frame (the borders' patches reach into the mirrored padding).
        err = (nrdepth.stitch(patches, truth, layout, alignment="coarse", window=window).astype(np.float64) - truth)[:, 31:-31, 31:-31]
        d2 = np.abs(np.diff(err, 2, axis=2)).mean((0, 1)) + np.abs(np.diff(err, 2, axis=1)).mean((0, 2))
        by_phase = np.array([d2[r::32].mean() for r in range(32)])  # by position in the hop
        bend[window] = by_phase.max() / np.median(by_phase)
    assert bend["triangle"] > 1.8 and bend["hann"] < 1.3, bend  # measured: 2.2–2.9 and 1.04–1.14


def test_bad_stitch_input_is_named():
    layout = nrdepth.patch_layout((16, 64, 64))
    good = np.zeros((len(layout.origins), *PATCH), np.float32)
    with pytest.raises(ValueError, match="^coarse:"):
        nrdepth.stitch(good, np.zeros((16, 64, 63), np.float32), layout)
    with pytest.raises(ValueError, match="^patches:"):
        nrdepth.stitch(good[:, :8], np.zeros((16, 64, 64), np.float32), layout)
    with pytest.raises(TypeError, match="^patches:"):
        nrdepth.stitch(good.astype(int), np.zeros((16, 64, 64), np.float32), layout)
    with pytest.raises(ValueError, match="^shape:"):
        nrdepth.patch_layout((0, 64, 64))


def test_reconstruct_runs_on_any_size_and_refuses_bad_video():
    torch.manual_seed(0)
    model = nrdepth.model.UNet3D(base=2)
    video = (np.random.default_rng(0).random((10, 40, 72)) * 255).astype(np.uint8)
    depth = nrdepth.reconstruct(video, model, device="cpu")
    assert depth.shape == (10, 40, 72) and np.isfinite(depth).all()
    with pytest.raises(ValueError, match="^video:"):
        nrdepth.reconstruct(video[0], model, device="cpu")
    with pytest.raises(TypeError, match="^video:"):
        nrdepth.reconstruct(video.astype(np.int32), model, device="cpu")


def test_pixels_off_the_surface_take_no_part_in_the_stitch_or_the_reconstruction():
    # The stitcher: NaN in the coarse depth marks pixels off the surface; the
    # distorted truth comes back on it, whatever the patches hold off it.
    shape = (16, 64, 80)
    truth = smooth_video(shape)
    layout = nrdepth.patch_layout(shape)
    t, y, x = np.mgrid[0 : shape[0], 0 : shape[1], 0 : shape[2]]
    on = (y - 30 - t) ** 2 + (x - 35) ** 2 < 26**2  # a disc drifting down
    coarse = np.where(on, truth, np.nan).astype(np.float32)
    patches = distorted_patches(truth, layout)
    noisy = patches.copy()
    off = cut(~on, layout)
    noisy[off] = np.random.default_rng(3).normal(scale=50, size=int(off.sum()))
    out = nrdepth.stitch(patches, coarse, layout, temporal_weight=0)
    assert np.isnan(out[~on]).all() and np.abs(out[on] - truth[on]).max() < 1e-2
    assert nrdepth.stitch(noisy, coarse, layout).tobytes() == nrdepth.stitch(patches, coarse, layout).tobytes()
    with pytest.raises(ValueError, match="^coarse:"):
        nrdepth.stitch(patches, np.where(on, truth, np.inf).astype(np.float32), layout)
    # reconstruct(mask=): NaN off the mask at the video's resolution, the working one smaller or not.
    torch.manual_seed(0)
    model = nrdepth.model.UNet3D(base=2)
    video = (np.random.default_rng(0).random((10, 40, 72)) * 255).astype(np.uint8)
    mask = np.zeros((40, 72), bool)
    mask[5:35, 10:60] = True
    for max_side in (None, 48):
        depth = nrdepth.reconstruct(video, model, device="cpu", mask=mask, max_side=max_side)
        assert np.isnan(depth[:, ~mask]).all() and np.isfinite(depth[:, mask]).all(), max_side
        assert abs(float(depth[:, mask].mean())) < 1e-5 and float(depth[:, mask].std()) == pytest.approx(1, rel=1e-4)
    moving = np.stack([np.roll(mask, k, axis=1) for k in range(10)])
    part = nrdepth.reconstruct(video, model, device="cpu", mask=moving, frames=slice(2, 8), roi=(4, 0, 60, 40))
    assert (np.isnan(part) == ~moving[2:8, :, 4:64]).all()
    dot = np.zeros_like(mask)
    dot[20, 36] = True  # one pixel: none of the 16-pixel-wide working frame's is mostly on it
    bad = [({"mask": mask.astype(np.uint8)}, TypeError), ({"mask": mask[:, :70]}, ValueError), ({"mask": moving[:9]}, ValueError),
           ({"mask": mask, "alignment": "coarse"}, ValueError), ({"mask": mask, "temporal": True}, ValueError),
           ({"mask": np.zeros_like(mask)}, ValueError), ({"mask": dot, "max_side": 16}, ValueError)]
    for options, error in bad:
        with pytest.raises(error, match="^mask:"):
            nrdepth.reconstruct(video, model, device="cpu", **options)


def test_coarse_pass_commutes_with_a_left_right_mirror():
    """The coarse pass averages its readings of the video and of the mirrored
    video, so mirroring the input mirrors its depth, whatever the network;
    a plain single reading by a network that is not mirror-symmetric fails."""
    from nrdepth.reconstruct import coarse_depth

    torch.manual_seed(0)
    net = nrdepth.model.build_model("unet2p1d").eval()
    video = (np.random.default_rng(1).random((20, 48, 80)) * 255).astype(np.uint8)
    dev = torch.device("cpu")
    depth = coarse_depth(video, net, 8, dev)
    mirrored = coarse_depth(np.ascontiguousarray(video[..., ::-1]), net, 8, dev)
    assert depth.shape == video.shape and depth.std() > 0
    np.testing.assert_allclose(mirrored, depth[..., ::-1], rtol=0, atol=1e-5 * np.abs(depth).max())


def test_temporal_align_is_invariant_to_per_frame_gbr_up_to_one_global_gbr():
    truth = nrdepth.generate_clips(1, seed=5).depth[0].astype(np.float64)
    rng = np.random.default_rng(2)
    yy, xx = np.mgrid[0 : truth.shape[1], 0 : truth.shape[2]]
    flicker = np.stack([
        a * xx + b * yy + lam * frame + tau
        for frame, (a, b, tau), lam in zip(truth, rng.normal(size=(len(truth), 3)) * (0.01, 0.01, 1.0), rng.uniform(0.3, 3, len(truth)) * rng.choice([-1, 1], len(truth)))
    ]).astype(np.float32)
    aligned = nrdepth.temporal_align(flicker)
    # Each frame moved by a GBR only: the per-frame score is untouched …
    assert nrdepth.mae_sn(aligned, truth, "frame") < 1e-3
    # … and the flicker is gone: the result is the truth's own temporal
    # alignment seen through one GBR, which frame 0's fit maps back everywhere.
    reference = nrdepth.temporal_align(truth.astype(np.float32))
    assert nrdepth.mae_sn(aligned, reference, "first") < 1e-3
    assert nrdepth.mae_sn(flicker, reference, "first") > 1.0
    np.testing.assert_array_equal(aligned[0], flicker[0])
    with pytest.raises(ValueError, match="^depth:"):
        nrdepth.temporal_align(flicker[0])
    with pytest.raises(ValueError, match="^depth:"):
        nrdepth.temporal_align(np.full((2, 4, 4), np.nan, np.float32))


def test_streaming_stitcher_refuses_misshapen_chunks_and_reuse():
    layout = nrdepth.patch_layout((16, 64, 64))
    stitcher = nrdepth._core.Stitcher(np.zeros((16, 64, 64), np.float32), layout.patch, "triangle")
    with pytest.raises(ValueError, match="^patches:"):
        stitcher.add(np.zeros((1, 64, 16, 64), np.float32), layout.origins[:1])
    with pytest.raises(ValueError, match="^origins:"):
        stitcher.add(np.zeros((2, 16, 64, 64), np.float32), layout.origins[:1])
    stitcher.finish()
    with pytest.raises(RuntimeError, match="already finished"):
        stitcher.finish()


def test_relief_scale_undoes_a_shrunk_relief_whatever_each_frames_plane():
    from nrdepth.reconstruct.export import relief_scale

    reference = smooth_video((4, 40, 56), seed=2).astype(np.float64)
    y, x = np.mgrid[0:40, 0:56]
    shrunk = np.stack([0.4 * f + a * x + b * y + c for f, (a, b, c) in zip(reference, np.random.default_rng(0).normal(size=(4, 3)))])
    assert relief_scale(shrunk, reference) == pytest.approx(2.5, rel=1e-9)
    assert relief_scale(np.stack([x + y] * 4).astype(float), reference) == 1.0  # planes: no relief to scale


def _companion_pair(tmp_path, share, seeds=(0, 1)):
    """A model folder whose model.json names a coarse companion at ``share``;
    the two networks, built from ``seeds``."""
    nets = []
    for name, seed in zip(("model", "coarse"), seeds):
        torch.manual_seed(seed)
        nets.append(nrdepth.model.build_model("unet2p1d").eval())
        nrdepth.model.save_model(nets[-1], tmp_path / f"{name}.safetensors")
    meta = json.loads((tmp_path / "model.json").read_text())
    meta["coarse_companion"] = {"model": "coarse.safetensors", "share": share}
    (tmp_path / "model.json").write_text(json.dumps(meta))
    return tmp_path / "model.safetensors", nets


def _by_windows(depth, window=16):
    """Brute force: each window of ``window`` frames at mean 0, standard deviation 1."""
    return np.concatenate([(w - w.mean()) / w.std() for w in np.split(depth.astype(np.float64), range(window, len(depth), window))])


def test_a_coarse_companion_blends_the_two_standardised_readings_at_its_share(tmp_path):
    """The coarse pass of a model with a companion is (1 − share)·a + share·b
    of the two networks' readings, each 16-frame window standardised
    (brute force on a 40-frame video: windows of 16, 16 and 8 frames); and a
    companion equal to the model gives its own reading standardised."""
    from nrdepth.reconstruct import coarse_half, inference_model

    path, (a, b) = _companion_pair(tmp_path, 0.25)
    dev = torch.device("cpu")
    net = inference_model(path, dev)
    assert net.coarse_companion[1] == 0.25 and not any("coarse_companion" in k for k in net.state_dict())
    small = np.random.default_rng(2).random((40, 64, 64)).astype(np.float32)
    blended = coarse_half(small, net, 8, dev)
    expected = 0.75 * _by_windows(coarse_half(small, a, 8, dev)) + 0.25 * _by_windows(coarse_half(small, b, 8, dev))
    np.testing.assert_allclose(blended, expected, rtol=0, atol=1e-5)
    (tmp_path / "same").mkdir()
    same, _ = _companion_pair(tmp_path / "same", 0.6, seeds=(0, 0))
    np.testing.assert_allclose(coarse_half(small, inference_model(same, dev), 8, dev), _by_windows(coarse_half(small, a, 8, dev)), rtol=0, atol=1e-5)


def test_reconstruct_reads_a_companion_from_the_file_and_from_a_module_alike(tmp_path):
    """``reconstruct`` given the model's path uses its companion (the depth
    differs from the model's alone) and gives the same depth as the module
    loaded by :func:`load_model`."""
    path, (a, _) = _companion_pair(tmp_path, 0.5)
    video = (np.random.default_rng(3).random((20, 72, 80)) * 255).astype(np.uint8)
    # float32: in bfloat16 the two layouts (a module is run as given, a file channels-last) round apart.
    from_file = nrdepth.reconstruct(video, path, device="cpu", precision="float32")
    from_module = nrdepth.reconstruct(video, nrdepth.model.load_model(path), device="cpu", precision="float32")
    alone = nrdepth.reconstruct(video, a, device="cpu")
    np.testing.assert_allclose(from_file, from_module, rtol=0, atol=1e-5)
    assert np.abs(from_file - alone).mean() > 1e-3


@pytest.mark.parametrize("spec, message", [
    ({"model": "coarse.safetensors", "share": 0}, "'coarse_companion' expected"),
    ({"model": "coarse.safetensors", "share": 1.5}, "'coarse_companion' expected"),
    ({"model": "coarse.safetensors", "share": True}, "'coarse_companion' expected"),
    ({"model": "../coarse.safetensors", "share": 0.5}, "'coarse_companion' expected"),
    ({"share": 0.5}, "'coarse_companion' expected"),
    ("coarse.safetensors", "'coarse_companion' expected"),
    ({"model": "absent.safetensors", "share": 0.5}, "absent.safetensors: not found"),
    ({"model": "model.safetensors", "share": 0.5}, "cannot have a companion of its own"),
    ({"model": "coarse.safetensors", "share": 0.5, "depth_units": "window"}, "cannot have a coarse companion"),
    ({"model": "coarse.safetensors", "share": 0.5, "companion_units": "window"}, "a coarse companion gives depth up to scale"),
])
def test_a_bad_coarse_companion_names_the_file_and_what_is_wrong(tmp_path, spec, message):
    path, _ = _companion_pair(tmp_path, 0.5)
    if isinstance(spec, dict) and "companion_units" in spec:  # the companion itself learnt the relief's scale
        companion = json.loads((tmp_path / "coarse.json").read_text())
        companion["depth_units"] = spec.pop("companion_units")
        (tmp_path / "coarse.json").write_text(json.dumps(companion))
    meta = json.loads(path.with_suffix(".json").read_text())
    if isinstance(spec, dict) and "depth_units" in spec:  # a model that learnt the relief's scale
        meta["depth_units"] = spec.pop("depth_units")
    meta["coarse_companion"] = spec
    path.with_suffix(".json").write_text(json.dumps(meta))
    with pytest.raises(ValueError, match=re.escape(message)):
        nrdepth.model.load_model(path)
