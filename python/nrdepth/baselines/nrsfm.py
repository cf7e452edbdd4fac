"""Non-rigid structure from motion baselines (the paper's comparison), in
numpy/scipy, following Gotardo and Martinez's published method and code as
written down in ``shared/nrsfm-notes.md``.

Measurements ``W`` (2T × n): rows 2t and 2t + 1 are the x and y image
coordinates of the n tracked points in frame t (orthographic camera).
Shapes are 3T × n (rows 3t .. 3t + 2: x, y, z of frame t).

- :func:`cameras`: orthographic cameras R_t (2 × 3 each, stacked 2T × 3) by
  the Euclidean upgrade of a low-rank factorisation of the centred ``W``
  (the PTA upgrade with its incremental extension): minimise
  ``(1/T) Σ_t (|a_t|² − 1)² + (|b_t|² − 1)² + (a_t·b_t)²`` over Q, where
  (a_t, b_t) are frame t's rows of ``M Q``.
- :func:`csf2`: "Non-rigid structure from motion with complementary rank-3
  spaces" (CVPR 2011). Shape coefficients are a smooth trajectory in a DCT
  basis of d functions, C = Ω_d X (T × K); each of K rank-3 spaces takes in
  turn what the previous ones left of ``W``:
  ``S_k = M_k⁺ R_{k−1}``, ``R_k = R_{k−1} − M_k S_k`` with
  ``M_k = [c_tk R_t]_t``, and X minimises ``‖R_K‖²_F / (4Tn)`` by damped
  Gauss–Newton (variable projection: the S_k are eliminated). The shape of
  frame t is ``Σ_k C[t, k] S_k`` (object frame). Deterministic: X starts at
  the identity.
- :func:`ksta`: "Kernel non-rigid structure from motion" (ICCV 2011) in our
  reading of its description (the authors' public code found is a later
  rotation-invariant-kernel variant): a Gaussian kernel on the shape
  coefficients of a first CSF2 solution gives, by kernel PCA, the coefficient
  basis of a second solve.
- :func:`error_3d`: the benchmark's 3-D error (centred frames, one global
  least-squares rotation onto the truth, mean point distance over the mean
  per-row standard deviation of the truth).
"""

from __future__ import annotations

import math
from typing import NamedTuple, Optional

import numpy as np

__all__ = ["cameras", "dct_basis", "kernel_basis", "csf2", "ksta", "error_3d", "CSF2Result"]


def _check_tracks(W: np.ndarray, name: str = "W") -> np.ndarray:
    W = np.asarray(W)
    if W.dtype.kind not in "fiu":
        raise TypeError(f"{name}: expected a numeric array, got dtype {W.dtype}")
    if W.ndim != 2 or W.shape[0] % 2 or W.shape[0] < 4:
        raise ValueError(f"{name}: expected (2T, n) tracks with an even number of rows and T >= 2, got shape {W.shape}")
    if W.shape[1] < 4:
        raise ValueError(f"{name}: expected at least 4 points, got {W.shape[1]}")
    if not np.isfinite(W).all():
        raise ValueError(f"{name}: expected finite values (found NaN or inf)")
    return W.astype(np.float64)


def cameras(W: np.ndarray) -> np.ndarray:
    """Orthographic cameras (2T × 3) of the tracks ``W`` (2T × n): the PTA
    Euclidean upgrade, extended three columns of the factorisation at a time
    while the metric cost falls. Not re-orthonormalised."""
    from scipy.optimize import minimize

    W = _check_tracks(W)
    T = W.shape[0] // 2
    Wc = W - W.mean(axis=1, keepdims=True)
    U, s, _ = np.linalg.svd(Wc, full_matrices=False)
    ns = 3 * math.ceil(np.count_nonzero(s / s[0] > 1e-4) / 3)
    if ns > len(s):
        ns -= 3
    M = U[:, :ns] * np.sqrt(s[:ns])

    def cost(q: np.ndarray, Mm: np.ndarray):
        Q = q.reshape(-1, 3)
        R = Mm @ Q
        a, b = R[0::2], R[1::2]
        na, nb, ab = (a * a).sum(1) - 1, (b * b).sum(1) - 1, (a * b).sum(1)
        f = (na**2 + nb**2 + ab**2).sum() / T
        G = np.empty_like(R)
        G[0::2] = (4 * na[:, None] * a + 2 * ab[:, None] * b) / T
        G[1::2] = (4 * nb[:, None] * b + 2 * ab[:, None] * a) / T
        return f, (Mm.T @ G).ravel()

    Q, best = np.eye(3), math.inf
    if ns == 3:  # rigid (rank 3): the schedule below would never solve; one solve on the 3 columns
        result = minimize(cost, Q.ravel(), args=(M,), jac=True, method="BFGS", options={"gtol": 1e-10, "maxiter": 2000})
        Q = result.x.reshape(3, 3)
    while Q.shape[0] + 3 <= ns:
        start = np.vstack([Q, np.zeros((3, 3))])
        Mm = M[:, : start.shape[0]]
        result = minimize(cost, start.ravel(), args=(Mm,), jac=True, method="BFGS", options={"gtol": 1e-10, "maxiter": 2000})
        if result.fun >= best:
            break
        Q, best = result.x.reshape(-1, 3), result.fun
    return M[:, : Q.shape[0]] @ Q


