"""Losses on depth videos, pure functions of ``(pred, target)``.

Both tensors are (B, T, H, W) (a channel axis of size 1 is accepted and
dropped). Derivatives are central differences on each frame (interior pixels
only, so no padding enters them): ``z_x, z_y`` first, ``z_xx, z_xy, z_yy``
second. With ``H = ∇²z`` and ``‖H‖_F = sqrt(z_xx² + 2 z_xy² + z_yy²)``:

- ``gbr``: ℓ_GBR = MSE(ι_pred, ι_gt), ``ι = (z_xx, √2 z_xy, z_yy)/‖H‖_F``, the
  paper's complete invariant under GBR ``z ↦ αx + βy + λz + τ`` (λ > 0).
- ``tr_sc``: ℓ_tr+sc = MSE(η_pred, η_gt), ``η = (z_x, z_y, z_xx, √2 z_xy, z_yy)/‖H‖_F``,
  invariant under z-stretch and z-translation only.
- ``aligned`` (ours): per frame, the closed-form least-squares GBR (α, β, λ, τ)
  mapping pred onto target is solved inside the graph (differentiable), and the
  loss is the MSE of the aligned prediction divided by the target frame's
  variance: the squared counterpart of MAE-SN, optimised directly, using the
  depth itself rather than its second derivatives (less noise-sensitive).
- ``aligned_clip`` (ours): the same with one GBR for the whole clip, which
  asks the frames to agree with each other (temporal consistency: the
  first-frame alignment of MAE-SN) instead of leaving each frame its own GBR.
- ``aligned_first`` (ours): MAE-SN's "first" alignment squared: one GBR per
  clip fitted on frame 0 alone, applied to every frame; ``aligned_signed_first``
  is its mean with ``aligned_signed``.
- ``aligned_signed``, ``aligned_clip_signed`` (ours, for data whose relief
  sign is observable: the generator's light-from-above prior): the same fits
  with λ ≥ 0. After each group's best plane is removed (weighted by
  1/var(target frame)), the least-squares residual is ``S_gg (1 − ρ²)`` with
  ρ the weighted correlation of prediction and target; the signed losses are
  ``S_gg (1 − ρ|ρ|)``: equal to the unconstrained loss where ρ ≥ 0 and worse
  than a flat prediction where ρ < 0, with a gradient that turns the sign
  (the hard constraint λ ≥ 0 would score every wrong sign as flat, with no
  gradient at all). ``aligned_both_signed`` is their mean: local shape frame
  by frame, and one reading and plane motion for the whole clip.
- ``aligned_clip_offsets_signed``, ``aligned_both_offsets_signed``: the clip
  terms with a free depth offset per frame (one α, β, λ ≥ 0 for the clip, τ
  per frame): motion along the optical axis is invisible to an orthographic
  camera, so the clip's τ would ask for what no image shows.

``relief_amplitude`` (ours) is not a loss of its own but a term added to one
(``nrdepth train --amplitude WEIGHT``): every loss above is blind to the
relief's scale (and a planar target scores 0 for any prediction, so nothing
teaches a flat sheet to come back flat). It compares the root-mean-square
relief of each frame (the frame minus its least-squares plane) of pred and
target on a log scale, ``(log(rms_pred + floor) − log(rms_target + floor))²``,
so it sets only the scale (the losses above, which standardise pred, keep
the shape) and needs the target in units the video shows: window widths (an
orthographic video of a surface scaled by s in x, y and z is the same video).

The signed losses take a masked target: NaN where a backdrop clip's view is
off the sheet. Those pixels weigh 0 and each frame's variance is over its
pixels on the sheet; the other losses refuse such a target.

The invariant losses average over pixels where the target's invariant is
defined: ``‖H_gt‖_F`` above ``MASK_RATIO`` × that frame's mean (flat and
planar regions are excluded; a frame with no such pixel contributes nothing).
"""

from __future__ import annotations

import math
from typing import Callable, Dict

import torch

__all__ = [
    "gbr_loss",
    "tr_sc_loss",
    "aligned_loss",
    "aligned_clip_loss",
    "aligned_signed_loss",
    "aligned_clip_signed_loss",
    "aligned_both_signed_loss",
    "aligned_clip_offsets_signed_loss",
    "aligned_both_offsets_signed_loss",
    "aligned_first_loss",
    "aligned_signed_first_loss",
    "relief_amplitude_loss",
    "relief_rms",
    "AMPLITUDE_FLOOR",
    "LOSSES",
    "MASKED_LOSSES",
    "get_loss",
    "derivatives",
]

