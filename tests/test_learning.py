"""Invariant losses, MAE-SN and the 3D U-Net."""

import numpy as np
import pytest
import torch

import nrdepth
from nrdepth.learning.losses import (
    aligned_both_offsets_signed_loss,
    aligned_both_signed_loss,
    aligned_clip_loss,
    aligned_clip_offsets_signed_loss,
    aligned_clip_signed_loss,
    aligned_first_loss,
    aligned_loss,
    aligned_signed_first_loss,
    aligned_signed_loss,
    gbr_loss,
    LOSSES,
    MASKED_LOSSES,
    get_loss,
    tr_sc_loss,
)
from nrdepth.scores.metrics import flat_baseline, mae_sn, relief_signs, sign_rates
from nrdepth.model import UNet2p1D, UNet2p1DDeep, UNet2p1DGlobal, UNet3D, count_parameters


def smooth_depth(seed, shape=(2, 4, 24, 24)):
    """Random smooth depth videos (float64) with curvature everywhere."""
    g = torch.Generator().manual_seed(seed)
    b, t, h, w = shape
    y, x = torch.meshgrid(torch.linspace(-1, 1, h, dtype=torch.float64), torch.linspace(-1, 1, w, dtype=torch.float64), indexing="ij")
    z = torch.zeros(shape, dtype=torch.float64)
    for _ in range(4):
        k = torch.randn(4, generator=g, dtype=torch.float64) * 2
        z += torch.sin(k[0] * x + k[1] * y + k[2] + k[3] * torch.arange(t, dtype=torch.float64).view(1, t, 1, 1) / t)
    return z + 0.3 * (x**2 + 0.5 * y**2)


def gbr(z, alpha, beta, lam, tau):
    h, w = z.shape[-2:]
    y, x = torch.meshgrid(torch.arange(h, dtype=z.dtype), torch.arange(w, dtype=z.dtype), indexing="ij")
    return alpha * x + beta * y + lam * z + tau


@pytest.mark.parametrize("seed", range(5))
def test_gbr_loss_is_zero_for_any_gbr_transform(seed):
    z = smooth_depth(seed)
    rng = np.random.default_rng(seed)
    alpha, beta, tau = rng.normal(size=3) * 3
    lam = rng.uniform(0.05, 20)
    assert gbr_loss(gbr(z, alpha, beta, lam, tau), z).item() < 1e-12
    assert gbr_loss(smooth_depth(seed + 100), z).item() > 1e-3


def test_tr_sc_loss_is_invariant_to_stretch_and_shift_but_not_shear():
    z = smooth_depth(1)
    assert tr_sc_loss(gbr(z, 0, 0, 7.5, -3.0), z).item() < 1e-12
    assert tr_sc_loss(gbr(z, 0.05, 0, 1.0, 0.0), z).item() > 1e-4
    assert tr_sc_loss(gbr(z, 0, -0.05, 1.0, 0.0), z).item() > 1e-4


def test_aligned_loss_is_zero_for_gbr_transforms_and_positive_otherwise():
    z = smooth_depth(2)
    assert aligned_loss(gbr(z, 1.5, -0.7, 3.0, 2.0), z).item() < 1e-8
    assert aligned_loss(gbr(z, 1.5, -0.7, -3.0, 2.0), z).item() < 1e-8  # λ < 0 is aligned too
    assert aligned_loss(smooth_depth(3), z).item() > 1e-2


def test_aligned_clip_loss_forgives_one_gbr_per_clip_but_not_one_per_frame():
    z = smooth_depth(6)
    assert aligned_clip_loss(gbr(z, 0.4, -0.2, -2.0, 1.0), z).item() < 1e-8
    per_frame = torch.stack([gbr(z[:, k], 0.3 * k, -0.1 * k, 1.0 + k, k) for k in range(z.shape[1])], dim=1)
    assert aligned_loss(per_frame, z).item() < 1e-8
    assert aligned_clip_loss(per_frame, z).item() > 1e-2