def dct_basis(T: int, d: int) -> np.ndarray:
    """The first d orthonormal DCT-II basis vectors over T frames (T × d)."""
    if not (isinstance(T, int) and isinstance(d, int) and 1 <= d <= T):
        raise ValueError(f"d: expected an int in [1, T = {T}], got {d!r}")
    t = np.arange(T)[:, None]
    k = np.arange(d)[None, :]
    basis = np.cos(np.pi * (2 * t + 1) * k / (2 * T)) * math.sqrt(2.0 / T)
    basis[:, 0] = math.sqrt(1.0 / T)
    return basis


class CSF2Result(NamedTuple):
    shapes: np.ndarray
    """3T × n: frame t's 3-D points (object frame), rows 3t .. 3t + 2."""
    cameras: np.ndarray
    """2T × 3: frame t's orthographic camera, rows 2t, 2t + 1."""
    coefficients: np.ndarray
    """T × K: the shape coefficients C = Ω_d X."""
    rmse: float
    """Root mean square reprojection error, ``W``'s units."""
    iterations: int


def _spaces(X: np.ndarray, B: np.ndarray, Rs: np.ndarray, Wc: np.ndarray):
    """M_k (2T × 3 each), their pseudo-inverses, S_k (3 × n each) and the
    residuals R_1 … R_K (2T × n each; the last is the model's)."""
    C = B @ X
    K = X.shape[1]
    R = Wc
    Ms, pinvs, Ss, Rk = [], [], [], []
    for k in range(K):
        Mk = np.repeat(C[:, k], 2)[:, None] * Rs  # rows 2t, 2t+1: c_tk R_t
        pk = np.linalg.pinv(Mk)
        Sk = pk @ R
        R = R - Mk @ Sk
        Ms.append(Mk), pinvs.append(pk), Ss.append(Sk), Rk.append(R)
    return Ms, pinvs, Ss, Rk


def _gradient(blocks: np.ndarray, Ms: list, pinvs: list, Ss: list, Rk: list, c: float) -> np.ndarray:
    """The exact gradient (d × K) of f = c ‖R_K‖² / 2 in X. Kaufman's
    variable-projection Jacobian (the authors') drops the change of M_k⁺
    seen through the later spaces, which stalls the descent where K > 1.
    With Z_k = Π_{k+1} … Π_K R_K and E_i = ∂M_k/∂X[i, k] (``blocks[:, i]``):
    ∂f/∂X[i, k] = −c (⟨Π_k Z_k, E_i S_k⟩ + ⟨E_i, R_k Z_kᵀ M_k⁺ᵀ⟩)."""
    K, d = len(Ms), blocks.shape[1]
    g = np.zeros((d, K))
    Z = Rk[-1]
    for k in reversed(range(K)):
        if k < K - 1:
            Z = Z - Ms[k + 1] @ (pinvs[k + 1] @ Z)
        projected = Z - Ms[k] @ (pinvs[k] @ Z)
        first = np.einsum("tia,tn,an->i", blocks, projected, Ss[k], optimize=True)
        second = np.einsum("tia,ta->i", blocks, Rk[k] @ (Z.T @ pinvs[k].T))
        g[:, k] = -c * (first + second)
    return g


