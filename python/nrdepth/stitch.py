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
stitch is ``alignment="coarse", window="triangle"``. Measured (README,
"Depth of a whole video"): the default beats the paper's stitch on the
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
import os
from typing import Any, Callable, Iterator, NamedTuple, Optional, Tuple, Union

import numpy as np

from . import _core

__all__ = ["PatchLayout", "patch_layout", "stitch", "temporal_align", "reconstruct", "inference_model", "coarse_depth", "patch_depths",
           "ALIGNMENTS", "WINDOWS", "COARSE_WEIGHT", "TEMPORAL_WEIGHT"]

PATCH = (16, 64, 64)
ALIGNMENTS = ("joint", "coarse")
"""How :func:`stitch` and :func:`reconstruct` align the patches, the default first (module docstring)."""
WINDOWS = ("hann", "triangle")
"""The overlap-add windows, the default first (module docstring)."""
COARSE_WEIGHT = 0.005
"""Default μ of the joint alignment: the weight of the patches' fit to the
coarse depth against their agreement with one another. On generated
256×256 videos (README), 0.005 with Hann windows kept the stitched score
of epoch 178 (shipped then) per frame within 0.002 of the paper's stitch,
and smaller weights cost more; on the real ``phisft_R1`` smaller weights score better
still."""
TEMPORAL_WEIGHT = 0.015
"""Default ν of the joint alignment's temporal tie, per pixel of a patch
(``rust/joint.rs``); 0 solves each frame on its own. Measured with
``benchmarks/temporal_tie.py`` (README, "Depth of a whole video"): at 0.015
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


def _sizes(name: str, value: Any) -> Tuple[int, int, int]:
    try:
        items = tuple(value)
    except TypeError:
        raise TypeError(f"{name}: expected three integers, got {type(value).__name__}") from None
    if len(items) != 3 or any(isinstance(v, bool) or not isinstance(v, (int, np.integer)) for v in items):
        raise ValueError(f"{name}: expected three integers, got {value!r}")
    return tuple(int(v) for v in items)  # type: ignore[return-value]


def patch_layout(shape: Tuple[int, int, int], patch: Tuple[int, int, int] = PATCH) -> PatchLayout:
    """Padding and patch origins for a (T, H, W) video."""
    shape, patch = _sizes("shape", shape), _sizes("patch", patch)
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
    ``"triangle"``): float32 (T, H, W)."""
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
    stitcher = _stitcher(coarse, layout.patch, alignment, coarse_weight, window, temporal_weight)
    stitcher.add(np.ascontiguousarray(patches, dtype=np.float32), np.ascontiguousarray(layout.origins, dtype=np.int64))
    return stitcher.finish()


def _check_stitching(alignment: str, coarse_weight: float, window: str, temporal_weight: float) -> Tuple[float, float]:
    """``coarse_weight`` and ``temporal_weight`` as floats, once ``alignment``, they and ``window`` are valid."""
    if alignment not in ALIGNMENTS:
        raise ValueError(f"alignment: expected one of {ALIGNMENTS}, got {alignment!r}")
    if window not in WINDOWS:
        raise ValueError(f"window: expected one of {WINDOWS}, got {window!r}")
    if isinstance(coarse_weight, bool) or not isinstance(coarse_weight, (int, float, np.integer, np.floating)) or not (0 < coarse_weight < math.inf):
        raise ValueError(f"coarse_weight: expected a finite number > 0, got {coarse_weight!r}")
    if isinstance(temporal_weight, bool) or not isinstance(temporal_weight, (int, float, np.integer, np.floating)) or not (0 <= temporal_weight < math.inf):
        raise ValueError(f"temporal_weight: expected a finite number ≥ 0, got {temporal_weight!r}")
    return float(coarse_weight), float(temporal_weight)


def _stitcher(coarse: np.ndarray, patch: Tuple[int, int, int], alignment: str, coarse_weight: float, window: str, temporal_weight: float) -> Any:
    """The streaming Rust stitcher of ``alignment`` and ``window`` over ``coarse``."""
    mu, nu = _check_stitching(alignment, coarse_weight, window, temporal_weight)
    coarse = np.ascontiguousarray(coarse, dtype=np.float32)
    if alignment == "coarse":
        return _core.Stitcher(coarse, patch, window)
    return _core.Stitcher(coarse, patch, window, mu, nu)


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


def _resize(frames: np.ndarray, size: Tuple[int, int]) -> np.ndarray:
    """Bilinear resize of (T, H, W) float frames to (T, *size) (area-averaged when shrinking)."""
    import torch

    x = torch.from_numpy(np.ascontiguousarray(frames, dtype=np.float32)).unsqueeze(1)
    shrink = size[0] < frames.shape[1] or size[1] < frames.shape[2]
    mode = "area" if shrink else "bilinear"
    y = torch.nn.functional.interpolate(x, size=size, mode=mode, **({} if shrink else {"align_corners": False}))
    return y[:, 0].numpy()