def test_the_first_frame_loss_is_mae_sn_first_alignment_squared():
    z = smooth_depth(7)
    pred = gbr(z, 0.4, -0.2, -2.0, 1.0)
    assert aligned_first_loss(pred, z).item() < 1e-8  # one GBR per clip, any sign
    pred = pred + 0.3 * smooth_depth(8)
    expected = []
    for p, g in zip(pred.numpy(), z.numpy()):  # the direct computation: fit frame 0, apply to every frame
        h, w = g.shape[-2:]
        y, x = np.mgrid[0:h, 0:w]
        design = np.stack([x, y, p[0], np.ones_like(p[0])], -1).reshape(-1, 4)
        coeffs = np.linalg.lstsq(design, g[0].ravel(), rcond=None)[0]
        aligned = coeffs[0] * x + coeffs[1] * y + coeffs[2] * p + coeffs[3]
        expected.append((((aligned - g) ** 2).mean((1, 2)) / g.var((1, 2))).mean())
    assert aligned_first_loss(pred, z).item() == pytest.approx(np.mean(expected), rel=1e-3)  # the ridge


def test_the_first_frame_loss_carries_frame_0s_error_into_the_clip():
    z = smooth_depth(13)
    tilted_first = z.clone()
    tilted_first[:, 0] = gbr(z[:, 0], 0.3, -0.2, 1.0, 0.0)  # only frame 0 is off, by a plane
    assert aligned_signed_loss(tilted_first, z).item() < 1e-8
    first, clip = aligned_first_loss(tilted_first, z).item(), aligned_clip_loss(tilted_first, z).item()
    assert first > 2 * clip > 1e-3  # fitted on frame 0, the tilt lands on the other frames
    assert aligned_signed_first_loss(tilted_first, z).item() == pytest.approx(first / 2, rel=1e-6)


def test_signed_losses_forgive_a_gbr_with_positive_lambda_only():
    z = smooth_depth(9)
    flat = torch.zeros_like(z)
    for loss_fn in (aligned_signed_loss, aligned_clip_signed_loss, aligned_both_signed_loss):
        assert loss_fn(gbr(z, 1.5, -0.7, 3.0, 2.0), z).item() < 1e-8
        # A mirrored relief scores worse than a flat prediction: twice its loss (ρ = −1).
        mirrored = loss_fn(gbr(z, 1.5, -0.7, -3.0, 2.0), z).item()
        assert mirrored == pytest.approx(2 * loss_fn(flat, z).item(), rel=1e-6)
        assert loss_fn(flat, z).item() > 0.05


def test_the_per_frame_signed_loss_is_the_unconstrained_one_where_the_sign_is_right():
    z = smooth_depth(10)
    pred = z + 0.5 * smooth_depth(11)
    assert aligned_signed_loss(pred, z).item() == pytest.approx(aligned_loss(pred, z, ridge=0.0).item(), rel=1e-6)
    assert aligned_clip_signed_loss(gbr(z, 0.4, -0.2, 2.0, 1.0), z).item() < 1e-8


def test_the_clip_signed_loss_asks_for_one_gbr_per_clip():
    z = smooth_depth(12)
    per_frame = torch.stack([gbr(z[:, k], 0.3 * k, -0.1 * k, 1.0 + k, k) for k in range(z.shape[1])], dim=1)
    assert aligned_signed_loss(per_frame, z).item() < 1e-8
    assert aligned_clip_signed_loss(per_frame, z).item() > 1e-2


def test_the_offsets_loss_forgives_a_depth_offset_per_frame_but_not_a_tilt():
    z = smooth_depth(16)
    offsets = torch.stack([gbr(z[:, k], 0.4, -0.2, 2.0, 3.0 * k) for k in range(z.shape[1])], dim=1)
    assert aligned_clip_offsets_signed_loss(offsets, z).item() < 1e-8
    assert aligned_clip_signed_loss(offsets, z).item() > 1e-2
    tilts = torch.stack([gbr(z[:, k], 0.3 * k, 0.0, 2.0, 0.0) for k in range(z.shape[1])], dim=1)
    assert aligned_clip_offsets_signed_loss(tilts, z).item() > 1e-2
    mirrored = aligned_clip_offsets_signed_loss(-offsets, z).item()
    assert mirrored == pytest.approx(2 * aligned_clip_offsets_signed_loss(torch.zeros_like(z), z).item(), rel=1e-6)
    assert aligned_both_offsets_signed_loss(offsets, z).item() < 1e-8


