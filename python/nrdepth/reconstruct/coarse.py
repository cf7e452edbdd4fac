"""The coarse pass: each whole frame at the patch side (64×64), through the
network in 16-frame windows. It sets every window's large-scale shape in
the stitch (docs/stitching.md)."""

from __future__ import annotations

import numpy as np

from .frames import as_unit_float, resize
from .stitch import PATCH

__all__ = ["coarse_depth", "coarse_half"]


def coarse_depth(video: np.ndarray, net: "torch.nn.Module", batch_size: int, device: "torch.device", readings: int = 2) -> np.ndarray:  # noqa: F821
    """The coarse pass of :func:`reconstruct`: the whole video (T, H, W)
    resized to the patch side, in 16-frame windows (the last one mirrored),
    through the network, and its depth resized back: float32 (T, H, W).
    Each window is read ``readings`` times (:func:`~nrdepth.model.predict_depth`),
    by default twice, as it is and mirrored left-right, the two depths
    averaged: the mirror keeps image-up (so the light prior, and the
    relief's sign), and this one reading sets every patch's large-scale
    shape, so halving its variance pays (docs/stitching.md); the pass runs
    one network window per 16 frames, so reading it twice is nearly free."""
    _, h, w = video.shape
    return resize(coarse_half(resize(as_unit_float(video), PATCH[1:]), net, batch_size, device, readings), (h, w))


def coarse_half(small: np.ndarray, net: "torch.nn.Module", batch_size: int, device: "torch.device", readings: int = 2) -> np.ndarray:  # noqa: F821
    """The network's depth (T, 32, 32) of a video already at the patch side
    (T, 64, 64) float in [0, 1], in 16-frame windows, the last one mirrored
    (:func:`coarse_depth` before its resize back).

    A network with a coarse companion (``model.json``'s ``coarse_companion``,
    :func:`~nrdepth.model.load_model`) gives ``(1 − share)·a + share·b``
    instead, where ``a`` and ``b`` are its and its companion's depths, each
    16-frame window standardised (mean 0, standard deviation 1): so that
    neither network's scale weighs more than its share."""
    companion = getattr(net, "coarse_companion", None)
    if companion is None:
        return coarse_reading(small, net, batch_size, device, readings)
    other, share = companion
    mine = standardised_windows(coarse_reading(small, net, batch_size, device, readings))
    theirs = standardised_windows(coarse_reading(small, other, batch_size, device, readings))
    return ((1 - share) * mine + share * theirs).astype(np.float32)


def standardised_windows(depth: np.ndarray) -> np.ndarray:
    """Depth (T, h, w) with each 16-frame window at mean 0, standard deviation 1 (float64)."""
    out = depth.astype(np.float64)
    for start in range(0, len(out), PATCH[0]):
        window = out[start : start + PATCH[0]]
        window -= window.mean()
        window /= window.std() or 1.0
    return out


def coarse_reading(small: np.ndarray, net: "torch.nn.Module", batch_size: int, device: "torch.device", readings: int) -> np.ndarray:  # noqa: F821
    """One network's depth of :func:`coarse_half`."""
    from ..model.io import predict_depth

    lt, ls, _ = PATCH
    t = len(small)
    windows = -(-t // lt)
    small = np.pad(small, ((0, windows * lt - t), (0, 0), (0, 0)), mode="symmetric").reshape(windows, lt, ls, ls)
    return predict_depth(net, small, batch_size, device, readings=readings).reshape(windows * lt, ls // 2, ls // 2)[:t]