def reconstruct(
    video: np.ndarray,
    model: Union[None, str, "os.PathLike[str]", "torch.nn.Module"] = None,  # noqa: F821
    batch_size: int = 8,
    device: str = "auto",
    progress: Optional[Callable[[int, int], None]] = None,
    temporal: bool = False,
    roi: Optional[Tuple[int, int, int, int]] = None,
    frames: Optional[slice] = None,
    units: str = "standard",
    alignment: str = "joint",
    coarse_weight: float = COARSE_WEIGHT,
    window: str = "hann",
    temporal_weight: float = TEMPORAL_WEIGHT,
) -> np.ndarray:
    """Depth video float32 (T, H, W) of a video (T, H, W) or colour video
    (T, H, W, 3) (uint8, or float in [0, 1]; colour becomes luma, ITU-R
    BT.601, as ``nrdepth reconstruct`` does) with a trained model: a module, a
    ``model.safetensors`` path or run folder, or ``None`` for the default
    model shipped in the package. ``frames`` (a slice) and ``roi`` (x, y,
    width, height in pixels) select the part of the video to reconstruct.
    Videos smaller than a patch are padded (symmetrically).
    ``progress(done, total)`` is called as patches are predicted.
    ``temporal`` applies :func:`temporal_align` to the stitched video: it
    gives every frame frame 0's plane and relief norm, which helps a model
    that predicts neither (one trained with per-frame losses) and hurts one
    that predicts the plane's motion, as the shipped model does (off by
    default, as in the paper; README, "Benchmarks"). Depth is defined up to
    one GBR per frame (one for the video with ``temporal``) and returned
    with zero mean over the video, in ``units``: ``"standard"`` (unit
    standard deviation over the video) or ``"pixels"`` (depth in pixels of
    the video, the relief's scale as the model reads it: only for a model
    trained with a relief-amplitude term, whose ``depth_units`` is
    ``"window"``; without ``model``, the shipped one that learnt it,
    :data:`nrdepth.model.SCALED_MODEL`. The coarse pass sees the whole
    frame as one window, so a window width is √(H·W) pixels, the frame's
    width when it is square, and the stitched relief is given the coarse
    pass's scale by one least-squares factor over the video). Its overall sign (convex or concave) follows
    the training data's light-from-above prior (lights within ±70° of
    image-up, row 0 being the top): under an
    orthographic camera a surface and its mirror image under mirrored lights
    make the same video, so a video lit from below reads inverted, and
    ``-depth`` is the other reading. The sign is consistent over space and
    (with ``temporal``) time. Patches stream through the network and the
    stitcher a chunk at a time: memory is a few copies of the video, not of
    its (8× overlapping) patches. ``alignment`` chooses how the patches are
    aligned: ``"joint"`` with ``coarse_weight`` and ``temporal_weight``
    (the default) or ``"coarse"`` (the paper's), and ``window`` how they are blended:
    ``"hann"`` (the default) or ``"triangle"`` (the paper's; module
    docstring)."""
    import torch

    from .model.io import resolve_device
    from .videoio import select, to_gray

    video = select(to_gray(video, "video"), frames, roi)
    if isinstance(batch_size, bool) or not isinstance(batch_size, (int, np.integer)) or batch_size < 1:
        raise ValueError(f"batch_size: expected a positive integer, got {batch_size!r}")
    batch_size = int(batch_size)
    if progress is not None and not callable(progress):
        raise TypeError(f"progress: expected a callable progress(done, total) or None, got {type(progress).__name__}")
    if model is not None and not isinstance(model, (str, os.PathLike, torch.nn.Module)):
        raise TypeError(f"model: expected None, a path to model.safetensors or its folder, or a torch.nn.Module, got {type(model).__name__}")
    if units not in ("standard", "pixels"):
        raise ValueError(f"units: expected 'standard' or 'pixels', got {units!r}")
    _check_stitching(alignment, coarse_weight, window, temporal_weight)
    dev = resolve_device(device)
    if model is None and units == "pixels":
        from .model.io import SCALED_MODEL

        model = SCALED_MODEL
    net = model.to(dev).eval() if isinstance(model, torch.nn.Module) else inference_model(model, dev)
    if units == "pixels" and getattr(net, "depth_units", None) != "window":
        raise ValueError("units: 'pixels' needs a model that learnt the relief's scale (model.json's depth_units 'window', "
                         "nrdepth train --amplitude); this one gives depth up to scale: use units='standard'")
    layout = patch_layout(video.shape)
    coarse = coarse_depth(video, net, batch_size, dev)
    stitcher = _stitcher(coarse, layout.patch, alignment, coarse_weight, window, temporal_weight)
    if units != "pixels":
        del coarse  # the stitcher holds its own copy; only the pixel scale needs this one
    done = 0
    for origins, depth in patch_depths(video, net, layout, batch_size, dev):
        stitcher.add(depth, origins)
        done += len(origins)
        if progress is not None:
            progress(done, len(layout.origins))
    depth = stitcher.finish()
    if temporal:
        depth = temporal_align(depth)
    if units == "pixels":
        # The coarse pass reads the relief's scale (one window the frame); the
        # patches' fits shrink it (least squares regresses toward the fit's
        # target, and the joint alignment's agreement term falls with the
        # scale squared), so the stitched relief takes the coarse pass's.
        depth = depth * _relief_scale(depth, coarse)
        return ((depth - depth.mean(dtype=np.float64)) * np.sqrt(video.shape[1] * video.shape[2])).astype(np.float32)
    mean = depth.mean(dtype=np.float64)
    # A network without a depth scale (GBR-invariant losses only): return a
    # canonical one rather than whatever magnitude its weights drifted to.
    std = depth.std(dtype=np.float64)
    return ((depth - mean) / (std if std > 0 else 1.0)).astype(np.float32)