def csf2(
    W: np.ndarray,
    K: int,
    d: int,
    Rs: Optional[np.ndarray] = None,
    max_iterations: int = 300,
    tolerance: float = 1e-12,
    basis: Optional[np.ndarray] = None,
    start: Optional[np.ndarray] = None,
) -> CSF2Result:
    """CSF2 on tracks ``W`` (2T × n) with K complementary rank-3 spaces and
    d DCT functions (1 ≤ d ≤ T, 1 ≤ K ≤ d). ``Rs`` (2T × 3): known cameras,
    else :func:`cameras`. ``basis`` (T × d): another coefficient basis in
    place of the DCT's (:func:`ksta` passes a kernel one). ``start`` (d × K):
    the first X (default: the identity's first K columns)."""
    W = _check_tracks(W)
    T, n = W.shape[0] // 2, W.shape[1]
    if isinstance(d, bool) or not isinstance(d, int) or not 1 <= d <= T:
        raise ValueError(f"d: expected an int in [1, T = {T}], got {d!r}")
    if isinstance(K, bool) or not isinstance(K, int) or not 1 <= K <= d:
        raise ValueError(f"K: expected an int in [1, d = {d}], got {K!r}")
    Wc = W - W.mean(axis=1, keepdims=True)
    Rs = cameras(W) if Rs is None else np.asarray(Rs, dtype=np.float64)
    if Rs.shape != (2 * T, 3):
        raise ValueError(f"Rs: expected (2T, 3) = {(2 * T, 3)}, got {Rs.shape}")
    B = dct_basis(T, d) if basis is None else np.asarray(basis, dtype=np.float64)
    if B.shape != (T, d) or not np.isfinite(B).all():
        raise ValueError(f"basis: expected a finite (T, d) = {(T, d)} array, got {B.shape}")
    c = 1.0 / (2 * T * n)
    # Bnr = D (B ⊗ I3): block i of columns is [B[t, i] R_t]_t.
    Bnr = np.concatenate([np.repeat(B[:, i], 2)[:, None] * Rs for i in range(d)], axis=1)

    def cost(X: np.ndarray) -> float:
        return float((_spaces(X, B, Rs, Wc)[3][-1] ** 2).sum()) * c / 2

    X = np.eye(d, K) if start is None else np.asarray(start, dtype=np.float64)
    if X.shape != (d, K) or not np.isfinite(X).all():
        raise ValueError(f"start: expected a finite (d, K) = {(d, K)} array, got {X.shape}")
    delta, f = 1e-4, cost(X)
    iterations = 0
    for iterations in range(1, max_iterations + 1):
        Ms, pinvs, Ss, Rk = _spaces(X, B, Rs, Wc)
        # Gauss–Newton matrix of the authors (variable projection, Kaufman's
        # Jacobian): A_k = Π_K … Π_k Bnr with Π_k = I − M_k M_k⁺.
        A = []
        for k in range(K):
            a = Bnr
            for m in range(k, K):
                a = a - Ms[m] @ (pinvs[m] @ a)
            A.append(a.reshape(2 * T, d, 3))
        SS = [[Ss[k] @ Ss[l].T for l in range(K)] for k in range(K)]
        H = np.zeros((d, K, d, K))
        for k in range(K):
            for l in range(k, K):
                block = np.einsum("tia,tjb,ab->ij", A[k], A[l], SS[k][l], optimize=True) * c  # contracted pairwise, not as one 5-index loop
                H[:, k, :, l] = block
                H[:, l, :, k] = block.T
        g = _gradient(Bnr.reshape(2 * T, d, 3), Ms, pinvs, Ss, Rk, c)
        H = H.reshape(d * K, d * K)
        g = g.ravel()
        while True:
            step = np.linalg.pinv(H + delta * np.eye(d * K)) @ g
            candidate = X - step.reshape(d, K)
            f_new = cost(candidate)
            if f_new < f:
                break
            delta *= 10
            if delta > 1e20:
                break
        if delta > 1e20:
            break
        X, improvement, f = candidate, f - f_new, f_new
        delta = max(delta / 100, 1e-20)
        if improvement < tolerance:
            break
    Ss = _spaces(X, B, Rs, Wc)[2]
    C = B @ X
    shapes = np.einsum("tk,kan->tan", C, np.stack(Ss)).reshape(3 * T, n)
    return CSF2Result(shapes, Rs, C, math.sqrt(2 * f), iterations)


