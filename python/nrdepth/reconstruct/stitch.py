"""Depth video of a video of any size from patch predictions (paper section
"Reconstruction of a depth map from local patches"), by constant overlap-add.

The video is cut into (16, 64, 64) patches at a hop of half a patch on every
axis, over the video padded by half a patch in front (symmetric padding).
Each patch's predicted depth is right only up to its own GBR per frame, so
the patches are aligned before they are weighted by separable windows and
added up; the windows sum to one over the video, so stitching needs no
normalisation. Two alignments (``alignment``):

- ``"joint"`` (the default; beyond the paper): in each frame, all the
  patches together, so that they agree with one another where they
  overlap, tied to a coarse depth (the network's prediction for the whole
  video resized to the patch size, in 16-frame windows) by a weight
  ``coarse_weight``, both over the video's own pixels (not its mirrored
  padding; the objective: ``rust/joint.rs``). The large-scale shape comes
  from the patches' agreement as well as from the coarse pass. Each
  patch's GBR is also tied to its GBR of the frame before by
  ``temporal_weight``, as much as the patch's own depth holds still
  (the tie lets go where it moves or deforms), so the reading of one patch
  does not flicker with the noise of each frame's fit.
- ``"coarse"``, the paper's: each patch on its own, frame by frame, to the
  coarse depth by least-squares GBR. The coarse pass alone then sets the
  video's large-scale shape.

Two windows (``window``): ``"hann"`` (the default), sin², and
``"triangle"``, the paper's. The triangle's kinks, at every multiple of the
hop, leave a grid wherever neighbouring patches disagree; the Hann window's
slope is continuous, and its stitched depth shows no grid. The paper's
stitch is ``alignment="coarse", window="triangle"``. Measured (docs/stitching.md): the default beats the paper's stitch on the
real ``phisft_R1`` for every one of 24 checkpoints of the campaign (0.2501
against 0.2719 on average; 0.2545 without its temporal tie), is level
with it per frame on generated videos, and leaves the spectrum at the
patch period close to the truth's.

Alignment and overlap-add run in Rust (``_core.Stitcher``, given a window,
and a ``coarse_weight`` and ``temporal_weight`` for the joint alignment),
fed a chunk of patches at a time, so memory does not grow with the
patches' 8× overlap. Beyond the paper,
:func:`temporal_align` then removes the per-frame GBR flicker.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple, Optional, Tuple

import numpy as np

from .. import _core
from ..checks import int_triple, is_number, option_error

__all__ = ["PatchLayout", "patch_layout", "stitch", "temporal_align", "make_stitcher", "check_stitching", "PATCH", "ALIGNMENTS", "WINDOWS", "COARSE_WEIGHT", "TEMPORAL_WEIGHT"]

PATCH = (16, 64, 64)
ALIGNMENTS = ("joint", "coarse")
"""How :func:`stitch` and :func:`reconstruct` align the patches, the default first (module docstring)."""
WINDOWS = ("hann", "triangle")
"""The overlap-add windows, the default first (module docstring)."""
COARSE_WEIGHT = 0.005
"""Default μ of the joint alignment: the weight of the patches' fit to the
coarse depth against their agreement with one another. On generated
256×256 videos (docs/stitching.md), 0.005 with Hann windows kept the stitched score
of epoch 178 (shipped then) per frame within 0.002 of the paper's stitch,
and smaller weights cost more; on the real ``phisft_R1`` smaller weights score better
still."""
TEMPORAL_WEIGHT = 0.015
"""Default ν of the joint alignment's temporal tie, per pixel of a patch
(``rust/joint.rs``); 0 solves each frame on its own. Measured with
``experiments/temporal_tie.py`` (docs/stitching.md): at 0.015
the real ``phisft_R1`` gains (epoch 178: 0.2323 → 0.2255 per frame), generated
256×256 videos stay level per frame (within 0.002 either way over two
draws) and gain from the first frame inside the training ranges; larger
weights gain more on the cloth but lose outside the ranges."""


class PatchLayout(NamedTuple):
    shape: Tuple[int, int, int]
    """The video's (T, H, W)."""
    patch: Tuple[int, int, int]
    pad: Tuple[int, int, int]
    """Front padding per axis (half a patch)."""
    padded: Tuple[int, int, int]
    """Padded shape, a whole number of hops per axis."""
    origins: np.ndarray
    """int64 (N, 3): (t, y, x) of every patch in padded coordinates."""


MAX_PATCHES = 2**24
"""Most patches a layout may hold (its origins alone take 8 bytes × 3 each)."""
MAX_VOXELS = 2**34
"""Largest padded video a layout may describe (the stitcher keeps float32 sums of it)."""


