"""The frames as the main job holds them: resized to and from the working
resolution, as unit floats or bytes, their statistic, a video on disk, a
mask's frames."""

from __future__ import annotations

import math
import os
from typing import Any, Optional, Tuple

import numpy as np

__all__ = ["CHUNK", "resize", "as_unit_float", "as_uint8", "working_shape", "Statistic", "DiskFrames", "frames_of"]

CHUNK = 16
"""Frames a chunk as the pipeline reads, converts and writes them."""


def resize(frames: np.ndarray, size: Tuple[int, int]) -> np.ndarray:
    """Bilinear resize of (T, H, W) float frames to (T, *size) (area-averaged when shrinking)."""
    import torch

    x = torch.from_numpy(np.ascontiguousarray(frames, dtype=np.float32)).unsqueeze(1)
    shrink = size[0] < frames.shape[1] or size[1] < frames.shape[2]
    mode = "area" if shrink else "bilinear"
    y = torch.nn.functional.interpolate(x, size=size, mode=mode, **({} if shrink else {"align_corners": False}))
    return y[:, 0].numpy()


def as_unit_float(frames: np.ndarray) -> np.ndarray:
    return frames.astype(np.float32) / 255.0 if frames.dtype == np.uint8 else frames.astype(np.float32)


def working_shape(shape: Tuple[int, int], max_side: Optional[int]) -> Tuple[int, int]:
    """The (H, W) a frame of ``shape`` is reconstructed at: shrunk, keeping
    its aspect, so that its longer side is at most ``max_side`` (``None``:
    as it is); never enlarged."""
    h, w = shape
    if max_side is None or max(h, w) <= max_side:
        return h, w
    scale = max_side / max(h, w)
    return max(1, round(h * scale)), max(1, round(w * scale))


class Statistic:
    """Mean and standard deviation (unbiased, as the networks' own) of a
    video's unit-float values, accumulated a chunk of frames at a time, in
    float64 (exact for uint8, by histogram)."""

    def __init__(self) -> None:
        self.counts = np.zeros(256, np.float64)
        self.n = 0
        self.total = self.squares = 0.0

    def add(self, frames: np.ndarray) -> None:
        if frames.dtype == np.uint8:
            self.counts += np.bincount(frames.ravel(), minlength=256)
        else:
            self.n += frames.size
            self.total += float(frames.sum(dtype=np.float64))
            self.squares += float(np.square(frames, dtype=np.float64).sum())

    def result(self) -> Tuple[float, float]:
        values = np.arange(256) / 255.0
        n = self.counts.sum() + self.n
        total = float(self.counts @ values) + self.total
        squares = float(self.counts @ values**2) + self.squares
        mean = total / max(n, 1)
        var = max(squares - n * mean * mean, 0.0) / max(n - 1, 1)
        return mean, math.sqrt(var)


def as_uint8(frames: np.ndarray) -> np.ndarray:
    """Gray frames as uint8 (floats in [0, 1] rounded), as the optical flow takes them."""
    return frames if frames.dtype == np.uint8 else np.rint(np.clip(frames, 0.0, 1.0) * 255).astype(np.uint8)



def frames_of(mask: np.ndarray, start: int, stop: int) -> np.ndarray:
    """Frames ``start .. stop`` of a mask (T, H, W), or its one frame repeated."""
    return np.broadcast_to(mask, (stop - start, *mask.shape[1:])) if len(mask) == 1 else mask[start:stop]


class DiskFrames:
    """A float32 video (T, H, W) on disk, appended in order and read back a
    slice of frames at a time by plain reads (not mapped: pages of a memory
    map count in the process's resident memory while they stay cached)."""

    def __init__(self, path: "os.PathLike[str]", frame: Tuple[int, int]) -> None:
        self.path, self.frame, self.count = path, tuple(frame), 0
        self.file = open(path, "w+b")

    @property
    def shape(self) -> Tuple[int, int, int]:
        return (self.count, *self.frame)

    @property
    def size(self) -> int:
        return self.count * self.frame[0] * self.frame[1]

    def __len__(self) -> int:
        return self.count

    def append(self, frames: np.ndarray) -> None:
        self.file.seek(0, os.SEEK_END)
        self.file.write(np.ascontiguousarray(frames, dtype=np.float32).tobytes())
        self.count += len(frames)

    def __getitem__(self, frames: slice) -> np.ndarray:
        start, stop, step = frames.indices(self.count)
        if step != 1:
            raise ValueError("frames: expected a contiguous slice")
        n = max(stop - start, 0)
        per = self.frame[0] * self.frame[1]
        self.file.seek(start * per * 4)
        return np.frombuffer(self.file.read(n * per * 4), np.float32).reshape(n, *self.frame).copy()

    def __setitem__(self, frames: slice, values: np.ndarray) -> None:
        start, stop, step = frames.indices(self.count)
        if step != 1 or np.shape(values) != (max(stop - start, 0), *self.frame):
            raise ValueError(f"frames: expected a contiguous slice of frames in place and values of its shape, got {frames} and {np.shape(values)}")
        self.file.seek(start * self.frame[0] * self.frame[1] * 4)
        self.file.write(np.ascontiguousarray(values, dtype=np.float32).tobytes())

    def __array__(self, dtype: Any = None, copy: Any = None) -> np.ndarray:
        whole = self[:]
        return whole if dtype is None else whole.astype(dtype)

    def remove(self) -> None:
        self.file.close()
        os.unlink(self.path)