def error_3d(shapes: np.ndarray, truth: np.ndarray, cameras_estimated: Optional[np.ndarray] = None) -> float:
    """The benchmark's 3-D error of reconstructed ``shapes`` against the
    ``truth`` (both 3T × n): each frame centred, one global least-squares
    rotation (reflections allowed, no scale) of the reconstruction onto the
    truth, then the mean point-to-point distance divided by the mean over the
    3T rows of the truth's (centred) standard deviation. With
    ``cameras_estimated`` (2T × 3), each frame is first turned into its
    camera's frame (for sequences whose truth is in the camera frame)."""
    shapes, truth = np.asarray(shapes, dtype=np.float64), np.asarray(truth, dtype=np.float64)
    if shapes.shape != truth.shape or shapes.ndim != 2 or shapes.shape[0] % 3:
        raise ValueError(f"shapes: expected the truth's shape (3T, n) = {truth.shape}, got {shapes.shape}")
    if not (np.isfinite(shapes).all() and np.isfinite(truth).all()):
        raise ValueError("shapes: expected finite values")
    T, n = shapes.shape[0] // 3, shapes.shape[1]
    S3 = shapes.reshape(T, 3, n) - shapes.reshape(T, 3, n).mean(axis=2, keepdims=True)
    S0 = truth.reshape(T, 3, n) - truth.reshape(T, 3, n).mean(axis=2, keepdims=True)
    if cameras_estimated is not None:
        Rs = np.asarray(cameras_estimated, dtype=np.float64).reshape(T, 2, 3)
        for t in range(T):
            r1, r2 = Rs[t]
            R3 = np.vstack([r1, r2, np.cross(r1, r2) / np.linalg.norm(r1)])
            if np.linalg.det(R3) < 0:
                R3[2] *= -1
            S3[t] = R3 @ S3[t]
    a = np.concatenate(list(S0), axis=1)  # 3 × Tn
    b = np.concatenate(list(S3), axis=1)
    Y = a @ np.linalg.pinv(b)
    u, _, vt = np.linalg.svd(Y)
    Y = u @ vt
    distance = np.linalg.norm(S0 - np.einsum("ab,tbn->tan", Y, S3), axis=1).mean()
    sigma = S0.reshape(3 * T, n).std(axis=1).mean()
    return float(distance / sigma)


def kernel_basis(points: np.ndarray, d: int) -> np.ndarray:
    """A d-function coefficient basis (T × d) from points (T × q) in a shape
    space: the Gaussian kernel K_ts = exp(−|p_t − p_s|² / 2σ²) and its leading
    eigenvectors, B = K V_d E_d^(−1/2) (kernel PCA, uncentred, as the authors'
    code builds it). σ² is the mean distance to the k-th nearest frame, with
    k found by bisection so that d eigenvalues hold 99 % of the spectrum."""
    points = np.asarray(points, dtype=np.float64)
    T = len(points)
    squared = ((points[:, None, :] - points[None, :, :]) ** 2).sum(-1)
    ordered = np.sort(squared, axis=1)
    lo, hi = 1, T - 1
    sigma2 = float(ordered[:, hi].mean())
    while hi - lo > 1:
        k = (lo + hi) // 2
        sigma2 = max(float(ordered[:, k].mean()), 1e-12)
        e = np.linalg.eigvalsh(np.exp(-squared / (2 * sigma2)))[::-1]
        needed = int(np.searchsorted(np.cumsum(e) / e.sum(), 0.99) + 1)
        if needed == d:
            break
        lo, hi = (k, hi) if needed > d else (lo, k)
    kernel = np.exp(-squared / (2 * sigma2))
    e, V = np.linalg.eigh(kernel)
    e, V = e[::-1][:d], V[:, ::-1][:, :d]
    return kernel @ V / np.sqrt(np.maximum(e, 1e-12))


def ksta(W: np.ndarray, K: int, d: int, Rs: Optional[np.ndarray] = None, max_iterations: int = 300) -> CSF2Result:
    """KSTA ("Kernel non-rigid structure from motion", ICCV 2011), in our
    reading of its published description: shapes are a non-linear function of
    points in a low-dimensional shape space, through the kernel trick. The
    points are the shape coefficients of a first, linear solution (CSF2 with
    the same K and d); a Gaussian kernel on them gives the coefficient basis
    (:func:`kernel_basis`), and the CSF2 machinery is solved again with it."""
    W = _check_tracks(W)
    Rs = cameras(W) if Rs is None else Rs
    linear = csf2(W, K, d, Rs=Rs, max_iterations=max_iterations)
    scale = linear.coefficients.std(axis=0)
    points = linear.coefficients / np.where(scale > 0, scale, 1.0)
    B = kernel_basis(points, d)
    # Start where the linear solution is: its coefficients in the kernel basis.
    start = np.linalg.lstsq(B, linear.coefficients, rcond=None)[0]
    return csf2(W, K, d, Rs=Rs, max_iterations=max_iterations, basis=B, start=start)