def test_a_wrong_sign_gets_a_gradient_that_turns_it():
    z = smooth_depth(13).float()
    # The relief read inverted, with an error: exactly -z would be the correlation's minimum (rho = -1), where the gradient vanishes.
    pred = (0.3 * smooth_depth(31).float() - z).requires_grad_(True)
    for loss_fn in (aligned_signed_loss, aligned_clip_signed_loss, aligned_clip_offsets_signed_loss):
        loss = loss_fn(pred, z)
        (grad,) = torch.autograd.grad(loss, pred)
        # A small step against the gradient moves the prediction toward +z.
        stepped = loss_fn(pred.detach() - 1e-2 * grad / grad.norm() * z.norm(), z)
        assert stepped.item() < loss.item()
        assert torch.sum(-grad * z).item() > 0
    # The sign-free loss, by contrast, settles into the inverted reading: its gradient points toward -z.
    (free,) = torch.autograd.grad(aligned_loss(pred, z), pred)
    assert torch.sum(-free * z).item() < 0


def test_sign_rates_count_correct_frames_and_flips():
    gt = smooth_depth(14, (1, 6, 16, 16))[0].numpy()
    assert sign_rates(gt, gt) == {"sign_correct": 1.0, "flip": 0.0}
    assert sign_rates(-gt, gt) == {"sign_correct": 0.0, "flip": 0.0}
    flipped = gt.copy()
    flipped[2] *= -1
    assert list(relief_signs(flipped, gt)) == [1, 1, -1, 1, 1, 1]
    assert sign_rates(flipped, gt) == {"sign_correct": pytest.approx(5 / 6), "flip": 1.0}


def test_masks_exclude_flat_and_planar_regions():
    z = smooth_depth(4)
    planar = z.clone()
    planar[..., :12] = gbr(torch.zeros_like(z), 0.3, 0.1, 1.0, 0.0)[..., :12]
    # A prediction that is wrong only where the target is planar costs nothing.
    pred = planar.clone()
    pred[..., :10] += torch.randn_like(pred[..., :10])
    assert gbr_loss(pred, planar).item() < 1e-12
    assert tr_sc_loss(pred, planar).item() < 1e-12


@pytest.mark.parametrize("name", ["gbr", "tr_sc", "aligned", "aligned_clip", "aligned_signed", "aligned_clip_signed", "aligned_both_signed", "aligned_clip_offsets_signed", "aligned_both_offsets_signed",
                                  "aligned_first", "aligned_signed_first"])
def test_losses_have_finite_gradients_on_flat_input(name):
    loss_fn = get_loss(name)
    pred = torch.zeros(2, 4, 16, 16, requires_grad=True)
    for target in (torch.zeros(2, 4, 16, 16), smooth_depth(5, (2, 4, 16, 16)).float()):
        loss = loss_fn(pred, target)
        (grad,) = torch.autograd.grad(loss, pred)
        assert torch.isfinite(loss) and torch.isfinite(grad).all()


