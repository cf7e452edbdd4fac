"""MAE-SN, the paper's error measure of a depth video, and its flat baseline.

For each frame t, least squares fits (α, β, λ, τ) so that
``α x + β y + λ z_pred + τ ≈ z_gt`` over the frame's pixels (x, y: column and
row index; λ is not constrained in sign), then

    MAE-SN = (1/T) Σ_t mean|aligned_t − gt_t| / std(gt_t).

``align="first"`` fits on frame 0 only and applies that alignment to every
frame (it measures temporal consistency). The *flat baseline* is the score of
a constant prediction, i.e. of the best plane ``α x + β y + τ``: a prediction
is useful only below it. Pure numpy, float64.
"""

from __future__ import annotations

from typing import Dict, Literal, Tuple

import numpy as np

__all__ = ["mae_sn", "flat_baseline", "gbr_fit", "gbr_align", "relief_signs", "sign_rates"]

Align = Literal["frame", "first"]


def _check(name: str, a: np.ndarray) -> np.ndarray:
    a = np.asarray(a)
    if a.dtype.kind not in "fiu":
        raise TypeError(f"{name}: expected a numeric array, got dtype {a.dtype}")
    if a.ndim != 3 or min(a.shape) < 1:
        raise ValueError(f"{name}: expected a depth video (T, H, W), got shape {a.shape}")
    if not np.isfinite(a).all():
        raise ValueError(f"{name}: expected finite values (found NaN or inf)")
    return a.astype(np.float64)


def _design(frame: np.ndarray) -> np.ndarray:
    h, w = frame.shape
    y, x = np.mgrid[0:h, 0:w]
    return np.column_stack([x.ravel(), y.ravel(), frame.ravel(), np.ones(h * w)])


def gbr_fit(pred: np.ndarray, gt: np.ndarray) -> np.ndarray:
    """Least-squares (α, β, λ, τ) mapping one predicted frame (H, W) onto the
    ground truth; minimum-norm when the prediction is flat."""
    coeffs, *_ = np.linalg.lstsq(_design(pred), gt.ravel(), rcond=None)
    return coeffs


def _check_pair(pred: np.ndarray, gt: np.ndarray, align: Align):
    pred, gt = _check("pred", pred), _check("gt", gt)
    if pred.shape != gt.shape:
        raise ValueError(f"pred: expected the shape of gt {gt.shape}, got {pred.shape}")
    if align not in ("frame", "first"):
        raise ValueError(f"align: expected 'frame' or 'first', got {align!r}")
    return pred, gt


def _unit_scale(a: np.ndarray) -> Tuple[np.ndarray, float]:
    """``a`` divided by its largest magnitude, and that magnitude: least
    squares and variances then work in units of order one whatever the data's
    (a 1e-300-scale prediction would fall below lstsq's rank cut-off)."""
    peak = float(np.abs(a).max())
    return (a / peak, peak) if peak > 0 else (a, 1.0)


def _aligned(pred: np.ndarray, gt: np.ndarray, align: Align) -> np.ndarray:
    first = gbr_fit(pred[0], gt[0])
    return np.stack([(_design(p) @ (first if align == "first" else gbr_fit(p, g))).reshape(g.shape) for p, g in zip(pred, gt)])


def gbr_align(pred: np.ndarray, gt: np.ndarray, align: Align = "frame") -> np.ndarray:
    """The prediction (T, H, W) mapped onto the ground truth by the
    least-squares GBR of each frame (or of frame 0 for ``align="first"``):
    float64 (T, H, W), the depth MAE-SN scores. Useful to show a prediction in
    the ground truth's units."""
    pred, gt = _check_pair(pred, gt, align)
    gt, peak = _unit_scale(gt)
    return _aligned(_unit_scale(pred)[0], gt, align) * peak


def mae_sn(pred: np.ndarray, gt: np.ndarray, align: Align = "frame") -> float:
    """MAE-SN of a predicted depth video against the ground truth, both
    (T, H, W). A constant ground-truth frame (standard deviation 0) has no
    score: ``ValueError`` naming the frame."""
    pred, gt = _check_pair(pred, gt, align)
    pred, gt = _unit_scale(pred)[0], _unit_scale(gt)[0]
    scores = []
    for t, (a, g) in enumerate(zip(_aligned(pred, gt, align), gt)):
        scale = g.std()
        if not scale > 1e-12:
            raise ValueError(f"gt: frame {t} is constant; MAE-SN divides by its standard deviation and is undefined there")
        scores.append(np.abs(a - g).mean() / scale)
    return float(np.mean(scores))


def flat_baseline(gt: np.ndarray, align: Align = "frame") -> float:
    """MAE-SN of a flat (constant) prediction: the trivial baseline."""
    gt = _check("gt", gt)
    return mae_sn(np.zeros_like(gt), gt, align)


def relief_signs(pred: np.ndarray, gt: np.ndarray) -> np.ndarray:
    """Sign (+1, −1, or 0 for a flat prediction) of λ in each frame's
    least-squares GBR fit of pred onto gt, both (T, H, W): int8 (T,)."""
    pred, gt = _check_pair(pred, gt, "frame")
    pred, gt = _unit_scale(pred)[0], _unit_scale(gt)[0]
    return np.array([np.sign(gbr_fit(p, g)[2]) for p, g in zip(pred, gt)], dtype=np.int8)


def sign_rates(pred: np.ndarray, gt: np.ndarray) -> Dict[str, float]:
    """``sign_correct``: the fraction of frames whose fitted λ is positive;
    ``flip``: 1.0 if the sign of λ changes inside the clip, else 0.0."""
    signs = relief_signs(pred, gt)
    return {"sign_correct": float(np.mean(signs > 0)), "flip": float(len(set(signs[signs != 0].tolist())) > 1)}
