"""MAE-SN, the paper's error measure of a depth video, and its flat baseline.

For each frame t, least squares fits (α, β, λ, τ) so that
``α x + β y + λ z_pred + τ ≈ z_gt`` over the frame's pixels (x, y: column and
row index; λ is not constrained in sign), then

    MAE-SN = (1/T) Σ_t mean|aligned_t − gt_t| / std(gt_t).

``align="first"`` fits on frame 0 only and applies that alignment to every
frame (it measures temporal consistency). ``align="first_offset"`` (ours, a
diagnostic) does the same but refits each frame's offset τ: under an
orthographic camera a surface's motion along the optical axis leaves no trace
in the video, so no method can be asked for it. The *flat baseline* is the score of
a constant prediction, i.e. of the best plane ``α x + β y + τ``: a prediction
is useful only below it. Pure numpy, float64.
"""

from __future__ import annotations

from typing import Dict, Literal, Optional, Tuple

import numpy as np

__all__ = ["mae_sn", "flat_baseline", "gbr_fit", "gbr_align", "relief_signs", "sign_rates"]

Align = Literal["frame", "first", "first_offset"]


def _check(name: str, a: np.ndarray, mask: Optional[np.ndarray] = None) -> np.ndarray:
    a = np.asarray(a)
    if a.dtype.kind not in "fiu":
        raise TypeError(f"{name}: expected a numeric array, got dtype {a.dtype}")
    if a.ndim != 3 or min(a.shape) < 1:
        raise ValueError(f"{name}: expected a depth video (T, H, W), got shape {a.shape}")
    if not np.isfinite(a if mask is None else a[mask]).all():
        raise ValueError(f"{name}: expected finite values{'' if mask is None else ' inside mask'} (found NaN or inf)")
    a = a.astype(np.float64)
    return a if mask is None else np.where(mask, a, 0.0)


def _check_mask(mask: Optional[np.ndarray], shape: Tuple[int, ...]) -> Optional[np.ndarray]:
    if mask is None:
        return None
    mask = np.asarray(mask)
    if mask.dtype != np.bool_ or mask.shape != shape:
        raise ValueError(f"mask: expected a bool array of the videos' shape {shape}, got {mask.dtype} {mask.shape}")
    few = [t for t, m in enumerate(mask) if m.sum() < 4]
    if few:
        raise ValueError(f"mask: frame {few[0]} has fewer than 4 pixels (a GBR has 4 parameters)")
    return mask


def _design(frame: np.ndarray, mask: Optional[np.ndarray] = None) -> np.ndarray:
    h, w = frame.shape
    y, x = np.mgrid[0:h, 0:w]
    design = np.column_stack([x.ravel(), y.ravel(), frame.ravel(), np.ones(h * w)])
    return design if mask is None else design[mask.ravel()]


def gbr_fit(pred: np.ndarray, gt: np.ndarray, mask: Optional[np.ndarray] = None) -> np.ndarray:
    """Least-squares (α, β, λ, τ) mapping one predicted frame (H, W) onto the
    ground truth (over the pixels of ``mask``, all by default);
    minimum-norm when the prediction is flat."""
    target = gt.ravel() if mask is None else gt[mask]
    coeffs, *_ = np.linalg.lstsq(_design(pred, mask), target, rcond=None)
    return coeffs


def _check_pair(pred: np.ndarray, gt: np.ndarray, align: Align, mask: Optional[np.ndarray] = None):
    mask = _check_mask(mask, np.shape(gt))
    pred, gt = _check("pred", pred, mask), _check("gt", gt, mask)
    if pred.shape != gt.shape:
        raise ValueError(f"pred: expected the shape of gt {gt.shape}, got {pred.shape}")
    if align not in ("frame", "first", "first_offset"):
        raise ValueError(f"align: expected 'frame', 'first' or 'first_offset', got {align!r}")
    return pred, gt, mask


def _unit_scale(a: np.ndarray) -> Tuple[np.ndarray, float]:
    """``a`` divided by its largest magnitude, and that magnitude: least
    squares and variances then work in units of order one whatever the data's
    (a 1e-300-scale prediction would fall below lstsq's rank cut-off)."""
    peak = float(np.abs(a).max())
    return (a / peak, peak) if peak > 0 else (a, 1.0)


