"""The sheet stage's last step: the points' depths spread over the region's
working frame (:func:`~nrdepth.baselines.tracks.densify`) and fused with
the network's stitched depth (:func:`~nrdepth.isometric.fuse`), all or
nothing: every chunk is fused before any is written back, so a failure
leaves the network's depth as it was.

Frames and units: the points in the video's pixels, moved into the region's
working frame (area-averaged resizes keep pixel centres' relative places);
the fusion's scale a fraction of the working frame's shorter side.
"""

from __future__ import annotations

import os
from typing import List, Tuple

import numpy as np

from ...baselines.tracks import densify
from ...isometric import fuse
from ..frames import CHUNK, DiskFrames

__all__ = ["fused"]


def fused(
    raw, work: Tuple[int, int], roi, region_shape: Tuple[int, int], xy: np.ndarray, depths: np.ndarray, scale: float
) -> None:
    """``raw`` (T, h, w: an array or :class:`~..frames.DiskFrames`) fused in
    place with the points ``xy`` (T, n, 2, the video's pixels) at ``depths``
    (T, n), a chunk at a time, at ``scale``; ``roi`` (x, y, w, h, or None:
    the whole ``region_shape`` frame) places the working frame ``work`` (h, w)."""
    x, y, w_region, h_region = roi or (0, 0, region_shape[1], region_shape[0])
    h, w = work
    working = (xy - np.array([x, y]) + 0.5) * np.array([w / w_region, h / h_region]) - 0.5
    staged = _Staged(raw)
    try:
        for a in range(0, len(xy), CHUNK):  # each frame is fused alone: memory stays a chunk's (and the staging's)
            b = min(a + CHUNK, len(xy))
            chunk = np.asarray(raw[a:b])
            on = np.isfinite(chunk)
            spread = densify(working[a:b], depths[a:b], chunk.shape)
            staged.append(
                np.where(on, fuse(np.where(on, chunk, 0.0), spread, scale * min(h, w), mask=on), np.nan).astype(
                    np.float32
                )
            )
        staged.commit()
    finally:
        staged.discard()


class _Staged:
    """Fused chunks held until every one is made (beside ``raw`` on disk where it is on disk), then written over it."""

    def __init__(self, raw) -> None:
        self.raw = raw
        self.disk = DiskFrames(f"{raw.path}.sheet", raw.frame) if isinstance(raw, DiskFrames) else None
        self.chunks: List[np.ndarray] = []

    def append(self, chunk: np.ndarray) -> None:
        if self.disk is not None:
            self.disk.append(chunk)
        else:
            self.chunks.append(chunk)

    def commit(self) -> None:
        start = 0
        if self.disk is not None:
            for a in range(0, len(self.disk), CHUNK):
                chunk = self.disk[a : a + CHUNK]
                self.raw[a : a + len(chunk)] = chunk
            return
        for chunk in self.chunks:
            self.raw[start : start + len(chunk)] = chunk
            start += len(chunk)

    def discard(self) -> None:
        self.chunks = []
        if self.disk is not None and os.path.exists(self.disk.path):
            self.disk.remove()
