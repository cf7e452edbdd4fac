"""Points held to their look in the first frame, so that chained flow
cannot drift (:func:`~nrdepth.isometric.track_points`' ``hold``).

Algorithm: the flow carries every point from one frame to the next (its
prediction). A smooth warp of the sheet is fitted to the predictions: the
affine moving-least-squares deformation (Schaefer et al. 2006, Gaussian
weights of :data:`SPREAD` times the points' spacing), which maps a place
of the first frame to its place in the current one and is linear in the
predictions of the points held in the frame before (all of them at
first: a point not found again has only the flow's guess, which drifts
and, on blank paper, bends the warp), so its matrix is built again only
when they change. The current frame is pulled
back through it into the first frame's geometry; there each point's
first-frame neighbourhood is found again by pyramidal Lucas–Kanade
(OpenCV), on frames whose local mean and contrast are taken out, since a
bending sheet's shading changes as it turns. Where it is found, mapped
forward through the warp, is the point's position. A point is *held*
where Lucas–Kanade converges, comes back to where it started (within
:data:`HOLD_FB` px) and finds a window that correlates with the first
frame's (:data:`HOLD_NCC`); elsewhere it is NaN in that frame, and the
warp carries it on, so it may be held again later.

Frames and units: pixel coordinates (column x, row y, pixel centres at
integers), as :mod:`nrdepth.isometric` counts them.
"""

from __future__ import annotations

from typing import Tuple

import numpy as np

__all__ = ["Anchor", "SPREAD", "STEP", "HOLD_FB", "HOLD_NCC", "HOLD_WINDOW", "HOLD_LEVELS", "OUTLIER", "CONTRAST", "AFFINE_KEPT"]

SPREAD = 1.5
"""The warp's Gaussian weights' width in the points' spacings: wide enough
that one point's error moves the warp by a fraction of it."""

STEP = 8
"""Pixels between the nodes where the warp is evaluated, interpolated
linearly between them (a sheet's warp is smooth at this scale)."""

HOLD_FB = 0.2
"""Pixels: a point is held where Lucas–Kanade, run back from where it
found the point, lands within this of where it started. Chosen over 0.5 by
the default's rule (docs/campaign.md, "The way back of 0.2 px through the
contrast at 2"): on 32 fresh generated sheets −0.0043 ± 0.0036 per frame
against 0.5, no fresh noise video read; the held tracker's 95th percentile
on the fresh sets 1.47 px against 1.69."""

HOLD_NCC = 0.5
"""A point is held only where its window in the first frame and where it
was found correlate at least this much (zero-mean normalised): Lucas–Kanade
also comes back to where it started on a flat card hiding the point."""

HOLD_WINDOW, HOLD_LEVELS = 21, 2
"""Lucas–Kanade's window (pixels) and pyramid levels above the frame: the
window the flow uses; two levels reach a prediction about 20 px off."""

OUTLIER = 3.0
"""Pixels: a prediction this far from the warp fitted to all of them is
replaced by the warp's before the warp is fitted again (one point
dragged by the flow would bend the warp around it)."""

AFFINE_KEPT = 1e-6
"""Pixels: the warp at a node must give an affine map of its anchors back
to this (it does, to rounding, wherever its moments are well
conditioned); elsewhere the node takes a translation (:func:`_mls`)."""

CONTRAST = 5.0
"""Pixels: the Gaussian over which each frame's local mean and contrast
are taken out before matching."""


def _normalised(cv2, frame: np.ndarray) -> np.ndarray:
    """``frame`` with its local mean and contrast taken out, as uint8 around 128."""
    f = frame.astype(np.float32)
    mean = cv2.GaussianBlur(f, (0, 0), CONTRAST)
    spread = np.sqrt(cv2.GaussianBlur((f - mean) ** 2, (0, 0), CONTRAST)) + 4.0  # + 4: flat paper's noise stays noise
    return np.clip(128 + 40 * (f - mean) / spread, 0, 255).astype(np.uint8)


def _windows(image: np.ndarray, at: np.ndarray) -> np.ndarray:
    """(n, window²): the :data:`HOLD_WINDOW`-pixel windows of ``image``
    around ``at`` (n, 2), bilinear, each of zero mean and unit norm; the
    zero-mean normalised correlation of two windows is their dot product."""
    from scipy.ndimage import map_coordinates

    offsets = np.arange(HOLD_WINDOW) - (HOLD_WINDOW - 1) / 2
    shape = (HOLD_WINDOW, HOLD_WINDOW)
    rows = np.broadcast_to(at[:, 1, None, None] + offsets[:, None], (len(at),) + shape)
    cols = np.broadcast_to(at[:, 0, None, None] + offsets[None, :], (len(at),) + shape)
    w = map_coordinates(image.astype(np.float32), [rows.ravel(), cols.ravel()], order=1, mode="nearest").reshape(len(at), -1)
    w -= w.mean(axis=1, keepdims=True)
    return w / (np.linalg.norm(w, axis=1, keepdims=True) + 1e-6)