MASK_RATIO = 1e-2
_EPS = 1e-12


def _frames(name: str, z: torch.Tensor) -> torch.Tensor:
    if not isinstance(z, torch.Tensor):
        raise TypeError(f"{name}: expected a torch.Tensor, got {type(z).__name__}")
    if z.dim() == 5 and z.shape[1] == 1:
        z = z[:, 0]
    if z.dim() != 4 or z.shape[-1] < 3 or z.shape[-2] < 3:
        raise ValueError(f"{name}: expected (B, T, H, W) or (B, 1, T, H, W) with H, W >= 3, got {tuple(z.shape)}")
    return z


def derivatives(z: torch.Tensor) -> Dict[str, torch.Tensor]:
    """Central differences of every frame of z (B, T, H, W) on the interior
    (B, T, H − 2, W − 2): keys x, y, xx, xy, yy (pixel units)."""
    c = z[..., 1:-1, 1:-1]
    right, left = z[..., 1:-1, 2:], z[..., 1:-1, :-2]
    down, up = z[..., 2:, 1:-1], z[..., :-2, 1:-1]
    return {
        "x": (right - left) / 2,
        "y": (down - up) / 2,
        "xx": right - 2 * c + left,
        "yy": down - 2 * c + up,
        "xy": (z[..., 2:, 2:] - z[..., 2:, :-2] - z[..., :-2, 2:] + z[..., :-2, :-2]) / 4,
    }


def _invariant(z: torch.Tensor, with_gradient: bool):
    d = derivatives(z)
    hessian = [d["xx"], math.sqrt(2.0) * d["xy"], d["yy"]]
    norm = torch.sqrt(sum(h * h for h in hessian) + _EPS)
    parts = ([d["x"], d["y"]] if with_gradient else []) + hessian
    return torch.stack([p / norm for p in parts], dim=-1), norm


def _unmasked(name: str, target: torch.Tensor) -> None:
    if not bool(torch.isfinite(target).all()):
        raise ValueError(f"target: {name} needs depth at every pixel; a masked target (NaN off the sheet, backdrop clips) takes a signed loss ({', '.join(MASKED_LOSSES)})")


def _masked_mse(pred: torch.Tensor, target: torch.Tensor, with_gradient: bool) -> torch.Tensor:
    pred, target = _frames("pred", pred), _frames("target", target)
    _unmasked("gbr" if not with_gradient else "tr_sc", target)
    if pred.shape != target.shape:
        raise ValueError(f"pred: expected the shape of target {tuple(target.shape)}, got {tuple(pred.shape)}")
    inv_pred, _ = _invariant(pred, with_gradient)
    with torch.no_grad():
        inv_target, norm = _invariant(target, with_gradient)
        frame_mean = norm.mean(dim=(-2, -1), keepdim=True)
        mask = (norm > MASK_RATIO * frame_mean).to(pred.dtype)
    squared = ((inv_pred - inv_target) ** 2).sum(-1)
    return (squared * mask).sum() / mask.sum().clamp_min(1.0) / inv_pred.shape[-1]


