"""The surface's pixels (``mask``): checked against the video and cut as
it is, from an array or a file."""

from __future__ import annotations

import os
from typing import Any, Optional, Tuple

import numpy as np

from ..checks import option_error
from ..io.decode import VideoSource, open_video, select
from .frames import CHUNK

__all__ = ["video_mask", "file_mask"]


def video_mask(mask: Any, video_shape: Tuple[int, ...], frames: Optional[slice], roi: Any) -> Optional[np.ndarray]:
    """``mask`` (bool (H, W) or (T, H, W) of the video as given; its dtype
    and the options it needs checked by :class:`~nrdepth.ReconstructOptions`)
    cut as the video is, (1 or T', h, w); None stays None."""
    if mask is None:
        return None
    if isinstance(mask, (str, os.PathLike)):
        raise option_error("mask", f"a file ({mask}) is read by reconstruct_file; reconstruct takes a bool array", TypeError)
    mask = np.asarray(mask)
    t, h, w = video_shape[:3]
    if mask.shape not in ((h, w), (t, h, w)):
        raise option_error("mask", f"expected ({h}, {w}) or ({t}, {h}, {w}), the video's frames, got {mask.shape}")
    mask = select(mask[None] if mask.ndim == 2 else mask, None if mask.ndim == 2 else frames, roi)
    if not mask.any(axis=(1, 2)).all():
        raise option_error("mask", "a frame has no pixel on the surface")
    return mask


def file_mask(mask: Any, source: VideoSource, frames: Optional[slice], roi: Any) -> Optional[np.ndarray]:
    """:func:`~nrdepth.reconstruct_file`'s ``mask`` (an array, or a file of
    one frame or of the input's frames) cut as the input ``source`` is,
    (1 or T', h, w)."""
    if mask is None or not isinstance(mask, (str, os.PathLike)):
        t = source.count_all() if np.ndim(mask) == 3 else 0  # a video file is decoded to count its frames only for a mask of each
        return video_mask(mask, (t, *source.raw_size), frames, roi)
    whole = open_video(mask, "mask")
    if whole.raw_size != source.raw_size:
        raise option_error("mask", f"expected frames of the input's size {source.raw_size}, got {whole.raw_size} in {mask}")
    if whole.count_all() == 1:
        return video_mask(next(whole.chunks(1))[0] >= 128, (0, *source.raw_size), None, roi)
    if whole.count_all() != source.count_all():
        raise option_error("mask", f"expected one image or the input's {source.count_all()} frames, got {whole.count_all()} in {mask}")
    cut = np.concatenate([chunk >= 128 for chunk in open_video(mask, "mask", frames, roi).chunks(CHUNK)])
    return video_mask(cut, cut.shape, None, None)
