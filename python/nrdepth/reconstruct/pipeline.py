"""What every stage after reading reads: the video's frames at the working
resolution, their statistic and the coarse pass.

The video is read twice here and once more by the writer: for the input
statistic, the frame count and the coarse pass's small frames (64×64),
then by the fine pass, a span of frames at a time (:mod:`.stitching`).
"""

from __future__ import annotations

from typing import Any, Callable, Iterable, Iterator, Optional, Tuple

import numpy as np

from ..interrupt import raise_if_interrupted
from .coarse import coarse_half
from .frames import Statistic, as_unit_float, frames_of, resize, working_shape
from .options import ReconstructOptions
from .stitch import PATCH

__all__ = ["Pipeline"]


class Pipeline:
    """A video of frames (H, W) that ``chunks()`` gives in order, in chunks,
    each time it is called, at the working resolution of ``options.max_side``,
    with its statistic and coarse pass through ``net``; ``mask``: the
    surface's pixels (1 or T, H, W), checked (:mod:`.mask`), or None."""

    def __init__(self, frame: Tuple[int, int], chunks: Callable[[], Iterable[np.ndarray]], net: Any, device: Any, options: ReconstructOptions,
                 mask: Optional[np.ndarray] = None) -> None:
        self.full, self.work = frame, working_shape(frame, options.max_side)
        self.chunks, self.net, self.device, self.options = chunks, net, device, options
        # The surface's pixels (T or 1, H, W) at the video's resolution and at the working one (the majority of each working pixel's).
        self.mask = mask
        self.mask_work = None if mask is None else (mask if self.work == self.full else resize(mask.astype(np.float32), self.work) >= 0.5)
        if self.mask_work is not None and not self.mask_work.any(axis=(1, 2)).all():
            raise ValueError(f"mask: a frame has no pixel on the surface at the working resolution {self.work} (max_side); mark more of it or raise max_side")
        statistic, small = Statistic(), []
        for chunk in self.working():
            statistic.add(chunk)
            small.append(resize(as_unit_float(chunk), PATCH[1:]))
        if not small:
            raise ValueError("video: holds no frames")
        self.statistic = statistic.result()
        self.half = coarse_half(np.concatenate(small), net, int(options.batch_size), device)
        self.shape = (len(self.half), *self.work)

    def working(self) -> Iterator[np.ndarray]:
        """The video's chunks at the working resolution (float32 in [0, 1] when resized)."""
        for chunk in self.chunks():
            raise_if_interrupted()
            if chunk.shape[1:] != self.full:
                raise ValueError(f"video: expected frames of {self.full}, got {chunk.shape[1:]}")
            yield chunk if self.work == self.full else resize(as_unit_float(chunk), self.work)

    def coarse(self, start: int, stop: int) -> np.ndarray:
        """The coarse depth of frames ``start .. stop`` at the working resolution; NaN off the mask."""
        if stop <= start:
            return np.zeros((0, *self.work), np.float32)
        coarse = resize(self.half[start:stop], self.work)
        if self.mask_work is not None:
            # NaN off the surface: the stitcher leaves those pixels out of every alignment.
            coarse[~frames_of(self.mask_work, start, stop)] = np.nan
        return coarse