@pytest.mark.parametrize("name", MASKED_LOSSES)
def test_a_masked_target_scores_only_the_sheet(name):
    # NaN off a rectangle = the loss on that rectangle alone (a plane fit and
    # the standardised prediction's correlation do not depend on where the
    # coordinates' origin lies), whatever the prediction is off the sheet.
    loss_fn = get_loss(name)
    target, pred = smooth_depth(6, (2, 4, 20, 20)), smooth_depth(7, (2, 4, 20, 20))
    rows, cols = slice(3, 17), slice(5, 20)
    masked = torch.full_like(target, float("nan"))
    masked[..., rows, cols] = target[..., rows, cols]
    crop = loss_fn(pred[..., rows, cols], target[..., rows, cols])
    assert loss_fn(pred, masked).item() == pytest.approx(crop.item(), rel=1e-9)
    scrambled = pred.clone()
    scrambled[..., :3, :] = 100 * torch.randn_like(scrambled[..., :3, :])
    scrambled.requires_grad_(True)
    loss = loss_fn(scrambled, masked)
    assert loss.item() == pytest.approx(crop.item(), rel=1e-9)
    (grad,) = torch.autograd.grad(loss, scrambled)
    assert torch.isfinite(grad).all() and grad[..., rows, cols].abs().sum() > 0
    # A frame with under 4 pixels on the sheet weighs nothing.
    sparse = masked.clone()
    sparse[0, 1] = float("nan")
    sparse[0, 1, 8, 8] = 1.0
    assert torch.isfinite(loss_fn(pred, sparse))
    empty = masked.clone()
    empty[0, 1] = float("nan")
    assert loss_fn(pred, sparse).item() == pytest.approx(loss_fn(pred, empty).item(), rel=1e-12)


@pytest.mark.parametrize("name", sorted(set(LOSSES) - set(MASKED_LOSSES)))
def test_the_other_losses_refuse_a_masked_target(name):
    target = smooth_depth(6, (1, 2, 12, 12))
    target[..., 0, 0] = float("nan")
    with pytest.raises(ValueError, match="^target: .*signed loss"):
        get_loss(name)(torch.zeros_like(target), target)


def test_loss_inputs_are_checked():
    with pytest.raises(ValueError, match="^loss:"):
        get_loss("l1")
    with pytest.raises(ValueError, match="^pred:"):
        gbr_loss(torch.zeros(1, 2, 8, 8), torch.zeros(1, 2, 8, 9))
    with pytest.raises(ValueError, match="^target:"):
        aligned_loss(torch.zeros(1, 2, 8, 8), torch.zeros(2, 8, 8))


# ------------------------------------------------------------------ MAE-SN


def test_mae_sn_is_zero_for_any_gbr_transform_of_the_truth():
    gt = smooth_depth(6, (1, 5, 20, 22))[0].numpy()
    transformed = gbr(torch.from_numpy(gt), -2.0, 0.5, 4.0, 1.0).numpy()
    assert mae_sn(transformed, gt) < 1e-10
    assert mae_sn(transformed, gt, align="first") < 1e-10


def test_mae_sn_equals_a_direct_computation():
    rng = np.random.default_rng(0)
    pred, gt = rng.normal(size=(3, 6, 7)), rng.normal(size=(3, 6, 7)).cumsum(axis=2)
    scores = []
    for p, g in zip(pred, gt):
        y, x = np.mgrid[0:6, 0:7]
        a = np.column_stack([x.ravel(), y.ravel(), p.ravel(), np.ones(42)])
        coeffs = np.linalg.solve(a.T @ a, a.T @ g.ravel())
        scores.append(np.abs(a @ coeffs - g.ravel()).mean() / g.std())
    assert mae_sn(pred, gt) == pytest.approx(np.mean(scores), rel=1e-10)


def test_first_frame_alignment_differs_when_the_transform_changes_over_time():
    gt = smooth_depth(7, (1, 4, 16, 16))[0]
    pred = torch.stack([gbr(gt[t], 0.1 * t, 0.0, 1.0 + t, 0.0) for t in range(4)]).numpy()
    assert mae_sn(pred, gt.numpy(), "frame") < 1e-10
    assert mae_sn(pred, gt.numpy(), "first") > 0.1


def test_first_offset_alignment_forgives_only_a_depth_offset_per_frame():
    gt = smooth_depth(17, (1, 4, 16, 16))[0].numpy()
    drifting = gt + np.arange(4)[:, None, None] * 0.7
    assert mae_sn(drifting, gt, "first") > 0.1
    assert mae_sn(drifting, gt, "first_offset") < 1e-10
    tilting = np.stack([gbr(torch.from_numpy(gt[t]), 0.1 * t, 0.0, 1.0, 0.0).numpy() for t in range(4)])
    assert mae_sn(tilting, gt, "first_offset") > 0.05


