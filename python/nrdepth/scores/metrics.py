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
is useful only below it. :func:`grid_contrast` looks for the seams of a
stitched video. Pure numpy, float64.
"""

from __future__ import annotations

from typing import Dict, Literal, Optional, Tuple

import numpy as np

__all__ = ["mae_sn", "flat_baseline", "gbr_fit", "gbr_align", "relief_signs", "sign_rates", "grid_contrast", "sparse_mae", "sparse_sign_rate", "sparse_baselines", "dense_baselines"]

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


def gbr_design(frame: np.ndarray, mask: Optional[np.ndarray] = None) -> np.ndarray:
    """The least-squares design of a GBR of ``frame`` (H, W): columns x, y,
    depth, 1 per pixel (rows: the pixels in ``mask``, or all)."""
    h, w = frame.shape
    y, x = np.mgrid[0:h, 0:w]
    design = np.column_stack([x.ravel(), y.ravel(), frame.ravel(), np.ones(h * w)])
    return design if mask is None else design[mask.ravel()]


def gbr_fit(pred: np.ndarray, gt: np.ndarray, mask: Optional[np.ndarray] = None) -> np.ndarray:
    """Least-squares (α, β, λ, τ) mapping one predicted frame (H, W) onto the
    ground truth (over the pixels of ``mask``, all by default);
    minimum-norm when the prediction is flat."""
    target = gt.ravel() if mask is None else gt[mask]
    coeffs, *_ = np.linalg.lstsq(gbr_design(pred, mask), target, rcond=None)
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
            out.append((gbr_design(p) @ gbr_fit(p, g, m)).reshape(g.shape))
            continue
        a = (gbr_design(p) @ first).reshape(g.shape)
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


def _periodic_spectrum(frame: np.ndarray) -> np.ndarray:
    """The 2-D DFT of the periodic component of ``frame`` (Moisan's periodic
    plus smooth decomposition, J. Math. Imaging Vis. 2011): the DFT of a
    frame whose opposite borders differ carries that jump on both frequency
    axes at every frequency; the smooth component ŝ = v̂ / (2 cos(2πq/H) +
    2 cos(2πr/W) − 4), with v the border jumps, takes it away."""
    h, w = frame.shape
    jumps = np.zeros_like(frame)
    jumps[0, :] += frame[-1, :] - frame[0, :]
    jumps[-1, :] += frame[0, :] - frame[-1, :]
    jumps[:, 0] += frame[:, -1] - frame[:, 0]
    jumps[:, -1] += frame[:, 0] - frame[:, -1]
    denominator = 2 * np.cos(2 * np.pi * np.arange(h) / h)[:, None] + 2 * np.cos(2 * np.pi * np.arange(w) / w)[None, :] - 4
    denominator[0, 0] = 1.0
    smooth = np.fft.fft2(jumps) / denominator
    smooth[0, 0] = 0.0
    return np.fft.fft2(frame) - smooth


def grid_contrast(depth: np.ndarray, period: int = 32) -> float:
    """How much a depth video (T, H, W) shows a grid of the given period
    (stitched patches' seams: half a 64-pixel patch). At each of the grid's
    frequencies, every multiple of ``side / period`` cycles along either axis
    below Nyquist, the power of the relief (each frame minus its
    least-squares plane; its periodic component) summed over frames is
    divided by the geometric mean of the power one cycle either side; the
    result is the geometric mean of these ratios, so every harmonic counts
    alike. A smooth spectrum gives about 1; seams (sharp: their power reaches
    the high harmonics, where a surface's own is small) give more, and a
    relief that lacks the grid's frequencies gives less. Invariant to a GBR
    of each frame. Comparing neighbours rather than taking the grid's share
    of all power keeps out what a share also counts (a relief smoother or
    rougher than the truth), and the periodic component keeps out the jump
    between a frame's opposite borders, which would put power on both axes
    at every frequency. An axis whose side is not a multiple of ``period``,
    or holds fewer than two periods, is skipped; a grid frequency with no
    power at it or beside it (a planar frame has none) is left out, and a
    video where that leaves nothing has no contrast (``ValueError``)."""
    depth = _check("depth", depth)
    if isinstance(period, bool) or not isinstance(period, (int, np.integer)) or period < 3:
        raise ValueError(f"period: expected an integer ≥ 3 (a grid below Nyquist), got {period!r}")
    _, h, w = depth.shape
    measured = [side % period == 0 and side // period >= 2 for side in (h, w)]
    if not any(measured):
        raise ValueError(f"period: expected a divisor of a frame side that leaves at least two periods, got {period} for {h}×{w} frames")
    design = gbr_design(np.zeros((h, w)))[:, [0, 1, 3]]  # x, y, 1
    lines = [np.zeros(h), np.zeros(w)]  # power along the y and x frequency axes, summed over frames
    for frame in _unit_scale(depth)[0]:
        coeffs, *_ = np.linalg.lstsq(design, frame.ravel(), rcond=None)
        relief = frame - (design @ coeffs).reshape(h, w)
        if relief.std() < 1e-9:  # planar up to rounding (the video is scaled to a peak of 1): no relief to weigh
            continue
        power = np.abs(_periodic_spectrum(relief / relief.std())) ** 2
        lines[0] += power[:, 0]
        lines[1] += power[0, :]
    logs = [np.log(line[k]) - 0.5 * np.log(line[k - 1] * line[k + 1])
            for side, line, use in zip((h, w), lines, measured) if use
            for k in range(side // period, side // 2, side // period)
            if min(line[k - 1 : k + 2]) > 0]
    if not logs:
        raise ValueError("depth: no relief power at the grid's frequencies or beside them (planar frames?); the contrast is undefined")
    return float(np.exp(np.mean(logs)))


def _sparse_check(depth: np.ndarray, uv: np.ndarray, z: np.ndarray, mask: Optional[np.ndarray]) -> Tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    depth, uv, z = np.asarray(depth, np.float64), np.asarray(uv, np.float64), np.asarray(z, np.float64)
    if depth.ndim != 3:
        raise ValueError(f"depth: expected (F, H, W), got shape {depth.shape}")
    if uv.shape != (len(depth), 2, z.shape[-1]) or z.shape != (len(depth), uv.shape[-1]):
        raise ValueError(f"uv, z: expected (F, 2, N) and (F, N) with F = {len(depth)}, got {uv.shape} and {z.shape}")
    mask = np.ones(z.shape, bool) if mask is None else np.asarray(mask, bool)
    if mask.shape != z.shape or (mask.sum(axis=1) < 4).any():
        raise ValueError(f"mask: expected (F, N) booleans keeping at least 4 points a frame, got {mask.shape}")
    _, h, w = depth.shape
    u, v = uv[:, 0][mask], uv[:, 1][mask]
    if u.min() < 0 or v.min() < 0 or u.max() > w - 1 or v.max() > h - 1:
        raise ValueError(f"uv: points outside the {w}×{h} frame")
    return depth, uv, z, mask


def _sparse_fits(depth: np.ndarray, uv: np.ndarray, z: np.ndarray, mask: Optional[np.ndarray]) -> list:
    """Per frame: the absolute errors and λ of the fit ``a·u + b·v + λ·depth + t ≈ z``."""
    depth, uv, z, mask = _sparse_check(depth, uv, z, mask)
    fits = []
    for f in range(len(depth)):
        u, v, target = uv[f, 0][mask[f]], uv[f, 1][mask[f]], z[f][mask[f]]
        sample = _bilinear(depth[f], u, v)
        design = np.stack([u, v, sample, np.ones_like(sample)], axis=1)
        coef, *_ = np.linalg.lstsq(design, target, rcond=None)
        fits.append((np.abs(design @ coef - target), coef[2]))
    return fits


def sparse_mae(depth: np.ndarray, uv: np.ndarray, z: np.ndarray, mask: Optional[np.ndarray] = None) -> float:
    """Mean absolute error, in the units of ``z``, of a depth video against
    sparse 3-D ground truth (``kinect_paper``'s ``gt_mdh.npz``; its README's
    fair score): ``depth`` (F, H, W) holds the frames that carry ground
    truth, ``uv`` (F, 2, N) the points' pixel positions (column, row;
    pixel centres at integers), ``z`` (F, N) their true depths and ``mask``
    (F, N) the points to score (default: all). The depth is sampled
    bilinearly at ``uv`` and fitted per frame by least squares,
    ``a·u + b·v + λ·depth + t ≈ z`` (the GBR in image coordinates, λ's sign
    free, as MAE-SN); the mean is over frames of each frame's mean. Points
    outside the frame are an error."""
    return float(np.mean([errors.mean() for errors, _ in _sparse_fits(depth, uv, z, mask)]))


def sparse_sign_rate(depth: np.ndarray, uv: np.ndarray, z: np.ndarray, mask: Optional[np.ndarray] = None) -> float:
    """The share of frames whose relief :func:`sparse_mae`'s fit reads with
    the right sign (λ > 0: ``depth`` and ``z`` both grow away from the camera)."""
    return float(np.mean([lam > 0 for _, lam in _sparse_fits(depth, uv, z, mask)]))


def sparse_baselines(uv: np.ndarray, z: np.ndarray, mask: Optional[np.ndarray] = None) -> Dict[str, float]:
    """The references beside :func:`sparse_mae`, fitted the same way, in the
    units of ``z``: ``"plane"`` (a flat prediction: a·u + b·v + t),
    ``"bowl"`` (a fixed paraboloid (u − u₀)² + (v − v₀)² under the GBR, the
    same in every frame: a shape-blind prior; any centre fits the same) and
    ``"quadratic"`` (the best quadratic in u, v fitted to the truth, 6
    parameters a frame: the best a smooth prior could reach)."""
    uv, z = np.asarray(uv, np.float64), np.asarray(z, np.float64)
    mask = np.ones(z.shape, bool) if mask is None else np.asarray(mask, bool)
    out: Dict[str, list] = {"plane": [], "bowl": [], "quadratic": []}
    for f in range(len(z)):
        u, v, target = uv[f, 0][mask[f]], uv[f, 1][mask[f]], z[f][mask[f]]
        one = np.ones_like(u)
        designs = {"plane": [u, v, one], "bowl": [u, v, u * u + v * v, one], "quadratic": [u, v, u * u, u * v, v * v, one]}
        for name, columns in designs.items():
            a = np.stack(columns, axis=1)
            coef, *_ = np.linalg.lstsq(a, target, rcond=None)
            out[name].append(np.abs(a @ coef - target).mean())
    return {name: float(np.mean(e)) for name, e in out.items()}


def dense_baselines(gt: np.ndarray, mask: Optional[np.ndarray] = None) -> Dict[str, float]:
    """MAE-SN per frame of the shape-blind references beside a dense depth
    video (T, H, W): ``"plane"`` (:func:`flat_baseline`), ``"bowl"`` (a
    fixed paraboloid (x − x₀)² + (y − y₀)², the same in every frame, under
    each frame's GBR) and ``"quadratic"`` (the best quadratic in x, y fitted
    to each frame of the truth: the best a smooth prior could reach)."""
    gt = _check("gt", gt, mask)
    mask = _check_mask(mask, gt.shape)
    t, h, w = gt.shape
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    bowl = np.broadcast_to(((x - w / 2) ** 2 + (y - h / 2) ** 2), gt.shape)
    quadratic = []
    for k in range(t):
        m = np.ones((h, w), bool) if mask is None else mask[k]
        a = np.stack([np.ones(m.sum()), x[m], y[m], x[m] ** 2, x[m] * y[m], y[m] ** 2], axis=1)
        coef, *_ = np.linalg.lstsq(a, gt[k][m], rcond=None)
        quadratic.append(np.abs(a @ coef - gt[k][m]).mean() / gt[k][m].std())
    return {"plane": flat_baseline(gt, "frame", mask=mask), "bowl": mae_sn(bowl, gt, "frame", mask=mask), "quadratic": float(np.mean(quadratic))}


def _bilinear(image: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``image`` sampled at columns ``u`` and rows ``v`` (inside the image) by bilinear interpolation."""
    h, w = image.shape
    x0 = np.clip(np.floor(u).astype(int), 0, w - 2) if w > 1 else np.zeros(len(u), int)
    y0 = np.clip(np.floor(v).astype(int), 0, h - 2) if h > 1 else np.zeros(len(v), int)
    fx, fy = u - x0, v - y0
    x1, y1 = np.minimum(x0 + 1, w - 1), np.minimum(y0 + 1, h - 1)
    top = image[y0, x0] * (1 - fx) + image[y0, x1] * fx
    bottom = image[y1, x0] * (1 - fx) + image[y1, x1] * fx
    return top * (1 - fy) + bottom * fy