def gbr_loss(pred: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """ℓ_GBR: MSE of the normalised Hessians (complete GBR invariant)."""
    return _masked_mse(pred, target, with_gradient=False)


def tr_sc_loss(pred: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """ℓ_tr+sc: MSE of (∇z, ∇²z)/‖∇²z‖_F (invariant to z-stretch and z-translation)."""
    return _masked_mse(pred, target, with_gradient=True)


def _aligned(pred: torch.Tensor, target: torch.Tensor, per_clip: bool, ridge: float, first_frame: bool = False) -> torch.Tensor:
    pred, target = _frames("pred", pred), _frames("target", target)
    _unmasked("the unsigned aligned losses", target)
    if pred.shape != target.shape:
        raise ValueError(f"pred: expected the shape of target {tuple(target.shape)}, got {tuple(pred.shape)}")
    b, t, h, w = pred.shape
    groups, frames = (b, t) if per_clip else (b * t, 1)  # one GBR per group of frames
    ys, xs = torch.meshgrid(torch.linspace(-1, 1, h, dtype=pred.dtype, device=pred.device), torch.linspace(-1, 1, w, dtype=pred.dtype, device=pred.device), indexing="ij")
    p = pred.reshape(groups, frames * h * w)
    g = target.reshape(groups, frames * h * w)
    # Standardise the prediction so the ridge term is scale-free.
    p = (p - p.mean(1, keepdim=True)) / (p.std(1, keepdim=True) + 1e-8)
    ones = torch.ones_like(p)
    design = torch.stack([xs.reshape(-1).repeat(frames).expand_as(p), ys.reshape(-1).repeat(frames).expand_as(p), p, ones], dim=-1)  # (G, P, 4)
    fit, fit_g = (design[:, : h * w], g[:, : h * w]) if first_frame else (design, g)  # the frames the GBR is fitted on
    normal = fit.transpose(1, 2) @ fit + ridge * fit.shape[1] * torch.eye(4, dtype=pred.dtype, device=pred.device)
    coeffs = torch.linalg.solve(normal, fit.transpose(1, 2) @ fit_g.unsqueeze(-1))
    aligned = (design @ coeffs).reshape(b * t, h * w)
    g = target.reshape(b * t, h * w)
    variance = g.var(1, unbiased=False).clamp_min(1e-12)
    return (((aligned - g) ** 2).mean(1) / variance).mean()


def aligned_loss(pred: torch.Tensor, target: torch.Tensor, ridge: float = 1e-6) -> torch.Tensor:
    """Ours: MSE after the per-frame least-squares GBR alignment of pred onto
    target, divided by the target frame's variance; differentiable in pred."""
    return _aligned(pred, target, per_clip=False, ridge=ridge)


def aligned_clip_loss(pred: torch.Tensor, target: torch.Tensor, ridge: float = 1e-6) -> torch.Tensor:
    """Ours, for temporal consistency: as :func:`aligned_loss` but with one
    least-squares GBR for the whole clip, so the frames must agree with each
    other up to a single GBR (the symmetric form of MAE-SN's "first"
    alignment); still divided by each target frame's variance."""
    return _aligned(pred, target, per_clip=True, ridge=ridge)


def aligned_first_loss(pred: torch.Tensor, target: torch.Tensor, ridge: float = 1e-6) -> torch.Tensor:
    """Ours, MAE-SN's "first" alignment as a loss: one least-squares GBR per
    clip fitted on frame 0 alone and applied to every frame, each frame's
    squared error divided by its target's variance. What :func:`aligned_clip_loss`
    forgives, it does not: a frame 0 whose plane or scale is off carries its
    error into the whole clip, as it does in the metric."""
    return _aligned(pred, target, per_clip=True, ridge=ridge, first_frame=True)


def _signed(pred: torch.Tensor, target: torch.Tensor, per_clip: bool, offsets: bool = False) -> torch.Tensor:
    pred, target = _frames("pred", pred), _frames("target", target)
    if pred.shape != target.shape:
        raise ValueError(f"pred: expected the shape of target {tuple(target.shape)}, got {tuple(pred.shape)}")
    b, t, h, w = pred.shape
    groups, frames = (b, t) if per_clip else (b * t, 1)
    valid = torch.isfinite(target)
    masked = not bool(valid.all())
    if masked:  # NaN off the sheet: those pixels weigh 0 (an unmasked batch keeps the exact sums below)
        target = torch.where(valid, target, torch.zeros_like(target))
        valid = valid.to(pred.dtype)
        count = valid.sum((-2, -1), keepdim=True)
    if offsets:
        # A free depth offset per frame: each frame's mean is removed, and the
        # shared plane needs no constant column (x and y have zero mean).
        if masked:
            pred = pred - (pred * valid).sum((-2, -1), keepdim=True) / count.clamp_min(1)
            target = (target - target.sum((-2, -1), keepdim=True) / count.clamp_min(1)) * valid
        else:
            pred = pred - pred.mean((-2, -1), keepdim=True)
            target = target - target.mean((-2, -1), keepdim=True)
    ys, xs = torch.meshgrid(torch.linspace(-1, 1, h, dtype=pred.dtype, device=pred.device), torch.linspace(-1, 1, w, dtype=pred.dtype, device=pred.device), indexing="ij")
    if masked and offsets:
        # x and y centred on each frame's pixels on the sheet, as the depths are.
        centred = [(c - (c * valid).sum((-2, -1), keepdim=True) / count.clamp_min(1)).reshape(groups, frames * h * w) for c in (xs, ys)]
        plane = torch.stack(centred, -1)  # (G, P, 2)
    else:
        columns = [xs.reshape(-1), ys.reshape(-1)] + ([] if offsets else [torch.ones_like(xs).reshape(-1)])
        plane = torch.stack(columns, -1).repeat(frames, 1)  # (P, 2 or 3)
    # Weight 1/(var(target frame) · pixels per frame): the weighted sum of
    # squares of a group is the sum over its frames of MSE / variance.
    if masked:
        # The same over each frame's pixels on the sheet; a frame with fewer than 4 (a GBR's parameters) weighs 0.
        mean = target.sum((-2, -1), keepdim=True) / count.clamp_min(1)
        variance = (((target - mean) * valid) ** 2).sum((-2, -1), keepdim=True) / count.clamp_min(1)
        weight = valid * (count >= 4) / (variance.clamp_min(1e-12) * count.clamp_min(1))
        weight = weight.reshape(groups, frames * h * w)
    else:
        weight = 1.0 / (target.reshape(b * t, h * w).var(1, unbiased=False).clamp_min(1e-12) * h * w)
        weight = weight.reshape(groups, frames, 1).expand(groups, frames, h * w).reshape(groups, frames * h * w)
    p = pred.reshape(groups, frames * h * w)
    if masked:  # the same over the pixels on the sheet, so that nothing off it enters
        on = valid.reshape(groups, frames * h * w)
        n = on.sum(1, keepdim=True).clamp_min(2)
        centred = (p - (p * on).sum(1, keepdim=True) / n) * on
        p = centred / ((centred**2).sum(1, keepdim=True) / (n - 1)).sqrt().add(1e-8)
    else:
        p = (p - p.mean(1, keepdim=True)) / (p.std(1, keepdim=True) + 1e-8)  # scale-free, as in _aligned
    g = target.reshape(groups, frames * h * w)
    weighted_plane = plane * weight.unsqueeze(-1)  # (G, P, 3)
    normal = plane.transpose(-1, -2) @ weighted_plane + 1e-9 * torch.eye(plane.shape[-1], dtype=pred.dtype, device=pred.device)  # (G, 3, 3)

    def off_plane(v: torch.Tensor) -> torch.Tensor:
        coeffs = torch.linalg.solve(normal, (weighted_plane.transpose(1, 2) @ v.unsqueeze(-1)))
        return v - (plane @ coeffs).squeeze(-1)

    p, g = off_plane(p), off_plane(g)
    s_gg, s_pp, s_pg = (weight * g * g).sum(1), (weight * p * p).sum(1), (weight * p * g).sum(1)
    rho = s_pg / (s_pp * s_gg).clamp_min(1e-30).sqrt()  # clamped: finite gradients for flat frames
    return (s_gg * (1 - rho * rho.abs())).sum() / (b * t)


def aligned_signed_loss(pred: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """Ours, sign-aware: :func:`aligned_loss` with λ ≥ 0 (a wrong relief sign
    scores worse than a flat frame, and its gradient turns it)."""
    return _signed(pred, target, per_clip=False)


def aligned_clip_signed_loss(pred: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """Ours, sign-aware, one GBR (α, β, λ ≥ 0, τ) for the whole clip: one
    reading of the relief and the plane's motion over the clip."""
    return _signed(pred, target, per_clip=True)


def aligned_both_signed_loss(pred: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """Ours: the mean of :func:`aligned_signed_loss` and :func:`aligned_clip_signed_loss`."""
    return 0.5 * (_signed(pred, target, per_clip=False) + _signed(pred, target, per_clip=True))


def aligned_clip_offsets_signed_loss(pred: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """Ours: :func:`aligned_clip_signed_loss` with a free depth offset per
    frame, i.e. one (α, β, λ ≥ 0) for the clip and one τ per frame. Under an
    orthographic camera a surface's motion along the optical axis leaves no
    trace in the images (the generator's ``drift_z``), so the clip-wide τ
    asks the network for what it cannot see; the tilt's motion it can."""
    return _signed(pred, target, per_clip=True, offsets=True)


def aligned_both_offsets_signed_loss(pred: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """Ours: the mean of :func:`aligned_signed_loss` and :func:`aligned_clip_offsets_signed_loss`."""
    return 0.5 * (_signed(pred, target, per_clip=False) + _signed(pred, target, per_clip=True, offsets=True))


def aligned_signed_first_loss(pred: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """Ours: the mean of :func:`aligned_signed_loss` (local shape and its sign,
    frame by frame) and :func:`aligned_first_loss` (the clip read through
    frame 0's GBR: the plane's motion and the frames' agreement)."""
    return 0.5 * (_signed(pred, target, per_clip=False) + aligned_first_loss(pred, target))


AMPLITUDE_FLOOR = 2e-3
"""Floor of :func:`relief_amplitude_loss`'s log, in window widths: the median
relief of the generator's nearly flat surfaces (intensity below 0.01; that
of its default surfaces is ~0.037), so reliefs under it count as flat."""


def relief_rms(z: torch.Tensor) -> torch.Tensor:
    """Root-mean-square of each frame of z (B, T, H, W) minus its
    least-squares plane in the pixel coordinates: (B, T)."""
    z = _frames("z", z)
    h, w = z.shape[-2:]
    ys, xs = torch.meshgrid(torch.arange(h, dtype=z.dtype, device=z.device), torch.arange(w, dtype=z.dtype, device=z.device), indexing="ij")
    plane = torch.stack([xs.reshape(-1), ys.reshape(-1), torch.ones(h * w, dtype=z.dtype, device=z.device)], -1)  # (P, 3)
    flat = z.reshape(-1, h * w)
    relief = flat - (flat @ torch.linalg.pinv(plane).T) @ plane.T
    return relief.pow(2).mean(-1).add(1e-30).sqrt().reshape(z.shape[:-2])


def relief_amplitude_loss(pred: torch.Tensor, target: torch.Tensor, floor: float = AMPLITUDE_FLOOR) -> torch.Tensor:
    """Ours, a term to add to a GBR-invariant loss: the squared log ratio of
    each frame's relief amplitude (:func:`relief_rms`, ``floor`` added to
    both) of pred and target, averaged over frames; both in the same units
    (window widths in training)."""
    pred, target = _frames("pred", pred), _frames("target", target)
    if pred.shape != target.shape:
        raise ValueError(f"pred: expected the shape of target {tuple(target.shape)}, got {tuple(pred.shape)}")
    _unmasked("relief_amplitude_loss", target)
    with torch.no_grad():
        wanted = torch.log(relief_rms(target) + floor)
    return (torch.log(relief_rms(pred) + floor) - wanted).pow(2).mean()


LOSSES: Dict[str, Callable[[torch.Tensor, torch.Tensor], torch.Tensor]] = {
    "gbr": gbr_loss,
    "tr_sc": tr_sc_loss,
    "aligned": aligned_loss,
    "aligned_clip": aligned_clip_loss,
    "aligned_signed": aligned_signed_loss,
    "aligned_clip_signed": aligned_clip_signed_loss,
    "aligned_both_signed": aligned_both_signed_loss,
    "aligned_clip_offsets_signed": aligned_clip_offsets_signed_loss,
    "aligned_both_offsets_signed": aligned_both_offsets_signed_loss,
    "aligned_first": aligned_first_loss,
    "aligned_signed_first": aligned_signed_first_loss,
}


MASKED_LOSSES = ("aligned_signed", "aligned_clip_signed", "aligned_both_signed", "aligned_clip_offsets_signed", "aligned_both_offsets_signed")
"""The losses that take a masked target: NaN where the view is off the
sheet (``GeneratorConfig.backdrop_probability``); those pixels weigh 0."""


def get_loss(name: str) -> Callable[[torch.Tensor, torch.Tensor], torch.Tensor]:
    """The loss called ``name``: one of ``LOSSES``."""
    try:
        return LOSSES[name]
    except KeyError:
        raise ValueError(f"loss: expected one of {sorted(LOSSES)}, got {name!r}") from None