def _relief_scale(depth: np.ndarray, reference: np.ndarray) -> float:
    """Least-squares s with s·r(depth) ≈ r(reference) over a video (T, H,
    W), r being each frame minus its least-squares plane; 1 if ``depth`` has
    no relief (planar frames, up to rounding)."""
    _, h, w = depth.shape
    y, x = np.mgrid[0:h, 0:w]
    basis, _ = np.linalg.qr(np.stack([x.ravel(), y.ravel(), np.ones(h * w)], axis=1))
    num = den = total = 0.0
    for frame, ref in zip(depth, reference):
        f = frame.ravel().astype(np.float64)
        total += float(f @ f)
        f -= basis @ (basis.T @ f)
        num += float(f @ ref.ravel())  # the plane of ``ref`` is orthogonal to the residual ``f``
        den += float(f @ f)
    return num / den if den > 1e-12 * total else 1.0


def inference_model(model: Union[None, str, "os.PathLike[str]"], device: "torch.device") -> "torch.nn.Module":  # noqa: F821
    """The network :func:`reconstruct` runs: ``load_model(model)`` on
    ``device`` in the channels-last 3D layout (≈ 1.4× faster on the CPU)."""
    import torch

    from .model.io import load_model

    return load_model(model, device=str(device)).to(memory_format=torch.channels_last_3d)


def _as_unit_float(frames: np.ndarray) -> np.ndarray:
    return frames.astype(np.float32) / 255.0 if frames.dtype == np.uint8 else frames.astype(np.float32)


def coarse_depth(video: np.ndarray, net: "torch.nn.Module", batch_size: int, device: "torch.device", readings: int = 2) -> np.ndarray:  # noqa: F821
    """The coarse pass of :func:`reconstruct`: the whole video (T, H, W)
    resized to the patch side, in 16-frame windows (the last one mirrored),
    through the network, and its depth resized back: float32 (T, H, W).
    Each window is read ``readings`` times (:func:`~nrdepth.model.predict_depth`),
    by default twice, as it is and mirrored left-right, the two depths
    averaged: the mirror keeps image-up (so the light prior, and the
    relief's sign), and this one reading sets every patch's large-scale
    shape, so halving its variance pays (README, "Depth of a whole video");
    the pass runs one network window per 16 frames, so reading it twice is
    nearly free. Reading the patches more than once changes the stitched
    depth by under 0.001 (README), so :func:`patch_depths` reads them once."""
    from .model.io import predict_depth

    lt, ls, _ = PATCH
    t, h, w = video.shape
    windows = -(-t // lt)
    small = np.pad(_resize(_as_unit_float(video), (ls, ls)), ((0, windows * lt - t), (0, 0), (0, 0)), mode="symmetric")
    small = small.reshape(windows, lt, ls, ls)
    coarse = predict_depth(net, small, batch_size, device, readings=readings)
    return _resize(coarse.reshape(windows * lt, ls // 2, ls // 2)[:t], (h, w))


def patch_depths(
    video: np.ndarray,
    net: "torch.nn.Module",  # noqa: F821
    layout: PatchLayout,
    batch_size: int,
    device: "torch.device",  # noqa: F821
    chunk: int = 64,
) -> Iterator[Tuple[np.ndarray, np.ndarray]]:
    """The fine pass of :func:`reconstruct`: for ``chunk`` patches at a time of
    the symmetrically padded video, their origins (n, 3) and depths
    (n, 16, 64, 64) (the network's half-resolution output upsampled)."""
    from .model.io import predict_depth

    lt, ls, _ = PATCH
    back = [layout.padded[a] - layout.shape[a] - layout.pad[a] for a in range(3)]
    padded = np.pad(video, [(layout.pad[a], back[a]) for a in range(3)], mode="symmetric")  # the input's dtype
    for i in range(0, len(layout.origins), chunk):
        origins = layout.origins[i : i + chunk]
        patches = np.stack([padded[t : t + lt, y : y + ls, x : x + ls] for t, y, x in origins])  # scaled by predict_depth
        half = predict_depth(net, patches, batch_size, device)
        yield origins, _resize(half.reshape(-1, *half.shape[2:]), (ls, ls)).reshape(len(half), lt, ls, ls)