def patch_layout(shape: Tuple[int, int, int], patch: Tuple[int, int, int] = PATCH) -> PatchLayout:
    """Padding and patch origins for a (T, H, W) video."""
    shape, patch = int_triple("shape", shape), int_triple("patch", patch)
    if min(shape) >= 1 and min(patch) >= 1:
        hops = [max(p // 2, 1) for p in patch]
        count = math.prod(s // h + 2 for s, h in zip(shape, hops))
        voxels = math.prod(s + p for s, p in zip(shape, patch))
        if count > MAX_PATCHES or voxels > MAX_VOXELS:
            raise ValueError(f"shape: {shape} with patch {patch} would need about {count:,} patches over {voxels:,} voxels (at most {MAX_PATCHES:,} and {MAX_VOXELS:,})")
    pad, padded, origins = _core.patch_layout(shape, patch)
    return PatchLayout(shape, patch, tuple(pad), tuple(padded), np.asarray(origins, dtype=np.int64).reshape(-1, 3))  # type: ignore[arg-type]


def stitch(
    patches: np.ndarray,
    coarse: np.ndarray,
    layout: PatchLayout,
    alignment: str = "joint",
    coarse_weight: float = COARSE_WEIGHT,
    window: str = "hann",
    temporal_weight: float = TEMPORAL_WEIGHT,
) -> np.ndarray:
    """Align the patch depths (N, Lt, Ls, Ls), one per origin of ``layout``,
    by per-frame GBRs (``alignment``: ``"joint"``, all together, tied to
    ``coarse`` (T, H, W) by ``coarse_weight`` and each patch's to its GBR of
    the frame before by ``temporal_weight``; ``"coarse"``, each on its own
    to ``coarse``, as the paper does, which takes neither weight) and
    overlap-add them with ``window`` (``"hann"`` or the paper's
    ``"triangle"``): float32 (T, H, W). With the joint alignment,
    ``coarse`` may be NaN off the surface: those pixels take no part in
    any alignment, and come back NaN."""
    patches = np.asarray(patches)
    coarse = np.asarray(coarse)
    for name, a, ndim in (("patches", patches, 4), ("coarse", coarse, 3)):
        if a.dtype.kind != "f":
            raise TypeError(f"{name}: expected a floating-point array, got dtype {a.dtype}")
        if a.ndim != ndim:
            raise ValueError(f"{name}: expected {ndim} dimensions, got shape {a.shape}")
    if tuple(coarse.shape) != tuple(layout.shape):
        raise ValueError(f"coarse: expected the layout's shape {layout.shape}, got {coarse.shape}")
    if tuple(patches.shape[1:]) != tuple(layout.patch):
        raise ValueError(f"patches: expected patches of {layout.patch}, got {patches.shape[1:]}")
    expected = patch_layout(layout.shape, layout.patch)
    if (tuple(layout.pad), tuple(layout.padded)) != (expected.pad, expected.padded) or not np.array_equal(np.asarray(layout.origins), expected.origins):
        raise ValueError(f"layout: not the layout of a {layout.shape} video in {layout.patch} patches; build it with patch_layout(shape)")
    if len(patches) != len(expected.origins):
        raise ValueError(f"patches: expected one patch per origin of the layout ({len(expected.origins)}), got {len(patches)}")
    stitcher = make_stitcher(coarse, layout.patch, alignment, coarse_weight, window, temporal_weight)
    stitcher.add(np.ascontiguousarray(patches, dtype=np.float32), np.ascontiguousarray(layout.origins, dtype=np.int64))
    return stitcher.finish()


def check_stitching(alignment: str, coarse_weight: float, window: str, temporal_weight: float) -> Tuple[float, float]:
    """``coarse_weight`` and ``temporal_weight`` as floats, once ``alignment``, they and ``window`` are valid."""
    if alignment not in ALIGNMENTS:
        raise option_error("alignment", f"expected one of {ALIGNMENTS}, got {alignment!r}")
    if window not in WINDOWS:
        raise option_error("window", f"expected one of {WINDOWS}, got {window!r}")
    if not is_number(coarse_weight) or not (0 < coarse_weight < math.inf):
        raise option_error("coarse_weight", f"expected a finite number > 0, got {coarse_weight!r}")
    if not is_number(temporal_weight) or not (0 <= temporal_weight < math.inf):
        raise option_error("temporal_weight", f"expected a finite number ≥ 0, got {temporal_weight!r}")
    return float(coarse_weight), float(temporal_weight)


def make_stitcher(coarse: np.ndarray, patch: Tuple[int, int, int], alignment: str, coarse_weight: float, window: str, temporal_weight: float,
                  frames: Optional[int] = None) -> Any:
    """The streaming Rust stitcher of ``alignment`` and ``window`` over
    ``coarse``; with ``frames`` (the joint alignment only), ``coarse`` may
    hold only the first of the video's ``frames`` frames, the rest to come
    by ``push_coarse``, and ``take`` gives the frames stitched so far."""
    mu, nu = check_stitching(alignment, coarse_weight, window, temporal_weight)
    coarse = np.ascontiguousarray(coarse, dtype=np.float32)
    if alignment == "coarse":
        return _core.Stitcher(coarse, patch, window)
    return _core.Stitcher(coarse, patch, window, mu, nu, frames)


def temporal_align(depth: np.ndarray) -> np.ndarray:
    """Give every frame of a depth video (T, H, W) frame 0's GBR: frame 0's
    least-squares plane, its relief norm, and a relief sign consistent with
    the frame before (beyond the paper: removes the per-frame GBR flicker of
    stitched depth). Returns float32 (T, H, W); exact for a fixed relief seen
    through a different GBR in every frame. Formula: ``rust/stitch.rs``."""
    depth = np.asarray(depth)
    if depth.dtype.kind != "f" or depth.ndim != 3 or min(depth.shape) < 1:
        raise ValueError(f"depth: expected a float depth video (T, H, W), got {depth.dtype} {depth.shape}")
    return _core.temporal_align(np.ascontiguousarray(depth, dtype=np.float32))
