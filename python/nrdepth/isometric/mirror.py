"""Each frame's lengths kept, and its shape or its mirror. The
maximum-depth program (:mod:`~nrdepth.isometric.mdh`) only bounds each
pair's distance, and pulls a frame's sheet as far from the camera as
they allow: a taut dome, and a sheet bent towards the camera comes out
bent away from it, its mirror. :func:`keep_lengths` refines a frame so
that every pair keeps its template distance; :func:`mirror_or_not` does
so from the program's answer and from its mirror and takes the start
that keeps the lengths better; :func:`shape_kept` tells whether a
refined frame still has the program's shape. An orthographic camera cannot tell a
shape from its mirror; a pinhole can where the sheet bends enough for
its size (docs/campaign.md, "Sheets that bend as real sheets do").

Frames and units: rays scaled to z = 1 (:meth:`~nrdepth.Camera.rays`);
depths along the optical axis in the template distances' units.
"""

from __future__ import annotations

from typing import Tuple

import numpy as np

from ..checks import is_number

__all__ = ["mirror_depths", "keep_lengths", "mirror_or_not", "shape_kept", "SHAPE_KEPT"]


def _check_frame(rays: np.ndarray, depths: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    rays, depths = np.asarray(rays, np.float64), np.asarray(depths, np.float64)
    if rays.ndim != 2 or rays.shape[1] != 3 or not np.isfinite(rays).all():
        raise ValueError(f"rays: expected one frame's finite rays (n, 3), got shape {rays.shape}")
    # Not checked positive: the cone program's answer may sit a rounding below its bound at 0.
    if depths.shape != (len(rays),) or np.isinf(depths).any():
        raise ValueError(f"depths: expected ({len(rays)},) depths, one a ray (NaN: out of view), got shape {depths.shape}")
    if np.count_nonzero(np.isfinite(depths)) < 3:
        raise ValueError("depths: expected at least 3 points in view (a plane needs 3)")
    return rays, depths


def _heights(rays: np.ndarray, depths: np.ndarray) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The points in view (mask (n,)), their heights above their best plane
    ``Z = a X + b Y + c`` along the optical axis, and (a, b, c)."""
    seen = np.isfinite(depths)
    points = rays[seen] * depths[seen, None]
    plane, *_ = np.linalg.lstsq(np.column_stack([points[:, 0], points[:, 1], np.ones(len(points))]), points[:, 2], rcond=None)
    return seen, points[:, 2] - (plane[0] * points[:, 0] + plane[1] * points[:, 1] + plane[2]), plane


def mirror_depths(rays: np.ndarray, depths: np.ndarray) -> np.ndarray:
    """The depths (n,) that put each point of one frame (``rays`` (n, 3),
    ``depths`` (n,), NaN: out of view) as far on the other side of the
    points' best plane ``Z = a X + b Y + c`` as it was on this one,
    measured along the optical axis, on its own ray: the image stays, the
    bend turns over. Depths kept positive."""
    rays, depths = _check_frame(rays, depths)
    seen, height, (a, b, c) = _heights(rays, depths)
    slant = 1.0 - a * rays[seen, 0] - b * rays[seen, 1]  # > 0 unless the plane holds the ray
    out = np.full_like(depths, np.nan)
    out[seen] = np.maximum((c - height) / np.maximum(slant, 1e-6), 1e-6 * abs(c))
    return out


SHAPE_KEPT = 0.8
"""A refined frame keeps the program's shape where its points' heights
above their best plane correlate with the program's at least this much:
the least seen over 200 solved frames of 8 paper-like generated sheets
from their true tracks, where keeping the lengths paid in every band of
correlation; on the cloth's nearly flat frames whose bend it turned over
the correlation was 0.04–0.58 (docs/campaign.md, "Sheets that bend as
real sheets do, and each frame's lengths kept")."""


def shape_kept(rays: np.ndarray, depths: np.ndarray, other: np.ndarray, correlation: float = SHAPE_KEPT) -> bool:
    """Whether ``other`` (n,), a second reading of one frame (``depths``
    (n,), NaN: out of view, the same points in view), keeps its shape:
    their points' heights above their own best planes correlate at least
    ``correlation``. A frame with no relief keeps any shape."""
    rays, depths = _check_frame(rays, depths)
    if not (is_number(correlation) and -1 <= correlation <= 1):
        raise ValueError(f"correlation: expected a number in [-1, 1], got {correlation!r}")
    other = np.asarray(other, np.float64)
    if other.shape != depths.shape or not np.array_equal(np.isfinite(other), np.isfinite(depths)):
        raise ValueError(f"other: expected depths {depths.shape} in view where depths are, got shape {other.shape}")
    seen, mine = _heights(rays, depths)[:2]
    theirs = _heights(rays, other)[1]
    flat = 1e-9 * np.linalg.norm(depths[seen])  # a plane's heights are rounding
    if np.linalg.norm(mine) <= flat or np.linalg.norm(theirs) <= flat:
        return True
    return bool(np.dot(mine, theirs) >= correlation * np.linalg.norm(mine) * np.linalg.norm(theirs))  # zero-mean heights: a correlation


def check_anchor(anchor: float, each_frame: str = "lengths") -> None:
    """ValueError naming ``anchor`` unless it is a finite number ≥ 0
    (:func:`keep_lengths`), and 0 unless ``each_frame`` is "lengths", the
    one reading that uses it."""
    if not (is_number(anchor) and np.isfinite(anchor) and anchor >= 0):
        raise ValueError(f"anchor: expected a finite number >= 0, got {anchor!r}")
    if anchor and each_frame != "lengths":
        raise ValueError(f"anchor: only each_frame='lengths' pulls towards the program's depths; got anchor={anchor!r} with each_frame={each_frame!r}")


def keep_lengths(rays: np.ndarray, pairs: np.ndarray, depths: np.ndarray, distances: np.ndarray,
                 evaluations: int = 50, anchor: float = 0.0) -> Tuple[np.ndarray, float]:
    """One frame's depths (n,) refined from ``depths`` (NaN: out of view)
    so that each pair (``pairs`` (E, 2)) in view keeps its template
    distance (``distances`` (E,)): least squares of the strains
    ``‖Z_i r_i − Z_j r_j‖ / D_ij − 1``, depths kept positive, at most
    ``evaluations`` evaluations; and the strains' root mean square at the
    end (how well the frame keeps its lengths). ``anchor`` ≥ 0: each depth
    also pulled towards its start, the residual ``√anchor · (Z_i −
    Z⁰_i) / mean(Z⁰)``, so that a nearly flat frame, whose lengths many
    shapes keep, stays near its start (0: free; docs/findings.md)."""
    from scipy import sparse
    from scipy.optimize import least_squares
    from threadpoolctl import threadpool_limits

    rays, depths = _check_frame(rays, depths)
    pairs, distances = np.asarray(pairs), np.asarray(distances, np.float64)
    if pairs.ndim != 2 or pairs.shape[1] != 2 or not np.issubdtype(pairs.dtype, np.integer) or pairs.min(initial=0) < 0 or pairs.max(initial=0) >= len(rays):
        raise ValueError(f"pairs: expected (E, 2) indices of the {len(rays)} points, got {pairs.dtype} {pairs.shape}")
    if distances.shape != (len(pairs),) or not (np.isfinite(distances) & (distances > 0)).all():
        raise ValueError(f"distances: expected the {len(pairs)} pairs' template distances, positive, got shape {distances.shape}")
    if not (isinstance(evaluations, (int, np.integer)) and evaluations >= 1):
        raise ValueError(f"evaluations: expected an int >= 1, got {evaluations!r}")
    check_anchor(anchor)
    seen = np.isfinite(depths)
    active = seen[pairs[:, 0]] & seen[pairs[:, 1]]
    i, j, distance = pairs[active, 0], pairs[active, 1], distances[active]
    variable = np.full(len(depths), -1)
    variable[seen] = np.arange(np.count_nonzero(seen))
    vi, vj = variable[i], variable[j]
    ray_i, ray_j = rays[i], rays[j]
    K, N = len(i), int(np.count_nonzero(seen))
    rows = np.concatenate([np.arange(K), np.arange(K)])
    columns = np.concatenate([vi, vj])

    def chords(z: np.ndarray) -> np.ndarray:
        return z[vi, None] * ray_i - z[vj, None] * ray_j

    start = np.maximum(depths[seen], 1e-9)
    pull = np.sqrt(anchor) / start.mean()  # the anchor's residuals: each depth's change, in the frame's mean depth

    def residuals(z: np.ndarray) -> np.ndarray:
        strains = np.linalg.norm(chords(z), axis=1) / distance - 1
        return np.concatenate([strains, pull * (z - start)]) if anchor else strains

    def jacobian(z: np.ndarray) -> sparse.csr_matrix:
        chord = chords(z)
        unit = chord / np.maximum(np.linalg.norm(chord, axis=1), 1e-12)[:, None]
        values = np.concatenate([np.einsum("ka,ka->k", unit, ray_i) / distance, -np.einsum("ka,ka->k", unit, ray_j) / distance])
        strains = sparse.csr_matrix((values, (rows, columns)), shape=(K, N))
        return sparse.vstack([strains, pull * sparse.identity(N, format="csr")], format="csr") if anchor else strains

    out = np.full_like(depths, np.nan)
    if K == 0:
        return out, np.nan
    # One BLAS thread: the answer's bytes do not depend on the thread count (as in mdh._refine).
    with threadpool_limits(limits=1, user_api="blas"):
        fit = least_squares(residuals, start, jac=jacobian, bounds=(0, np.inf), method="trf",
                            tr_solver="lsmr", x_scale="jac", max_nfev=evaluations)
    out[seen] = fit.x
    return out, float(np.sqrt(np.mean(fit.fun[:K] ** 2)))


def mirror_or_not(rays: np.ndarray, pairs: np.ndarray, depths: np.ndarray, distances: np.ndarray,
                  evaluations: int = 50) -> Tuple[np.ndarray, bool]:
    """One frame's depths (n,) refined by :func:`keep_lengths` from the
    program's ``depths`` and from their mirror (:func:`mirror_depths`),
    whichever keeps the lengths better, and whether it was the mirror."""
    straight, strain = keep_lengths(rays, pairs, depths, distances, evaluations)
    mirrored, mirrored_strain = keep_lengths(rays, pairs, mirror_depths(rays, depths), distances, evaluations)
    return (mirrored, True) if mirrored_strain < strain else (straight, False)