def test_flat_baseline_is_the_score_of_a_constant_and_beaten_by_the_truth():
    gt = smooth_depth(8, (1, 3, 16, 16))[0].numpy()
    assert flat_baseline(gt) == pytest.approx(mae_sn(np.full_like(gt, 3.0), gt))
    assert flat_baseline(gt) > 0.1
    with pytest.raises(ValueError, match="^align:"):
        mae_sn(gt, gt, align="last")
    with pytest.raises(ValueError, match="^pred:"):
        mae_sn(gt[:, :4], gt)
    with pytest.raises(ValueError, match="^gt:"):
        mae_sn(gt, np.where(gt > 0, np.nan, gt))


# ------------------------------------------------------------------ network


def test_unet_shapes_and_parameter_count():
    model = UNet3D()
    out = model(torch.zeros(1, 1, 16, 64, 64))
    assert out.shape == (1, 1, 16, 32, 32)
    assert count_parameters(model) == 3_042_849
    with pytest.raises(ValueError, match="^video:"):
        model(torch.zeros(1, 1, 15, 64, 64))


def test_unet2p1d_shapes_and_exposure_invariance():
    torch.manual_seed(0)
    model = UNet2p1D(width=8, stem_width=4)
    video = torch.rand(2, 1, 6, 32, 40)
    out = model(video)
    assert out.shape == (2, 1, 6, 16, 20)
    # The input is standardised per clip: gain and offset of the exposure
    # change nothing but through the 1e-3 floor on the standard deviation.
    exposure = (model(0.5 * video + 0.2) - out).abs().max().item()
    content = (model(video.flip(-2)) - out).abs().max().item()
    assert exposure < 0.02 * content, (exposure, content)
    assert count_parameters(UNet2p1D()) < count_parameters(UNet3D()) / 8
    with pytest.raises(ValueError, match="^video:"):
        model(torch.zeros(1, 1, 4, 30, 32))
    with pytest.raises(ValueError, match="^width:"):
        UNet2p1D(width=0)


def receptive_frames(model, frames=16):
    """Which input frames change output frame 0 (the gradient's support)
    through the network's layers (after the clip-wide standardisation of
    its input, which reaches every frame through two numbers)."""
    video = torch.rand(1, 1, frames, 32, 32, requires_grad=True)
    l1 = model.level1(model.stem(video))
    l2 = model.level2(l1)
    l3 = model.level3(l2)
    (grad,) = torch.autograd.grad(model.head(model.up1(model.up2(l3, l2), l1))[0, 0, 0].sum(), video)
    return grad[0, 0].abs().sum((1, 2)) > 0


def test_the_global_unet2p1d_starts_as_the_plain_one_and_sees_the_whole_clip():
    torch.manual_seed(0)
    plain, global_ = UNet2p1D(width=8, stem_width=4), UNet2p1DGlobal(width=8, stem_width=4)
    missing = global_.load_state_dict(plain.state_dict(), strict=False).missing_keys
    assert missing and all(".fuse." in k or ".reduce." in k or ".branches." in k for k in missing)
    video = torch.rand(2, 1, 16, 32, 32)
    assert torch.equal(global_(video), plain(video))  # the temporal context starts as the identity
    assert not receptive_frames(plain)[8:].any()  # ±7 frames: frame 0 never sees the second half
    torch.nn.init.normal_(global_.level3[-1].fuse.weight, std=0.1)
    assert receptive_frames(global_).all()
    assert global_.config["temporal_rates"] == [2, 4, 8]
    with pytest.raises(ValueError, match="^temporal_rates:"):
        UNet2p1DGlobal(temporal_rates=())