def _frame_masks(mask: Optional[np.ndarray], t: int) -> list:
    return [None] * t if mask is None else list(mask)


def _aligned(pred: np.ndarray, gt: np.ndarray, align: Align, mask: Optional[np.ndarray] = None) -> np.ndarray:
    masks = _frame_masks(mask, len(pred))
    first = gbr_fit(pred[0], gt[0], masks[0])
    out = []
    for p, g, m in zip(pred, gt, masks):
        if align == "frame":
            out.append((_design(p) @ gbr_fit(p, g, m)).reshape(g.shape))
            continue
        a = (_design(p) @ first).reshape(g.shape)
        if align == "first_offset":  # frame 0's α, β, λ; this frame's own τ
            a = a + ((g - a)[m] if m is not None else (g - a)).mean()
        out.append(a)
    return np.stack(out)


def gbr_align(pred: np.ndarray, gt: np.ndarray, align: Align = "frame", mask: Optional[np.ndarray] = None) -> np.ndarray:
    """The prediction (T, H, W) mapped onto the ground truth by the
    least-squares GBR of each frame (or of frame 0 for ``align="first"``),
    fitted over ``mask`` (all pixels by default): float64 (T, H, W), the
    depth MAE-SN scores. Useful to show a prediction in the ground truth's
    units."""
    pred, gt, mask = _check_pair(pred, gt, align, mask)
    gt, peak = _unit_scale(gt)
    return _aligned(_unit_scale(pred)[0], gt, align, mask) * peak


def mae_sn(pred: np.ndarray, gt: np.ndarray, align: Align = "frame", mask: Optional[np.ndarray] = None) -> float:
    """MAE-SN of a predicted depth video against the ground truth, both
    (T, H, W). ``mask`` (bool, same shape) restricts fits and scores to
    ground-truth pixels (the truth may be NaN outside it), e.g. the part of a
    real frame a depth sensor saw. A constant ground-truth frame (standard
    deviation 0) has no score: ``ValueError`` naming the frame."""
    pred, gt, mask = _check_pair(pred, gt, align, mask)
    pred, gt = _unit_scale(pred)[0], _unit_scale(gt)[0]
    scores = []
    for t, (a, g, m) in enumerate(zip(_aligned(pred, gt, align, mask), gt, _frame_masks(mask, len(gt)))):
        if m is not None:
            a, g = a[m], g[m]
        scale = g.std()
        if not scale > 1e-12:
            raise ValueError(f"gt: frame {t} is constant; MAE-SN divides by its standard deviation and is undefined there")
        scores.append(np.abs(a - g).mean() / scale)
    return float(np.mean(scores))


def flat_baseline(gt: np.ndarray, align: Align = "frame", mask: Optional[np.ndarray] = None) -> float:
    """MAE-SN of a flat (constant) prediction: the trivial baseline."""
    return mae_sn(np.zeros(np.shape(gt)), gt, align, mask)


def relief_signs(pred: np.ndarray, gt: np.ndarray, mask: Optional[np.ndarray] = None) -> np.ndarray:
    """Sign (+1, −1, or 0 for a flat prediction) of λ in each frame's
    least-squares GBR fit of pred onto gt, both (T, H, W): int8 (T,)."""
    pred, gt, mask = _check_pair(pred, gt, "frame", mask)
    pred, gt = _unit_scale(pred)[0], _unit_scale(gt)[0]
    return np.array([np.sign(gbr_fit(p, g, m)[2]) for p, g, m in zip(pred, gt, _frame_masks(mask, len(gt)))], dtype=np.int8)


def sign_rates(pred: np.ndarray, gt: np.ndarray, mask: Optional[np.ndarray] = None) -> Dict[str, float]:
    """``sign_correct``: the fraction of frames whose fitted λ is positive;
    ``flip``: 1.0 if the sign of λ changes inside the clip, else 0.0."""
    signs = relief_signs(pred, gt, mask)
    return {"sign_correct": float(np.mean(signs > 0)), "flip": float(len(set(signs[signs != 0].tolist())) > 1)}
