"""The maximum-depth heuristic of inextensible NRSfM (Chhatkuli, Pizarro,
Collins and Bartoli, TPAMI 2018): the depths of tracked points on a sheet
seen through a pinhole camera (:mod:`nrdepth.isometric` has the method).

Frames and units: pixel coordinates; depth along the optical axis, in units
of the mean template distance between neighbouring points.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from functools import partial
from typing import Optional, Tuple, Union

import numpy as np

from ..camera import Camera
from .mirror import check_anchor, keep_lengths, mirror_or_not, shape_kept

__all__ = ["neighbour_pairs", "mdh_depths", "pair_strain", "template_strain", "keyframe_indices", "solve_template", "TooFewPoints", "TEMPLATES", "EACH_FRAME"]


class TooFewPoints(ValueError):
    """:func:`mdh_depths`' tracks leave ``frames`` (their indices) with fewer
    than 3 points in view and tied to a pair."""

    def __init__(self, frames: list):
        self.frames = frames
        super().__init__(f"xy: expected at least 3 points in view and tied to a pair in every frame, got fewer in frames {frames[:5]}")


class NotSolved(RuntimeError):
    """:func:`mdh_depths`' cone program ended without an answer, with
    Clarabel's ``status`` (e.g. ``InsufficientProgress``): rays nearly
    parallel (a focal length far too long: no perspective to read), or
    tracks no inextensible sheet fits."""

    def __init__(self, status: str):
        self.status = status
        super().__init__(f"the MDH cone program was not solved: {status}")


def neighbour_pairs(xy: np.ndarray, neighbours: int = 20, far: int = 0, reach: int = 0) -> np.ndarray:
    """The pairs (E, 2), i < j, sorted, of each point (n, 2) with its
    ``neighbours`` nearest, and with ``far`` more spread evenly in rank over
    its nearest ``2 · neighbours`` to ``reach`` (0: none). Why far pairs: a
    track's error is a smaller share of a longer distance, and a pair a few
    points apart still bends little between them."""
    from scipy.spatial import cKDTree

    xy = np.asarray(xy, np.float64)
    if xy.ndim != 2 or xy.shape[1] != 2 or len(xy) < 2:
        raise ValueError(f"xy: expected points (n, 2) with n >= 2, got shape {xy.shape}")
    if not (isinstance(neighbours, (int, np.integer)) and neighbours >= 1):
        raise ValueError(f"neighbours: expected an int >= 1, got {neighbours!r}")
    if not (isinstance(far, (int, np.integer)) and far >= 0):
        raise ValueError(f"far: expected an int >= 0, got {far!r}")
    if far and not (isinstance(reach, (int, np.integer)) and reach >= 2 * neighbours):
        raise ValueError(f"reach: expected an int >= 2 · neighbours = {2 * neighbours} with far pairs, got {reach!r}")
    ranks = np.arange(1, neighbours + 1)
    if far:
        ranks = np.union1d(ranks, np.rint(np.linspace(2 * neighbours, reach, far)).astype(int))
    ranks = ranks[ranks < len(xy)]
    _, nearest = cKDTree(xy).query(xy, ranks + 1)  # k as a list: those ranks only (1 is the nearest other point)
    i = np.repeat(np.arange(len(xy)), len(ranks))
    j = nearest.ravel()
    pairs = np.unique(np.sort(np.column_stack([i, j]), axis=1), axis=0)
    return pairs[pairs[:, 0] != pairs[:, 1]]


def _active(seen: np.ndarray, pairs: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """Each frame's pairs (M, E) with both points in view, and the points
    in view (M, n) that keep at least one of them: a point tied to nothing
    would have no bound on its depth."""
    active = seen[:, pairs[:, 0]] & seen[:, pairs[:, 1]]
    tied = np.zeros_like(seen)
    t, e = np.nonzero(active)
    tied[t, pairs[e, 0]] = tied[t, pairs[e, 1]] = True
    return active, seen & tied


def _socp(rays: np.ndarray, pairs: np.ndarray, distances: Optional[np.ndarray],
          seen: Optional[np.ndarray] = None) -> Tuple[np.ndarray, np.ndarray]:
    """Depths (M, n) maximising their sum under the cones of the pairs in
    view (``seen`` (M, n), default every point; NaN where not), and the
    template distances (E,): variables (their sum the number of pairs)
    unless given."""
    import clarabel
    from scipy import sparse

    M, n, _ = rays.shape
    E = len(pairs)
    active, seen = _active(np.ones((M, n), bool) if seen is None else seen, pairs)
    variable = np.full((M, n), -1)
    variable[seen] = np.arange(np.count_nonzero(seen))  # a depth variable for each point in view
    depths = int(np.count_nonzero(seen))
    free = distances is None
    variables = depths + (E if free else 0)
    t, e = np.nonzero(active)
    cones = len(t)
    i, j = pairs[e, 0], pairs[e, 1]
    offset = depths + (1 if free else 0)
    first = offset + 4 * np.arange(cones)  # each cone's first row: its norm bound
    b = np.zeros(offset + 4 * cones)
    rows, columns, values = [np.arange(depths)], [np.arange(depths)], [-np.ones(depths)]  # depths >= 0
    if free:
        rows += [np.full(E, depths), first]  # Σ D <= E, and each cone's bound is its pair's D
        columns += [depths + np.arange(E), depths + e]
        values += [np.ones(E), -np.ones(cones)]
        b[depths] = E
    else:
        b[first] = distances[e]
    for axis in range(3):  # the cone's vector: Z_i r_i − Z_j r_j
        rows += [first + 1 + axis, first + 1 + axis]
        columns += [variable[t, i], variable[t, j]]
        values += [-rays[t, i, axis], rays[t, j, axis]]
    A = sparse.csc_matrix((np.concatenate(values), (np.concatenate(rows), np.concatenate(columns))), shape=(len(b), variables))
    q = np.zeros(variables)
    q[:depths] = -1.0
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    solution = clarabel.DefaultSolver(sparse.csc_matrix((variables, variables)), q, A, b,
                                      [clarabel.NonnegativeConeT(offset)] + [clarabel.SecondOrderConeT(4)] * cones, settings).solve()
    if str(solution.status) not in ("Solved", "AlmostSolved"):
        raise NotSolved(str(solution.status))
    x = np.asarray(solution.x)
    out = np.full((M, n), np.nan)
    out[seen] = x[:depths]
    return out, (x[depths:] if free else distances)


def _refine(rays: np.ndarray, pairs: np.ndarray, depths: np.ndarray, distances: np.ndarray,
            evaluations: int, anchor: float = 0.0) -> Tuple[np.ndarray, np.ndarray]:
    """Depths (M, n) and template distances (E,), from ``depths`` (NaN:
    not in view) and ``distances``, that make each pair's distance
    ``‖Z_i r_i − Z_j r_j‖`` equal to its ``D_ij`` in every frame where
    both are in view: least squares of the strains
    ``‖Z_i r_i − Z_j r_j‖ / D_ij − 1`` (relative, so that shrinking the
    sheet towards the camera gains nothing), depths and distances kept
    positive, ``Σ D = E`` kept by one more residual; trust-region
    reflective Gauss–Newton with the sparse exact Jacobian, at most
    ``evaluations`` evaluations (it stops where it got to). ``anchor`` > 0:
    each depth also pulled towards its start by one more residual,
    ``√anchor · (Z − Z⁰) / mean(Z⁰)`` (as
    :func:`~nrdepth.isometric.mirror.keep_lengths`' frame by frame), so
    that the answer stays in the basin of the cone program's taut start
    (deeper minima lie elsewhere: docs/campaign.md, "What comes next")."""
    from scipy import sparse
    from scipy.optimize import least_squares
    from threadpoolctl import threadpool_limits

    M, n, _ = rays.shape
    E = len(pairs)
    seen = np.isfinite(depths)
    variable = np.full((M, n), -1)
    N = int(np.count_nonzero(seen))
    variable[seen] = np.arange(N)
    t, e = np.nonzero(seen[:, pairs[:, 0]] & seen[:, pairs[:, 1]])
    K = len(t)
    i, j = pairs[e, 0], pairs[e, 1]
    ray_i, ray_j = rays[t, i], rays[t, j]
    depth_i, depth_j = variable[t, i], variable[t, j]
    weight = np.sqrt(K)  # the scale's residual weighs as much as all strains

    def chords(x: np.ndarray) -> np.ndarray:
        return x[depth_i, None] * ray_i - x[depth_j, None] * ray_j

    taut = depths[seen]  # Z⁰: where the refinement starts
    pull = np.sqrt(anchor) / np.mean(taut) if anchor else 0.0

    def residuals(x: np.ndarray) -> np.ndarray:
        out = np.append(np.linalg.norm(chords(x), axis=1) / x[N + e] - 1, (x[N:].sum() / E - 1) * weight)
        return np.concatenate([out, pull * (x[:N] - taut)]) if anchor else out

    rows = np.arange(K)

    def jacobian(x: np.ndarray) -> sparse.csr_matrix:
        chord = chords(x)
        length = np.linalg.norm(chord, axis=1)
        unit = chord / length[:, None]
        distance = x[N + e]
        values = [np.einsum("ka,ka->k", unit, ray_i) / distance, -np.einsum("ka,ka->k", unit, ray_j) / distance,
                  -length / distance**2, np.full(E, weight / E)]
        at_rows, at_columns = [rows, rows, rows, np.full(E, K)], [depth_i, depth_j, N + e, N + np.arange(E)]
        if anchor:
            values, at_rows, at_columns = values + [np.full(N, pull)], at_rows + [K + 1 + np.arange(N)], at_columns + [np.arange(N)]
        return sparse.csr_matrix((np.concatenate(values), (np.concatenate(at_rows), np.concatenate(at_columns))),
                                 shape=(K + 1 + (N if anchor else 0), N + E))

    start = np.maximum(np.append(taut, distances), 0.0)  # the cone program's answer may sit a rounding below a bound
    # One BLAS thread: a threaded BLAS sums the solver's long dot products in an order that depends on its
    # thread count, and a hundred Gauss–Newton steps carry that rounding into the answer's fourth digit.
    with threadpool_limits(limits=1, user_api="blas"):
        x = least_squares(residuals, start, jac=jacobian, bounds=(0, np.inf), method="trf",
                          tr_solver="lsmr", x_scale="jac", max_nfev=evaluations).x
    out = np.full((M, n), np.nan)
    out[seen] = x[:N]
    return out, x[N:]


TEMPLATES = ("joint", "refined", "first")
"""Where :func:`mdh_depths` takes the template distances from, when it is not given them."""

EACH_FRAME = ("program", "lengths", "mirror")
"""What :func:`mdh_depths` makes of each solved frame's depths."""


def _check_template(template: str) -> None:
    if template not in TEMPLATES:
        raise ValueError(f"template: expected one of {TEMPLATES} or the pairs' distances, got {template!r}")


def mdh_depths(xy: np.ndarray, camera: Union[Camera, float, Tuple[float, float]], centre: Optional[Tuple[float, float]] = None, pairs: Optional[np.ndarray] = None, neighbours: int = 20,
               keyframes: int = 24, far: int = 0, reach: int = 0, template="joint", evaluations: int = 100, every: int = 1,
               each_frame: str = "program", anchor: float = 0.0, with_distances: bool = False) -> Union[np.ndarray, Tuple[np.ndarray, np.ndarray]]:
    """Depths (T, n) of tracked points ``xy`` (T, n, 2) by the maximum-depth
    heuristic (module docstring); NaN where ``xy`` is NaN, a point out of
    view in that frame (:func:`track_points`), whose pairs bind nothing
    there, and where a point is paired with none in view. ``camera``: a
    :class:`~nrdepth.Camera` with its principal point, or its focal length
    in pixels (one number or (f_x, f_y)) with ``centre``, the principal
    point (c_x, c_y);
    ``pairs`` (E, 2): the neighbours tied by inextensibility (default:
    :func:`neighbour_pairs` of the first frame with ``neighbours``, ``far``
    and ``reach``). ``template``: where the pairs' template distances come
    from. "joint": ``keyframes`` frames spread evenly over the video, solved
    together, every other frame then solved with them fixed. "refined": the
    same, with the keyframes' depths and the distances refined in between
    so that each pair's distance equals its template distance in every
    keyframe (least squares, at most ``evaluations`` evaluations; module
    docstring): for tracks that do not drift. "first": the
    first frame taken as a flat sheet facing the camera (the distances
    between its points' rays at depth 1), every frame solved alone with
    them: for a video that starts with the sheet flat and nearly
    fronto-parallel (docs/reconstruction.md). Or the distances themselves,
    (E,) positive, one for each of ``pairs`` (given), as a template of
    the sheet gives them (shape from template): the depths come out in
    their units. ``every``: only every ``every``-th frame (and the last) is
    solved; each point's depth in the frames between is linear in time
    between the two solved around it (a sheet's large-scale shape changes
    little in a few frames). ``each_frame``: what each solved frame's
    depths are: "program", the maximum-depth program's with the distances
    fixed; "lengths", those refined so that each pair keeps its template
    distance (:func:`~nrdepth.isometric.keep_lengths`) in every solved
    frame, or, where one refined frame does not keep its shape
    (:func:`~nrdepth.isometric.shape_kept`), the program's in every frame
    (the relief's depth stays of one kind over the video); "mirror", refined from the
    program's answer and from its mirror, whichever keeps
    the lengths better (:func:`~nrdepth.isometric.mirror_or_not`: the
    program bends every sheet away from the camera). ``anchor``: with
    "lengths", each refined depth also pulled towards the program's
    (:func:`~nrdepth.isometric.keep_lengths`' ``anchor``; 0: free).
    ``with_distances``: also return the pairs' template distances (E,)
    used, in the depths' units."""
    camera = camera if isinstance(camera, Camera) else Camera(camera, centre)
    if camera.centre is None:
        raise ValueError("centre: expected the principal point (c_x, c_y) in pixels, got None")
    xy = np.asarray(xy, np.float64)
    if xy.ndim != 3 or xy.shape[2] != 2 or xy.shape[0] < 2 or xy.shape[1] < 3 or not np.isfinite(xy[0]).all() or np.isinf(xy).any():
        raise ValueError(f"xy: expected tracks (T, n, 2) with T >= 2 and n >= 3, finite in the first frame (NaN: out of view), got shape {xy.shape}")
    if not (isinstance(keyframes, (int, np.integer)) and keyframes >= 2):
        raise ValueError(f"keyframes: expected an int >= 2, got {keyframes!r}")
    if not (isinstance(every, (int, np.integer)) and every >= 1):
        raise ValueError(f"every: expected an int >= 1 (1: every frame solved), got {every!r}")
    if not (isinstance(evaluations, (int, np.integer)) and evaluations >= 1):
        raise ValueError(f"evaluations: expected an int >= 1, got {evaluations!r}")
    if each_frame not in EACH_FRAME:
        raise ValueError(f"each_frame: expected one of {EACH_FRAME}, got {each_frame!r}")
    check_anchor(anchor, each_frame)
    if isinstance(template, str):
        _check_template(template)
    elif pairs is None:
        raise ValueError("pairs: expected the pairs whose template distances are given (template)")
    pairs = neighbour_pairs(xy[0], neighbours, far, reach) if pairs is None else np.asarray(pairs)
    if pairs.ndim != 2 or pairs.shape[1] != 2 or len(pairs) < 1 or pairs.min() < 0 or pairs.max() >= xy.shape[1]:
        raise ValueError(f"pairs: expected (E, 2) indices of the {xy.shape[1]} points, got shape {pairs.shape}")
    rays = camera.rays(xy)
    seen = np.isfinite(rays).all(axis=2)
    rays[~seen] = 0.0
    few = np.flatnonzero(_active(seen, pairs)[1].sum(axis=1) < 3)
    if len(few):
        raise TooFewPoints(few.tolist())
    T = len(xy)
    depths = np.empty(xy.shape[:2])
    if not isinstance(template, str):
        keys = np.zeros(0, int)
        distances = np.asarray(template, np.float64)
        if distances.shape != (len(pairs),) or not np.all(np.isfinite(distances) & (distances > 0)):
            raise ValueError(f"template: expected one of {TEMPLATES} or the {len(pairs)} pairs' distances, positive, got shape {distances.shape}")
    elif template in ("joint", "refined"):
        keys = keyframe_indices(T, keyframes)
        depths[keys], distances = solve_template(rays[keys], pairs, seen[keys], refined=template == "refined", evaluations=evaluations)
    else:
        keys = np.zeros(0, int)
        distances = np.linalg.norm(rays[0, pairs[:, 0]] - rays[0, pairs[:, 1]], axis=1)
        if not np.all(distances > 0):
            raise ValueError("xy: two paired points share a position in the first frame")
        distances *= len(pairs) / distances.sum()  # the joint program's units: Σ D = the number of pairs
    anchors = solved_frames(T, keys, every)
    rest = np.setdiff1d(anchors, keys)
    # With the distances fixed the frames are independent: one small program each (ten times faster than
    # several frames in one), in threads (Clarabel releases the GIL; each frame's answer is the same in any thread).
    pool = ThreadPoolExecutor(max_workers=max(1, min(len(rest), os.cpu_count() or 1)))
    try:
        for t, solved in zip(rest, pool.map(lambda t: _socp(rays[t : t + 1], pairs, distances, seen[t : t + 1])[0][0], rest)):
            depths[t] = solved
    finally:
        pool.shutdown(cancel_futures=True)  # on Ctrl-C: the frames not yet started are dropped, not waited for
    if each_frame != "program":  # the solved frames are NaN out of view already
        refine = partial(keep_lengths, anchor=anchor) if each_frame == "lengths" else mirror_or_not
        from threadpoolctl import threadpool_limits

        # One BLAS thread around the whole pool: threadpoolctl's limits are the process's, not a thread's.
        with threadpool_limits(limits=1, user_api="blas"):
            pool = ThreadPoolExecutor(max_workers=max(1, min(len(anchors), os.cpu_count() or 1)))
            fitted = []
            try:
                for t, refined in zip(anchors, pool.map(lambda t: refine(rays[t], pairs, depths[t], distances)[0], anchors)):
                    # Where a frame barely bends, keeping its lengths can bend it anew; one such frame falling back alone
                    # beside refined ones, bent more deeply, makes the relief's depth jump from frame to frame
                    # (docs/findings.md): so every solved frame is refined, or none, and the first that turns stops the rest.
                    if each_frame == "lengths" and not shape_kept(rays[t], depths[t], refined):
                        fitted = []
                        break
                    fitted.append(refined)
            finally:
                pool.shutdown(cancel_futures=True)
        if fitted:
            depths[anchors] = np.stack(fitted)
    if len(anchors) < T:
        _between(depths, anchors, seen)
    return (depths, distances) if with_distances else depths


def solve_template(rays: np.ndarray, pairs: np.ndarray, seen: Optional[np.ndarray] = None, refined: bool = False,
                   evaluations: int = 100, anchor: float = 0.0) -> Tuple[np.ndarray, np.ndarray]:
    """The depths (M, n) of frames solved together, their points' ``rays``
    (M, n, 3) (``seen`` (M, n): in view, default all; NaN where not), and
    the template distances (E,) of ``pairs`` (E, 2) that the joint cone
    program gives them; ``refined``: then each pair held to its distance
    in every frame (least squares, at most ``evaluations`` evaluations;
    ``anchor``: each depth also pulled towards the program's, :func:`_refine`'s):
    :func:`mdh_depths`' keyframes, ``template`` "joint" or "refined"."""
    check_anchor(anchor)
    depths, distances = _socp(rays, pairs, None, seen)
    return _refine(rays, pairs, depths, distances, evaluations, anchor) if refined else (depths, distances)


def pair_strain(xy: np.ndarray, depths: np.ndarray, camera: Camera, pairs: np.ndarray, distances: np.ndarray) -> float:
    """How far ``pairs`` (E, 2) stray from their template ``distances``
    (E,) in the frames of ``xy`` (M, n, 2) with ``depths`` (M, n) (NaN:
    out of view): the root mean square over the pairs in view of
    ``‖Z_i r_i − Z_j r_j‖ / D_ij − 1`` through ``camera``. 0: every pair
    at its length. In the keyframes ``template="refined"`` fitted, what
    is left is what the tracks' errors and the sheet's own stretch leave:
    a cloth more than a print (docs/campaign.md)."""
    xy, depths, pairs, distances = np.asarray(xy, np.float64), np.asarray(depths, np.float64), np.asarray(pairs), np.asarray(distances, np.float64)
    if xy.ndim != 3 or xy.shape[2] != 2 or depths.shape != xy.shape[:2]:
        raise ValueError(f"xy, depths: expected tracks (M, n, 2) and their depths (M, n), got shapes {xy.shape} and {depths.shape}")
    if pairs.ndim != 2 or pairs.shape[1] != 2 or distances.shape != (len(pairs),):
        raise ValueError(f"pairs, distances: expected (E, 2) pairs and their (E,) distances, got shapes {pairs.shape} and {distances.shape}")
    points = camera.rays(xy) * depths[..., None]
    strains = np.linalg.norm(points[:, pairs[:, 0]] - points[:, pairs[:, 1]], axis=2) / distances - 1
    strains = strains[np.isfinite(strains)]
    if not strains.size:
        raise ValueError("xy: expected a pair with both points in view in some frame")
    return float(np.sqrt(np.mean(strains**2)))


def template_strain(xy: np.ndarray, depths: np.ndarray, camera: Camera, distances: np.ndarray, keyframes: int, neighbours: int = 20,
                    far: int = 0, reach: int = 0) -> float:
    """:func:`pair_strain` in the ``keyframes`` frames :func:`mdh_depths`
    read its template from, of its default pairs (``neighbours``, ``far``,
    ``reach``): ``xy`` (T, n, 2) and ``depths`` (T, n) and ``distances``
    (E,) as ``mdh_depths(..., with_distances=True)`` gave them. After
    ``template="refined"``, what the tracks' errors and the sheet's own
    stretch leave."""
    keys = keyframe_indices(len(xy), keyframes)
    return pair_strain(np.asarray(xy)[keys], np.asarray(depths)[keys], camera, neighbour_pairs(np.asarray(xy)[0], neighbours, far, reach), distances)


def keyframe_indices(T: int, keyframes: int) -> np.ndarray:
    """The ``keyframes`` frames of ``T`` that :func:`mdh_depths`' joint program solves together, spread evenly, first and last among them."""
    return np.unique(np.rint(np.linspace(0, T - 1, min(keyframes, T))).astype(int))


def solved_frames(T: int, keys: np.ndarray, every: int) -> np.ndarray:
    """The frames of ``T`` whose depths :func:`mdh_depths` solves: the keyframes ``keys``, every ``every``-th frame and the last."""
    return np.union1d(np.union1d(keys, np.arange(0, T, every)), [T - 1])


def _between(depths: np.ndarray, anchors: np.ndarray, seen: np.ndarray) -> None:
    """Fills in place the frames of ``depths`` (T, n) between the solved
    ``anchors``: each point's depth linear in time between the two solved
    frames around (the nearer one's where it is in view in only one; NaN
    where ``seen`` (T, n) says it is out of view)."""
    T = len(depths)
    after = np.searchsorted(anchors, np.arange(T))
    for t in np.setdiff1d(np.arange(T), anchors):
        a, b = anchors[after[t] - 1], anchors[after[t]]
        w = (t - a) / (b - a)
        left, right = depths[a], depths[b]
        near = left if w <= 0.5 else right
        blend = (1 - w) * left + w * right
        both = np.isfinite(left) & np.isfinite(right)
        row = np.where(both, blend, np.where(np.isfinite(near), near, np.where(np.isfinite(left), left, right)))
        depths[t] = np.where(seen[t], row, np.nan)