def _weights(nodes: np.ndarray, anchors: np.ndarray, sigma: float) -> np.ndarray:
    """(m, n): the moving least squares' Gaussian weights of ``anchors`` (n, 2) at ``nodes`` (m, 2)."""
    return np.exp(-((nodes[:, None, :] - anchors[None]) ** 2).sum(-1) / (2 * sigma**2)) + 1e-12  # + 1e-12: far nodes stay defined


def _mls(nodes: np.ndarray, anchors: np.ndarray, weights: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """(m, n) and (m, 2): where the affine moving-least-squares deformation
    takes ``nodes`` (m, 2) is this matrix times where it takes ``anchors``
    (n, 2), plus the offset, given their :func:`_weights` (m, n). The
    offset is zero, as the deformation needs none, but at a node whose
    moments are singular in rounding (one anchor near it, the rest far off
    and on a line), where the solve would not give an affine map of the
    anchors back; such a node moves by its anchors' weighted mean
    displacement instead."""
    A = np.column_stack([anchors, np.ones(len(anchors))])
    G = np.column_stack([nodes, np.ones(len(nodes))])
    moments = np.einsum("mi,iab->mab", weights, A[:, :, None] * A[:, None, :])  # two operands: twice as fast as three
    try:
        solved = np.linalg.solve(moments, G[:, :, None])[..., 0]
    except np.linalg.LinAlgError:  # a node's moments exactly singular: found below with the others that are nearly so
        solved = (np.linalg.pinv(moments) @ G[:, :, None])[..., 0]
    matrix = weights * (A @ solved.T).T
    offset = np.zeros((len(nodes), 2))
    broken = np.abs(matrix @ A - G).max(axis=1) > AFFINE_KEPT
    if broken.any():
        mean = weights[broken] / weights[broken].sum(axis=1, keepdims=True)
        matrix[broken], offset[broken] = mean, nodes[broken] - mean @ anchors
    return matrix, offset


class Anchor:
    """The first frame's look of the points ``start`` (n, 2) in ``first``
    (H, W) uint8, and the warp's matrices, for :meth:`hold`."""

    def __init__(self, cv2, first: np.ndarray, start: np.ndarray, margin: int):
        self.cv2, self.start, self.shape = cv2, np.asarray(start, np.float64), first.shape
        H, W = first.shape
        x0, y0 = (max(0, int(np.floor(self.start[:, k].min())) - margin) for k in (0, 1))
        x1, y1 = min(W, int(np.ceil(self.start[:, 0].max())) + margin + 1), min(H, int(np.ceil(self.start[:, 1].max())) + margin + 1)
        self.corner = np.array([x0, y0], np.float64)
        nodes_y, nodes_x = np.mgrid[y0 : y1 + STEP : STEP, x0 : x1 + STEP : STEP].astype(np.float64)
        self.nodes_shape = nodes_x.shape
        self.look = np.ascontiguousarray(_normalised(cv2, first)[y0:y1, x0:x1])
        # Where the points are in the box, and their first look's windows, once: every frame compares against them.
        self.origin = (self.start - self.corner).astype(np.float32).reshape(-1, 1, 2)
        self.first_windows = _windows(self.look, self.origin.reshape(-1, 2))
        hull = cv2.contourArea(cv2.convexHull(self.start.astype(np.float32))) if len(self.start) >= 3 else 0.0
        self.sigma = SPREAD * max(np.sqrt(hull / len(self.start)), 1.0)
        self.nodes = np.column_stack([nodes_x.ravel(), nodes_y.ravel()])
        # Every point's weights, once: the warp is refitted to the held ones in most frames, and the distances cost most.
        self.node_weights, self.point_weights = _weights(self.nodes, self.start, self.sigma), _weights(self.start, self.start, self.sigma)
        self.fitted = None
        self._fit(np.ones(len(self.start), bool))
        shift = (STEP - 1) / 2  # cv2.resize puts node k at pixel k·STEP + (STEP − 1)/2
        rows, cols = np.mgrid[0 : y1 - y0, 0 : x1 - x0].astype(np.float32)
        self.upsample = (cols + shift, rows + shift)
        self.lk = dict(winSize=(HOLD_WINDOW, HOLD_WINDOW), maxLevel=HOLD_LEVELS,
                       criteria=(cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 30, 0.01), flags=cv2.OPTFLOW_USE_INITIAL_FLOW)

    def _fit(self, fitted: np.ndarray) -> None:
        """The warp's matrices over the points ``fitted`` (n,) bool, or over
        every point where those do not span the plane (fewer than 3, or all
        on one line: an affine fit would be singular)."""
        if np.linalg.matrix_rank(np.column_stack([self.start[fitted], np.ones(int(fitted.sum()))])) < 3:  # also fewer than 3 points
            fitted = np.ones(len(self.start), bool)
        if self.fitted is None or not np.array_equal(fitted, self.fitted):
            self.fitted, anchors = fitted.copy(), self.start[fitted]
            self.to_nodes, self.node_offset = _mls(self.nodes, anchors, self.node_weights[:, fitted])
            self.to_points, self.point_offset = _mls(self.start, anchors, self.point_weights[:, fitted])

    def _warp(self, predicted: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
        """The warp's maps over the first frame's box: where each of its pixels is in the current frame."""
        cv2, at_nodes = self.cv2, self.to_nodes @ predicted[self.fitted] + self.node_offset
        maps = []
        for c in (0, 1):
            coarse = at_nodes[:, c].reshape(self.nodes_shape).astype(np.float32)
            fine = cv2.resize(coarse, (coarse.shape[1] * STEP, coarse.shape[0] * STEP), interpolation=cv2.INTER_LINEAR)
            maps.append(cv2.remap(fine, *self.upsample, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE))
        return maps[0], maps[1]

    def hold(self, frame: np.ndarray, predicted: np.ndarray) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Every point's position in ``frame`` from the flow's ``predicted``
        (n, 2), finite: (n, 2) where each is found again by its look in the
        first frame, whether it was (``held`` (n,)), and (n, 2) the
        predictions with those far from the warp replaced by it
        (:data:`OUTLIER`), to carry the points not held to the next frame."""
        from scipy.ndimage import map_coordinates

        cv2 = self.cv2
        smooth = self.to_points @ predicted[self.fitted] + self.point_offset
        predicted = np.where((np.linalg.norm(smooth - predicted, axis=1) > OUTLIER)[:, None], smooth, predicted)
        map_x, map_y = self._warp(predicted)
        # Only the part of the frame the warp reads is normalised: its box grown by the two blurs' reach (OpenCV's
        # kernel spans 4σ a side) and bilinear's pixel, so every pixel read is as the whole frame's normalisation gives it.
        reach = int(8 * CONTRAST) + 2
        H, W = frame.shape
        x0, y0 = max(0, int(np.floor(map_x.min())) - reach), max(0, int(np.floor(map_y.min())) - reach)
        x1, y1 = min(W, int(np.ceil(map_x.max())) + reach + 1), min(H, int(np.ceil(map_y.max())) + reach + 1)
        if x1 > x0 and y1 > y0:
            pulled = cv2.remap(_normalised(cv2, frame[y0:y1, x0:x1]), map_x - np.float32(x0), map_y - np.float32(y0), cv2.INTER_LINEAR,
                               borderMode=cv2.BORDER_CONSTANT, borderValue=128)
        else:  # the warp has left the frame: nothing to find
            pulled = np.full(map_x.shape, 128, np.uint8)
        origin = self.origin
        found, ok, _ = cv2.calcOpticalFlowPyrLK(self.look, pulled, origin, origin.copy(), **self.lk)
        back, ok_back, _ = cv2.calcOpticalFlowPyrLK(pulled, self.look, found, origin.copy(), **self.lk)
        found = found.reshape(-1, 2).astype(np.float64)
        h, w = self.look.shape
        held = ((ok.ravel() == 1) & (ok_back.ravel() == 1) & (np.linalg.norm(back.reshape(-1, 2) - origin.reshape(-1, 2), axis=1) < HOLD_FB)
                & (found[:, 0] >= 0) & (found[:, 1] >= 0) & (found[:, 0] <= w - 1) & (found[:, 1] <= h - 1))
        held &= (self.first_windows * _windows(pulled, found)).sum(axis=1) >= HOLD_NCC
        position = np.stack([map_coordinates(m, [found[:, 1], found[:, 0]], order=1, mode="nearest") for m in (map_x, map_y)], axis=1).astype(np.float64)
        self._fit(held)
        return position, held, predicted
