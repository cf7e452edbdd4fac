"""The large-scale shape of an inextensible sheet (paper, cloth) from its
video, and its fusion with the network's depth.

A network reads a frame's relief but little of its large-scale bend
(docs/campaign.md); a sheet that bends without stretching gives that bend
away through perspective. Three steps:

- :func:`track_grid`: points spread evenly over ``mask`` in the first frame,
  moved (:func:`track_points`) from each frame to the next by OpenCV's Farneback dense optical flow
  (sampled bilinearly at each point), forward and backward. No point is lost to a fast or
  blurred frame: the flow of its neighbourhood carries it, where a sparse
  tracker would lose it; one that leaves the frame is lost from there on
  (NaN). The share ``drop`` of the points whose two flows disagree most
  over the video is left out: points where the motion breaks (near a
  border), which the flow drags.
- :func:`mdh_depths`: the depth of every point in every frame by the
  maximum-depth heuristic of inextensible NRSfM (Chhatkuli, Pizarro,
  Collins and Bartoli, TPAMI 2018): maximise the sum of the depths subject
  to ``‖Z_i r_i − Z_j r_j‖ ≤ D_ij`` in every frame for each pair of
  neighbours in view (``r``: the point's ray, ``(x − c_x)/f_x, (y − c_y)/f_y, 1``),
  with the pairs' template distances ``D_ij`` shared by all frames and
  ``Σ D_ij`` fixed to the number of pairs (the video fixes no scale). The
  sheet is pulled as far from the camera as its inextensible threads allow,
  which makes them taut: the true shape when the video shows it bent in
  enough ways (a short or barely bending clip leaves the distances loose
  and reads as a taut dome). A second-order cone program, solved by Clarabel over
  ``keyframes`` frames spread over the video; every other frame is then
  solved alone with those ``D_ij`` fixed, in parallel threads. The program
  only bounds each pair's distance, and with the ``D_ij`` free it favours a
  dome: it lengthens the pairs in the middle of the sheet and shortens those
  at its edge. ``template="refined"`` then asks each pair's distance to
  equal ``D_ij`` in every keyframe (isometry as an equality): a
  least-squares refinement of the keyframes' depths and the ``D_ij``,
  started from the program's answer (docs/reconstruction.md).
- :func:`isometric_depth` runs both and spreads the depths over each frame
  (linear over the points' Delaunay triangles, nearest outside their hull);
  :func:`fuse` keeps the network's relief and takes the shape above a
  length scale from the isometric depth.

Frames and units: pixel coordinates (column x, row y, pixel centres at
integers); depth is distance along the optical axis, growing away from the
camera, in units of the mean template distance between neighbouring points
(the scale is free: a video fixes none). Needs a perspective camera of known
intrinsics, and the optional dependencies: ``pip install 'nrdepth[isometric]'``.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from typing import Optional, Tuple

import numpy as np

__all__ = ["track_grid", "track_points", "least_disagreeing", "neighbour_pairs", "mdh_depths", "isometric_depth", "fuse"]

DROP = 0.2
""":func:`isometric_depth`'s and ``reconstruct(focal=...)``'s share of the
tracked points left out: those whose forward and backward flows disagree
most (:func:`track_grid`'s ``drop``). At every fusion scale the paper
and the cloth per frame gain, and the long generated sheets decided it
by a rule fixed beforehand (docs/campaign.md)."""


BORDER = 0.0
""":func:`track_points`' and :func:`track_grid`'s margin in pixels: a
point closer than this to the frame's edge, or beyond it, is lost for
good. 0: a point is lost where it leaves the frame (8 lost more points
and read generated sheets worse: docs/reconstruction.md)."""


def _cv2():
    """OpenCV, after checking that both optional dependencies are there."""
    try:
        import clarabel  # noqa: F401
        import cv2
    except ImportError as error:  # optional dependencies: say how to get them
        raise ImportError("nrdepth.isometric needs OpenCV and Clarabel: pip install 'nrdepth[isometric]'") from error
    return cv2


def _check_video(video: np.ndarray) -> np.ndarray:
    video = np.asarray(video)
    if video.ndim != 3 or video.dtype != np.uint8 or video.shape[0] < 2 or min(video.shape[1:]) < 8:
        raise ValueError(f"video: expected a (T, H, W) uint8 grayscale video with T >= 2 and frames of at least 8×8, "
                         f"got {video.dtype} {video.shape}")
    return video


def _check_mask(mask: Optional[np.ndarray], shape: Tuple[int, int]) -> np.ndarray:
    if mask is None:
        return np.ones(shape, bool)
    mask = np.asarray(mask)
    if mask.dtype != np.bool_ or mask.shape != shape:
        raise ValueError(f"mask: expected a bool array of a frame's shape {shape}, got {mask.dtype} {mask.shape}")
    return mask


def track_grid(video: np.ndarray, mask: Optional[np.ndarray] = None, points: int = 400, window: int = 21,
               backward: bool = True, drop: float = 0.0, border: float = BORDER) -> np.ndarray:
    """Tracks (T, n, 2) (column, row) of about ``points`` points on a square
    grid over ``mask`` (H, W) of the first frame (default: the whole frame)
    at least ``border`` pixels inside the frame's edge, moved through
    ``video`` (T, H, W) uint8 by :func:`track_points` (``window``,
    ``backward``, ``border``: NaN from the frame where a point leaves the
    view). ``drop``: the share of the points left out,
    those whose forward and backward flows disagree most over the video
    (:func:`track_points`' ``disagreement``; needs ``backward``): points
    at a boundary of the motion, where the flow bleeds from one side to
    the other, whose tracks would read as stretch (docs/reconstruction.md)."""
    video = _check_video(video)
    mask = _check_mask(mask, video.shape[1:])
    if not (isinstance(points, (int, np.integer)) and points >= 4):
        raise ValueError(f"points: expected an int >= 4, got {points!r}")
    if not (isinstance(drop, (int, float, np.floating)) and 0 <= drop < 1):
        raise ValueError(f"drop: expected a share of the points in [0, 1), got {drop!r}")
    if drop > 0 and not backward:
        raise ValueError("drop: the points to leave out are found by the flow both ways: expected backward=True, or drop=0")
    spacing = max(1.0, float(np.sqrt(mask.sum() / points)))
    rows, cols = np.mgrid[spacing / 2 : video.shape[1] : spacing, spacing / 2 : video.shape[2] : spacing]
    grid = np.column_stack([cols.ravel(), rows.ravel()])
    grid = grid[mask[rows.astype(int).ravel(), cols.astype(int).ravel()] & _inside(grid, video.shape[1:], border)]
    kept = len(grid) - int(round(drop * len(grid)))
    if kept < 4:
        raise ValueError(f"mask: expected room for at least 4 points at {points} points over its area (drop {drop:g}), got {kept}")
    if drop == 0:
        return track_points(video, grid, window, backward, border=border)
    xy, disagreement = track_points(video, grid, window, backward, disagreement=True, border=border)
    return xy[:, least_disagreeing(disagreement, drop)]


def least_disagreeing(disagreement: np.ndarray, drop: float) -> np.ndarray:
    """Indices, ascending, of the points kept when the share ``drop`` of
    them whose ``disagreement`` (n,) (:func:`track_points`) is largest is
    left out (ties: the later point goes)."""
    kept = len(disagreement) - int(round(drop * len(disagreement)))
    return np.sort(np.argsort(disagreement, kind="stable")[:kept])


def track_points(video: np.ndarray, start: np.ndarray, window: int = 21, backward: bool = True,
                 disagreement: bool = False, border: float = BORDER):
    """Tracks (T, n, 2) (column, row) of the points ``start`` (n, 2) of the
    first frame, moved through ``video`` (T, H, W) uint8 by Farneback optical
    flow (5 pyramid levels, ``window``-pixel windows) from each frame to the
    next: the mean of where the forward flow takes a point and where the
    backward flow says it came from (both real videos read better, generated
    sheets within 0.0005 per frame: docs/reconstruction.md), or with
    ``backward`` False the forward flow alone (half the flow's cost). A
    point is lost for good (NaN) from the first frame after the start where
    it lies within ``border`` pixels of the frame's edge or beyond it: the
    flow cannot follow what leaves the view, and would hold it at the edge.
    With ``disagreement`` (needs ``backward``), also (n,): each point's
    distance between where the two flows take it, its mean over the steps
    it stays in view (pixels; 0 for a point lost at once)."""
    from scipy.ndimage import map_coordinates

    cv2 = _cv2()
    video = _check_video(video)
    start = np.asarray(start, np.float64)
    if start.ndim != 2 or start.shape[1] != 2 or not np.isfinite(start).all():
        raise ValueError(f"start: expected finite points (n, 2) (column, row), got shape {start.shape}")
    if not (isinstance(window, (int, np.integer)) and window >= 3):
        raise ValueError(f"window: expected an int >= 3 (pixels), got {window!r}")
    if not (isinstance(border, (int, float, np.integer, np.floating)) and 0 <= border < min(video.shape[1:]) / 2):
        raise ValueError(f"border: expected pixels in [0, {min(video.shape[1:]) / 2:g}) (half the frame's shorter side), got {border!r}")
    if disagreement and not backward:
        raise ValueError("disagreement: the forward and backward flows' disagreement needs backward=True")

    def flow(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        return cv2.calcOpticalFlowFarneback(a, b, None, 0.5, 5, window, 5, 7, 1.5, 0)

    def at(field: np.ndarray, where: np.ndarray) -> np.ndarray:  # bilinear
        return np.stack([map_coordinates(field[..., c], [where[:, 1], where[:, 0]], order=1, mode="nearest") for c in (0, 1)], axis=1)

    xy = np.full((len(video), len(start), 2), np.nan)
    xy[0] = start
    alive = np.arange(len(start))
    apart, steps = np.zeros(len(start)), np.zeros(len(start))
    for t in range(1, len(video)):
        if not len(alive):
            break
        was = xy[t - 1, alive]
        ahead = was + at(flow(video[t - 1], video[t]), was)
        now = ahead
        if backward:
            field, back = flow(video[t], video[t - 1]), ahead
            for _ in range(3):  # the point p whose backward flow lands on xy[t − 1]: p = xy[t − 1] − field(p)
                back = was - at(field, back)
            now = (ahead + back) / 2
        stays = _inside(now, video.shape[1:], border)
        alive, now = alive[stays], now[stays]
        xy[t, alive] = now
        if backward:
            apart[alive] += np.linalg.norm(ahead[stays] - back[stays], axis=1)
            steps[alive] += 1
    return (xy, apart / np.maximum(steps, 1)) if disagreement else xy


def _inside(xy: np.ndarray, shape: Tuple[int, int], border: float) -> np.ndarray:
    """Which points (n, 2) lie at least ``border`` pixels inside a frame of ``shape`` (H, W)."""
    return (xy[:, 0] >= border) & (xy[:, 0] <= shape[1] - 1 - border) & (xy[:, 1] >= border) & (xy[:, 1] <= shape[0] - 1 - border)


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
        raise RuntimeError(f"the MDH cone program was not solved: {solution.status}")
    x = np.asarray(solution.x)
    out = np.full((M, n), np.nan)
    out[seen] = x[:depths]
    return out, (x[depths:] if free else distances)


def _refine(rays: np.ndarray, pairs: np.ndarray, depths: np.ndarray, distances: np.ndarray,
            evaluations: int) -> Tuple[np.ndarray, np.ndarray]:
    """Depths (M, n) and template distances (E,), from ``depths`` (NaN:
    not in view) and ``distances``, that make each pair's distance
    ``‖Z_i r_i − Z_j r_j‖`` equal to its ``D_ij`` in every frame where
    both are in view: least squares of the strains
    ``‖Z_i r_i − Z_j r_j‖ / D_ij − 1`` (relative, so that shrinking the
    sheet towards the camera gains nothing), depths and distances kept
    positive, ``Σ D = E`` kept by one more residual; trust-region
    reflective Gauss–Newton with the sparse exact Jacobian, at most
    ``evaluations`` evaluations (it stops where it got to)."""
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

    def residuals(x: np.ndarray) -> np.ndarray:
        return np.append(np.linalg.norm(chords(x), axis=1) / x[N + e] - 1, (x[N:].sum() / E - 1) * weight)

    rows = np.arange(K)

    def jacobian(x: np.ndarray) -> sparse.csr_matrix:
        chord = chords(x)
        length = np.linalg.norm(chord, axis=1)
        unit = chord / length[:, None]
        distance = x[N + e]
        values = [np.einsum("ka,ka->k", unit, ray_i) / distance, -np.einsum("ka,ka->k", unit, ray_j) / distance,
                  -length / distance**2, np.full(E, weight / E)]
        return sparse.csr_matrix((np.concatenate(values), (np.concatenate([rows, rows, rows, np.full(E, K)]),
                                                           np.concatenate([depth_i, depth_j, N + e, N + np.arange(E)]))),
                                 shape=(K + 1, N + E))

    start = np.maximum(np.append(depths[seen], distances), 0.0)  # the cone program's answer may sit a rounding below a bound
    # One BLAS thread: a threaded BLAS sums the solver's long dot products in an order that depends on its
    # thread count, and a hundred Gauss–Newton steps carry that rounding into the answer's fourth digit.
    with threadpool_limits(limits=1, user_api="blas"):
        x = least_squares(residuals, start, jac=jacobian, bounds=(0, np.inf), method="trf",
                          tr_solver="lsmr", x_scale="jac", max_nfev=evaluations).x
    out = np.full((M, n), np.nan)
    out[seen] = x[:N]
    return out, x[N:]


def _camera(focal, centre) -> Tuple[Tuple[float, float], Tuple[float, float]]:
    """``focal`` (one number or (f_x, f_y), pixels, positive) and ``centre``
    ((c_x, c_y), pixels), checked: ((f_x, f_y), (c_x, c_y))."""
    try:
        f = np.broadcast_to(np.asarray(focal, np.float64), (2,)) if np.ndim(focal) == 0 else np.asarray(focal, np.float64)
        ok = f.shape == (2,) and bool(np.all(np.isfinite(f)) and np.all(f > 0))
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise ValueError(f"focal: expected the camera's focal length in pixels, one positive number or (f_x, f_y), got {focal!r}")
    try:
        c = np.asarray(centre, np.float64)
        ok = c.shape == (2,) and bool(np.all(np.isfinite(c)))
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise ValueError(f"centre: expected the principal point (c_x, c_y) in pixels, got {centre!r}")
    return (float(f[0]), float(f[1])), (float(c[0]), float(c[1]))


TEMPLATES = ("joint", "refined", "first")
"""Where :func:`mdh_depths` takes the template distances from, when it is not given them."""


def _check_template(template: str) -> None:
    if template not in TEMPLATES:
        raise ValueError(f"template: expected one of {TEMPLATES} or the pairs' distances, got {template!r}")


def _rays(xy: np.ndarray, focal, centre) -> np.ndarray:
    (fx, fy), (cx, cy) = _camera(focal, centre)
    return np.stack([(xy[..., 0] - cx) / fx, (xy[..., 1] - cy) / fy, np.ones(xy.shape[:2])], axis=-1)


def mdh_depths(xy: np.ndarray, focal, centre, pairs: Optional[np.ndarray] = None, neighbours: int = 20,
               keyframes: int = 24, far: int = 0, reach: int = 0, template="joint", evaluations: int = 100) -> np.ndarray:
    """Depths (T, n) of tracked points ``xy`` (T, n, 2) by the maximum-depth
    heuristic (module docstring); NaN where ``xy`` is NaN, a point out of
    view in that frame (:func:`track_points`), whose pairs bind nothing
    there, and where a point is paired with none in view. ``focal``: the focal length in pixels, one
    number or (f_x, f_y); ``centre``: the principal point (c_x, c_y);
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
    their units."""
    xy = np.asarray(xy, np.float64)
    if xy.ndim != 3 or xy.shape[2] != 2 or xy.shape[0] < 2 or xy.shape[1] < 3 or not np.isfinite(xy[0]).all() or np.isinf(xy).any():
        raise ValueError(f"xy: expected tracks (T, n, 2) with T >= 2 and n >= 3, finite in the first frame (NaN: out of view), got shape {xy.shape}")
    if not (isinstance(keyframes, (int, np.integer)) and keyframes >= 2):
        raise ValueError(f"keyframes: expected an int >= 2, got {keyframes!r}")
    if not (isinstance(evaluations, (int, np.integer)) and evaluations >= 1):
        raise ValueError(f"evaluations: expected an int >= 1, got {evaluations!r}")
    if isinstance(template, str):
        _check_template(template)
    elif pairs is None:
        raise ValueError("pairs: expected the pairs whose template distances are given (template)")
    pairs = neighbour_pairs(xy[0], neighbours, far, reach) if pairs is None else np.asarray(pairs)
    if pairs.ndim != 2 or pairs.shape[1] != 2 or len(pairs) < 1 or pairs.min() < 0 or pairs.max() >= xy.shape[1]:
        raise ValueError(f"pairs: expected (E, 2) indices of the {xy.shape[1]} points, got shape {pairs.shape}")
    rays = _rays(xy, focal, centre)
    seen = np.isfinite(rays).all(axis=2)
    rays[~seen] = 0.0
    few = np.flatnonzero(_active(seen, pairs)[1].sum(axis=1) < 3)
    if len(few):
        raise ValueError(f"xy: expected at least 3 points in view and tied to a pair in every frame, got fewer in frames {few[:5].tolist()}")
    T = len(xy)
    depths = np.empty(xy.shape[:2])
    if not isinstance(template, str):
        keys = np.zeros(0, int)
        distances = np.asarray(template, np.float64)
        if distances.shape != (len(pairs),) or not np.all(np.isfinite(distances) & (distances > 0)):
            raise ValueError(f"template: expected one of {TEMPLATES} or the {len(pairs)} pairs' distances, positive, got shape {distances.shape}")
    elif template in ("joint", "refined"):
        keys = np.unique(np.rint(np.linspace(0, T - 1, min(keyframes, T))).astype(int))
        depths[keys], distances = _socp(rays[keys], pairs, None, seen[keys])
        if template == "refined":
            depths[keys], distances = _refine(rays[keys], pairs, depths[keys], distances, evaluations)
    else:
        keys = np.zeros(0, int)
        distances = np.linalg.norm(rays[0, pairs[:, 0]] - rays[0, pairs[:, 1]], axis=1)
        if not np.all(distances > 0):
            raise ValueError("xy: two paired points share a position in the first frame")
        distances *= len(pairs) / distances.sum()  # the joint program's units: Σ D = the number of pairs
    rest = np.setdiff1d(np.arange(T), keys)
    # With the distances fixed the frames are independent: one small program each (ten times faster than
    # several frames in one), in threads (Clarabel releases the GIL; each frame's answer is the same in any thread).
    with ThreadPoolExecutor(max_workers=max(1, min(len(rest), os.cpu_count() or 1))) as pool:
        for t, solved in zip(rest, pool.map(lambda t: _socp(rays[t : t + 1], pairs, distances, seen[t : t + 1])[0][0], rest)):
            depths[t] = solved
    return depths


def isometric_depth(video: np.ndarray, focal, centre=None, mask: Optional[np.ndarray] = None, points: int = 400,
                    neighbours: int = 20, keyframes: int = 24, far: int = 0, reach: int = 0, window: int = 21,
                    backward: bool = True, template: str = "joint", drop: float = DROP) -> np.ndarray:
    """Dense depth (T, H, W) float64 of an inextensible sheet filmed by
    ``video`` (T, H, W) uint8 through a perspective camera of focal length
    ``focal`` pixels (one number or (f_x, f_y)) and principal point
    ``centre`` (default: the frame's centre): :func:`track_grid` over
    ``mask`` (the sheet in the first frame; default: the whole frame;
    ``points``, ``window``, ``backward``, ``drop``: :data:`DROP`), :func:`mdh_depths` (``neighbours``,
    ``keyframes``, ``far``, ``reach``, ``template``), then linear over the points' Delaunay triangles,
    nearest outside their hull. Units: the mean distance between
    neighbouring points is about 1."""
    from .tracks import densify

    video = _check_video(video)
    if centre is None:
        centre = ((video.shape[2] - 1) / 2, (video.shape[1] - 1) / 2)
    _camera(focal, centre)  # before tracking
    if not isinstance(template, str):  # given distances need the pairs, which are drawn after tracking
        raise ValueError(f"template: expected one of {TEMPLATES} (given distances go to mdh_depths with their pairs), got {type(template).__name__}")
    _check_template(template)
    xy = track_grid(video, mask, points, window, backward, drop)
    depths = mdh_depths(xy, focal, centre, neighbours=neighbours, keyframes=keyframes, far=far, reach=reach, template=template)
    return densify(xy, depths, video.shape)


def fuse(depth: np.ndarray, isometric: np.ndarray, scale: float, mask: Optional[np.ndarray] = None,
         relief: str = "frame") -> np.ndarray:
    """The network's ``depth`` (T, H, W) with its shape above ``scale``
    (the standard deviation of a Gaussian, in pixels) taken from
    ``isometric`` (T, H, W, :func:`isometric_depth`): ``depth`` is fitted to
    ``isometric`` over ``mask`` (T, H, W, default every pixel) by
    ``λ d + α x + β y + τ``, a plane per frame, and their difference,
    smoothed by the Gaussian over ``mask``, is added. ``relief``: "frame"
    fits each frame's own λ (a GBR per frame); "video" takes one λ for the
    whole video (the median of the frames' own), so the relief keeps the
    network's scale from frame to frame and the sign the isometric depth
    has in most frames (better on both real videos, worse on short generated
    clips: docs/findings.md). In ``isometric``'s units; ``scale`` 0 gives
    ``isometric`` back."""
    from .metrics import _design, gbr_fit

    depth, isometric = np.asarray(depth, np.float64), np.asarray(isometric, np.float64)
    if depth.ndim != 3 or depth.shape != isometric.shape:
        raise ValueError(f"depth, isometric: expected two depth videos (T, H, W) of one shape, got {depth.shape} and {isometric.shape}")
    if not (np.isfinite(scale) and scale >= 0):
        raise ValueError(f"scale: expected a length in pixels >= 0, got {scale!r}")
    if relief not in ("video", "frame"):
        raise ValueError(f"relief: expected 'video' or 'frame', got {relief!r}")
    mask = np.ones(depth.shape, bool) if mask is None else np.asarray(mask)
    if mask.dtype != np.bool_ or mask.shape != depth.shape:
        raise ValueError(f"mask: expected a bool array of the videos' shape {depth.shape}, got {mask.dtype} {mask.shape}")
    if not (np.isfinite(depth[mask]).all() and np.isfinite(isometric[mask]).all()):
        raise ValueError("depth, isometric: expected finite values inside mask (found NaN or inf)")
    if scale == 0:
        return isometric.copy()
    fits = [gbr_fit(d, i, m) for d, i, m in zip(depth, isometric, mask)]  # each frame's (α, β, λ, τ)
    if relief == "video":
        shared = float(np.median([fit[2] for fit in fits]))
        fits = []
        for d, i, m in zip(depth, isometric, mask):
            plane = _design(np.zeros_like(d), m)[:, [0, 1, 3]]
            fits.append(np.insert(np.linalg.lstsq(plane, i[m] - shared * d[m], rcond=None)[0], 2, shared))
    out = np.empty_like(depth)
    for t, (d, i, m, fit) in enumerate(zip(depth, isometric, mask, fits)):
        aligned = (_design(d, None) @ fit).reshape(d.shape)
        weight = _blur(m.astype(np.float64), scale)
        difference = _blur(np.where(m, i - aligned, 0.0), scale)
        out[t] = aligned + difference / np.maximum(weight, 1e-6)  # normalised: the mask's outside takes no part
    return out


def _blur(image: np.ndarray, sigma: float) -> np.ndarray:
    """A Gaussian blur of standard deviation ``sigma`` pixels with zeros
    outside the image, by FFT over the image padded by 4σ (at most its own
    size): the cost does not grow with σ."""
    from scipy import fft
    from scipy.ndimage import fourier_gaussian

    h, w = image.shape
    pad_h, pad_w = (min(int(np.ceil(4 * sigma)), n) for n in (h, w))
    padded = np.zeros((fft.next_fast_len(h + 2 * pad_h, real=True), fft.next_fast_len(w + 2 * pad_w, real=True)))
    padded[pad_h : pad_h + h, pad_w : pad_w + w] = image
    blurred = fft.irfft2(fourier_gaussian(fft.rfft2(padded), sigma, n=padded.shape[1]), s=padded.shape)
    return blurred[pad_h : pad_h + h, pad_w : pad_w + w]