def test_the_deep_unet2p1d_starts_as_the_plain_one_and_reaches_further_in_time():
    torch.manual_seed(0)
    plain, deep = UNet2p1D(width=8, stem_width=4), UNet2p1DDeep(width=8, stem_width=4, coarse_blocks=3)
    missing = deep.load_state_dict(plain.state_dict(), strict=False).missing_keys
    assert len(missing) == 3 * 4 and all(k.startswith("level3.") for k in missing)  # a spatial and a temporal conv per block
    video = torch.rand(2, 1, 16, 32, 32)
    assert torch.equal(deep(video), plain(video))  # the added blocks start as the identity
    for block in deep.level3[-3:]:
        torch.nn.init.normal_(block.temporal.weight, std=0.1)
    reach = receptive_frames(deep)
    assert reach[:11].all() and not reach[11:].any()  # ±7 frames, and one more per block at the coarsest level
    assert deep.config["coarse_blocks"] == 3 and UNet2p1DDeep().config["coarse_blocks"] == 4
    with pytest.raises(ValueError, match="^coarse_blocks:"):
        UNet2p1DDeep(coarse_blocks=0)


def test_a_small_unet_overfits_a_few_generated_clips():
    torch.manual_seed(0)
    config = nrdepth.GeneratorConfig(frames=4, size=32, grid=32, texture_size=64)
    clips = nrdepth.generate_clips(2, seed=0, config=config)
    video = torch.from_numpy(clips.video).float().div(255).unsqueeze(1)
    depth = torch.from_numpy(clips.depth).unsqueeze(1)
    target = torch.nn.functional.avg_pool3d(depth, (1, 2, 2))[:, 0]
    model = UNet3D(base=4)
    optimiser = torch.optim.Adam(model.parameters(), lr=3e-3)
    losses = []
    for _ in range(200):
        optimiser.zero_grad()
        loss = aligned_loss(model(video)[:, 0], target)
        loss.backward()
        optimiser.step()
        losses.append(loss.item())
    assert np.mean(losses[-10:]) < 0.1 * np.mean(losses[:10]), (losses[:3], losses[-3:])


def test_a_mask_scores_only_its_pixels():
    gt = smooth_depth(15, (1, 3, 16, 16))[0].numpy()
    pred = gbr(torch.from_numpy(gt), 0.2, -0.1, 2.0, 1.0).numpy()
    mask = np.zeros(gt.shape, bool)
    mask[:, 2:12, 3:14] = True
    corrupted_gt = np.where(mask, gt, np.nan)
    corrupted_pred = np.where(mask, pred, 1e6)  # what lies outside the mask must not matter
    assert mae_sn(corrupted_pred, corrupted_gt, mask=mask) < 1e-10
    assert mae_sn(corrupted_pred, corrupted_gt, "first", mask=mask) < 1e-10
    inside = gt[:, 2:12, 3:14]
    assert flat_baseline(corrupted_gt, mask=mask) == pytest.approx(flat_baseline(inside), rel=1e-9)
    with pytest.raises(ValueError, match="^mask:"):
        mae_sn(pred, gt, mask=mask[:, :4])
    with pytest.raises(ValueError, match="^gt:"):
        mae_sn(pred, corrupted_gt)


def test_the_relief_amplitude_term_sees_the_relief_scale_and_nothing_else():
    from nrdepth.learning.losses import AMPLITUDE_FLOOR, relief_amplitude_loss, relief_rms

    z = smooth_depth(3)
    relief = 0.05 * z
    assert relief_amplitude_loss(relief, relief).item() == 0.0
    # A plane and an offset in every frame change nothing; so does the sign.
    planar = gbr(relief, 0.3, -0.2, 1.0, 5.0)
    assert torch.allclose(relief_rms(planar), relief_rms(relief), rtol=1e-9)
    assert relief_amplitude_loss(-planar, relief).item() < 1e-18
    # A relief s times too large costs log(s)² (up to the floor).
    rms = relief_rms(relief)
    expected = (torch.log((3 * rms + AMPLITUDE_FLOOR) / (rms + AMPLITUDE_FLOOR)) ** 2).mean()
    assert torch.isclose(relief_amplitude_loss(3 * relief, relief), expected, rtol=1e-9)
    # A flat target asks for a flat prediction: the gradient shrinks the relief.
    pred = relief.clone().requires_grad_(True)
    relief_amplitude_loss(pred, gbr(torch.zeros_like(relief), 0.1, 0.2, 1.0, 0.0)).backward()
    assert (pred.grad * relief).sum() > 0


def test_averaged_readings_commute_with_the_symmetries_they_average():
    """``readings=2`` averages a clip's reading with its left-right mirror's,
    so mirroring the input mirrors the depth; ``readings=4`` adds both
    upside down and negated, so turning the input upside down turns the
    depth upside down and negates it; whatever the network. One reading of
    a random network has neither symmetry."""
    from nrdepth.learning.evaluate import evaluate
    from nrdepth.model import predict_depth

    torch.manual_seed(0)
    net = nrdepth.model.build_model("unet2p1d").eval()
    video = (np.random.default_rng(3).random((2, 16, 32, 32)) * 255).astype(np.uint8)
    mirror, upside_down = (lambda v: np.ascontiguousarray(v[..., ::-1])), (lambda v: np.ascontiguousarray(v[..., ::-1, :]))
    one = predict_depth(net, video)
    tol = 1e-5 * np.abs(one).max()
    assert np.abs(predict_depth(net, mirror(video)) - mirror(one)).max() > 100 * tol
    assert np.abs(predict_depth(net, upside_down(video)) + upside_down(one)).max() > 100 * tol
    two = predict_depth(net, video, readings=2)
    np.testing.assert_allclose(predict_depth(net, mirror(video), readings=2), mirror(two), rtol=0, atol=tol)
    four = predict_depth(net, video, readings=4)
    np.testing.assert_allclose(predict_depth(net, mirror(video), readings=4), mirror(four), rtol=0, atol=tol)
    np.testing.assert_allclose(predict_depth(net, upside_down(video), readings=4), -upside_down(four), rtol=0, atol=tol)
    for bad in (3, 0, True, "4"):
        with pytest.raises(ValueError, match="^readings:"):
            predict_depth(net, video, readings=bad)
    with pytest.raises(ValueError, match="^readings:"):
        evaluate("no-such-model.safetensors", clips=1, readings=8)


def test_upmerge_projects_before_upsampling_as_if_after():
    from nrdepth.model.unet2p1d import UpMerge

    torch.manual_seed(0)
    merge = UpMerge(8, 4)
    x, skip = torch.randn(2, 8, 3, 5, 6), torch.randn(2, 4, 3, 10, 12)
    after = merge.block(merge.project(torch.nn.functional.interpolate(x, size=skip.shape[2:], mode="nearest")) + skip)
    torch.testing.assert_close(merge(x, skip), after, rtol=1e-6, atol=1e-6)


@pytest.mark.parametrize("architecture", ["unet2p1d", "unet2p1d_global", "unet2p1d_deep"])
@pytest.mark.parametrize("layout", [torch.contiguous_format, torch.channels_last_3d])
def test_inference_writes_over_its_activations_and_gives_the_same_bits(monkeypatch, architecture, layout):
    """Without gradients the (2+1)D networks add residuals and skips in the
    memory of a layer's new output: the same bits as with gradients and as
    with every sum a new tensor (``WRITE_OVER`` off), and the input is left
    as it was."""
    from nrdepth.model import unet2p1d
    from nrdepth.model.io import build_model

    torch.manual_seed(0)
    net = build_model(architecture, width=8, stem_width=4).eval().to(memory_format=layout)
    with torch.no_grad():
        for parameter in net.parameters():  # the modules that start as the identity too
            parameter.normal_(0.0, 0.2)
    video = torch.rand(2, 1, 5, 32, 40).contiguous(memory_format=layout)
    given = video.clone()
    with torch.enable_grad():
        summed = net(video).detach()
    with torch.inference_mode():
        written_over = net(video)
        monkeypatch.setattr(unet2p1d, "WRITE_OVER", False)
        new_tensors = net(video)
    assert torch.equal(video, given)
    assert torch.equal(summed, written_over) and torch.equal(new_tensors, written_over)
