"""The main job: a video in, its depth video out.

:func:`reconstruct` (an array) and :func:`reconstruct_file` (a file to a
folder, streamed) select the frames and region, shrink the video to a
working resolution (``max_side``, :data:`MAX_SIDE`), run the coarse pass
(the whole frame at the patch size, :func:`coarse_depth`), then the fine
pass, align and overlap-add its 16×64×64 windows with the stitcher
(:mod:`nrdepth.stitch`), and give the depth its units and the video's
resolution back. docs/reconstruction.md has the figures.

Two fine passes (``fine``) feed the stitcher the same windows, at the same
origins (:func:`~nrdepth.stitch.patch_layout`):

- ``"field"`` (the default): the network runs **once** over the video, in
  large tiles (:data:`TILE` frames × rows × columns) that overlap by
  :data:`MARGIN` on every side, discarded: each output voxel is computed
  once (plus the margins), not eight times. The networks are fully
  convolutional, so a tile's output away from its edges is the output of
  one pass over the whole video. Tiles end at the video's own borders, where
  the network's zero padding stands in for what lies outside, as at every
  edge of a training clip. The tiles' half-resolution depth is assembled into
  one field, upsampled once, mirrored into the layout's padding, and the
  windows are cut from it. The input is standardised with **one statistic
  for the whole video** (its mean and standard deviation), not per tile, so
  a tile's output does not depend on where the tile boundaries fall: at the
  default margins the tiled field of ``kinect_paper`` differs from one
  untiled pass by 0.0006 of its standard deviation on average, 0.11 at
  most (``benchmarks/bench_video.py``; ``tests/test_fine_pass.py``).
- ``"patches"``: every window through the network on its own, standardised
  per window (the paper's way; 8× the network work).

Frames flow through in time order: the fine pass computes a span of frames,
the windows it completes go to the stitcher, which gives back the frames it
has solved, and frames no window needs any more are dropped, so memory does
not grow with the video's length (:func:`reconstruct_file`).
"""

from __future__ import annotations

import math
import os
from contextlib import nullcontext
from typing import Any, Callable, Iterable, Iterator, Optional, Tuple, Union

import numpy as np

from .isometric import DROP
from .stitch import COARSE_WEIGHT, PATCH, TEMPORAL_WEIGHT, PatchLayout, _check_stitching, _stitcher, patch_layout, temporal_align
from .videoio import select, to_gray

__all__ = ["reconstruct", "reconstruct_file", "MAX_SIDE", "coarse_depth", "patch_depths", "field_frames", "field_windows", "tile_plan", "inference_model", "working_shape",
           "FINE_PASSES", "TILE", "GPU_TILE", "MARGIN"]

MAX_SIDE = 480
"""Default working resolution: a frame's longer side, in pixels. Measured
(``benchmarks/bench_video.py --resolution``, docs/reconstruction.md): the
real cloth ``phisft_R1``, filmed at 1920×1080, reads best at this scale (a
1920-wide frame at 480: MAE-SN 0.2226 per frame, against 0.2479 and 0.2567
at 1.5× and 2× the scale, and 0.2689 at 0.67×), and the real sheet of
``kinect_paper`` reads the same at 384 and 528 (9.76 mm); a 1080p frame
costs 16× less than at its own size."""
FINE_PASSES = ("field", "patches")
"""The fine passes of :func:`reconstruct`, the default first (module docstring)."""
TILE = (32, 320, 320)
"""Default core of a fine-pass tile on the CPU: frames, rows, columns (rows
and columns multiples of 8, the networks' coarsest stride). With
:data:`MARGIN` a tile holds at most 48 × 448 × 448 input voxels (≈ 200
bytes of activations each). Larger tiles pay less margin but run slower
per voxel on a 2-core CPU (cache): the network alone over ``kinect_paper``
took 41.7 s with this core, 48.4 s with (32, 256, 256) (a one-off timing)."""
GPU_TILE = (64, 512, 512)
"""Default core of a tile on CUDA, where larger tiles keep the device busy."""
MARGIN = (8, 64, 64)
"""Overlap of a tile on each side, discarded: frames, rows, columns. One
output voxel's input gradient has 0.9 % of its mass more than 8 frames and
2.3 % more than 64 pixels away (a one-off measurement); at these margins the tiled field of the
real ``kinect_paper`` differs from one untiled pass by 0.06 % of its
standard deviation on average (48-pixel margins: 0.5 %, with seams up to
half a standard deviation; ``benchmarks/bench_video.py`` prints it)."""


def _resize(frames: np.ndarray, size: Tuple[int, int]) -> np.ndarray:
    """Bilinear resize of (T, H, W) float frames to (T, *size) (area-averaged when shrinking)."""
    import torch

    x = torch.from_numpy(np.ascontiguousarray(frames, dtype=np.float32)).unsqueeze(1)
    shrink = size[0] < frames.shape[1] or size[1] < frames.shape[2]
    mode = "area" if shrink else "bilinear"
    y = torch.nn.functional.interpolate(x, size=size, mode=mode, **({} if shrink else {"align_corners": False}))
    return y[:, 0].numpy()


def _as_unit_float(frames: np.ndarray) -> np.ndarray:
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


def inference_model(model: Union[None, str, "os.PathLike[str]"], device: "torch.device") -> "torch.nn.Module":  # noqa: F821
    """The network :func:`reconstruct` runs: ``load_model(model)`` on
    ``device`` in the channels-last 3D layout (≈ 1.4× faster on the CPU)."""
    import torch

    from .model.io import load_model

    net = load_model(model, device=str(device))
    for each in _networks(net):
        each.to(memory_format=torch.channels_last_3d)
    return net


def _networks(net: "torch.nn.Module") -> list:  # noqa: F821
    """``net`` and its coarse companion's network, if it has one."""
    companion = getattr(net, "coarse_companion", None)
    return [net] if companion is None else [net, companion[0]]


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
    return _resize(coarse_half(_resize(_as_unit_float(video), PATCH[1:]), net, batch_size, device, readings), (h, w))


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
        return _coarse_reading(small, net, batch_size, device, readings)
    other, share = companion
    mine = _standardised_windows(_coarse_reading(small, net, batch_size, device, readings))
    theirs = _standardised_windows(_coarse_reading(small, other, batch_size, device, readings))
    return ((1 - share) * mine + share * theirs).astype(np.float32)


def _standardised_windows(depth: np.ndarray) -> np.ndarray:
    """Depth (T, h, w) with each 16-frame window at mean 0, standard deviation 1 (float64)."""
    out = depth.astype(np.float64)
    for start in range(0, len(out), PATCH[0]):
        window = out[start : start + PATCH[0]]
        window -= window.mean()
        window /= window.std() or 1.0
    return out


def _coarse_reading(small: np.ndarray, net: "torch.nn.Module", batch_size: int, device: "torch.device", readings: int) -> np.ndarray:  # noqa: F821
    """One network's depth of :func:`coarse_half`."""
    from .model.io import predict_depth

    lt, ls, _ = PATCH
    t = len(small)
    windows = -(-t // lt)
    small = np.pad(small, ((0, windows * lt - t), (0, 0), (0, 0)), mode="symmetric").reshape(windows, lt, ls, ls)
    return predict_depth(net, small, batch_size, device, readings=readings).reshape(windows * lt, ls // 2, ls // 2)[:t]


def patch_depths(
    video: np.ndarray,
    net: "torch.nn.Module",  # noqa: F821
    layout: PatchLayout,
    batch_size: int,
    device: "torch.device",  # noqa: F821
    chunk: int = 64,
) -> Iterator[Tuple[np.ndarray, np.ndarray]]:
    """The ``"patches"`` fine pass: for ``chunk`` patches at a time of the
    symmetrically padded video, their origins (n, 3) and depths
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


def _spans(length: int, core: int, margin: int, align: int) -> list:
    """Tiles along one axis of ``length`` (a multiple of ``align``): cores
    of at most ``core`` (about equal, their bounds multiples of ``align``),
    each widened by ``margin`` on both sides within the axis. Tuples (lo,
    hi, keep_lo, keep_hi): compute [lo, hi), keep [keep_lo, keep_hi)."""
    count = -(-length // core)
    bounds = [min(length, -(-round(i * length / count) // align) * align) for i in range(count + 1)]
    bounds = sorted(set(bounds))
    return [(max(0, a - margin), min(length, b + margin), a, b) for a, b in zip(bounds[:-1], bounds[1:])]


def _time_multiple(net: "torch.nn.Module") -> int:  # noqa: F821
    """The frame count a network's input must be a multiple of: 4 for the
    paper's U-Net (it pools time twice), 1 for the (2+1)D networks."""
    from .model.unet import UNet3D

    return 4 if isinstance(net, UNet3D) else 1


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


def _check_sizes(name: str, value: Any) -> Tuple[int, int, int]:
    try:
        t, y, x = (int(v) for v in value if not isinstance(v, bool) and int(v) == v)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected three integers (frames, rows, columns), got {value!r}") from None
    return t, y, x


def field_frames(
    video: Union[np.ndarray, Tuple[Tuple[int, int, int], Iterable[np.ndarray]]],
    net: "torch.nn.Module",  # noqa: F821
    device: "torch.device",  # noqa: F821
    tile: Optional[Tuple[int, int, int]] = None,
    margin: Tuple[int, int, int] = MARGIN,
    statistic: Optional[Tuple[float, float]] = None,
) -> Iterator[Tuple[int, np.ndarray]]:
    """The network's depth of a video, computed in overlapping tiles, one
    span of frames at a time: pairs (t0, depth) of the span's first frame
    and its float32 depth (n, H, W) at the video's resolution (the
    network's half-resolution output assembled, then upsampled bilinearly
    once), in time order, covering every frame once.

    ``video``: an array (T, H, W), or its shape and an iterable of its
    frames in chunks (n, H, W) in order, read only as far as each span
    needs (uint8, or float in [0, 1]). ``statistic``: the (mean, standard
    deviation) the input is standardised with (default: the array's own;
    required with chunks). ``tile``: a tile's core (frames, rows, columns;
    :data:`TILE`, or :data:`GPU_TILE` on CUDA); ``margin``: its overlap on
    each side, discarded (:data:`MARGIN`)."""
    import torch

    from .model.unet2p1d import STD_FLOOR

    tile = (GPU_TILE if device.type == "cuda" else TILE) if tile is None else _check_sizes("tile", tile)
    margin = _check_sizes("margin", margin)
    if min(tile) < 1 or tile[1] % 8 or tile[2] % 8:
        raise ValueError(f"tile: expected positive sizes, rows and columns multiples of 8, got {tile}")
    if min(margin) < 0 or margin[1] % 8 or margin[2] % 8:
        raise ValueError(f"margin: expected sizes ≥ 0, rows and columns multiples of 8, got {margin}")
    if isinstance(video, np.ndarray):
        shape, chunks = video.shape, [video]
        if statistic is None:
            statistic = Statistic()
            statistic.add(video)
            statistic = statistic.result()
    else:
        shape, chunks = video
        if statistic is None:
            raise ValueError("statistic: required when the video comes in chunks")
    mean, std = statistic
    t, h, w = shape
    tm = _time_multiple(net)
    # The network's multiples, reached by mirroring the last frames, rows and columns; the extra is discarded.
    size = _network_size(shape, net)
    frame_of = np.pad(np.arange(t), (0, size[0] - t), mode="symmetric")
    standardised = getattr(net, "forward_standardised", None)
    autocast = torch.autocast("cuda", dtype=torch.bfloat16) if device.type == "cuda" else nullcontext()
    rows = _spans(size[1], tile[1], margin[1], 8)
    cols = _spans(size[2], tile[2], margin[2], 8)
    spans = _spans(size[0], tile[0], margin[0], tm)
    source, loaded, buffer = iter(chunks), 0, {}
    net.eval()
    with torch.inference_mode(), autocast:
        for n, (lo, hi, keep_lo, keep_hi) in enumerate(spans):
            needed = frame_of[lo:hi]
            while loaded <= needed.max():
                chunk = next(source, None)
                if chunk is None or chunk.shape[1:] != (h, w):
                    raise ValueError(f"video: expected {t} frames of {(h, w)}, got {'no more' if chunk is None else chunk.shape[1:]} at frame {loaded}")
                for frame in chunk:
                    buffer[loaded] = np.pad(frame, ((0, size[1] - h), (0, size[2] - w)), mode="symmetric")
                    loaded += 1
            block = np.stack([buffer[int(f)] for f in needed])
            scale = 1.0 / 255.0 if block.dtype == np.uint8 else 1.0
            half = np.empty((keep_hi - keep_lo, size[1] // 2, size[2] // 2), np.float32)
            for y0, y1, ky0, ky1 in rows:
                for x0, x1, kx0, kx1 in cols:
                    x = torch.from_numpy(np.ascontiguousarray(block[:, y0:y1, x0:x1])).to(device).float() * scale
                    x = x[None, None].contiguous(memory_format=torch.channels_last_3d)
                    x = standardised((x - mean) / (std + STD_FLOOR)) if standardised is not None else net(x)
                    out = x[0, 0, keep_lo - lo : keep_hi - lo, (ky0 - y0) // 2 : (ky1 - y0) // 2, (kx0 - x0) // 2 : (kx1 - x0) // 2]
                    half[:, ky0 // 2 : ky1 // 2, kx0 // 2 : kx1 // 2] = out.float().cpu().numpy()
            stop = min(keep_hi, t)
            if stop > keep_lo:
                yield keep_lo, _resize(half[: stop - keep_lo], (size[1], size[2]))[:, :h, :w]
            keep = int(frame_of[spans[n + 1][0] :].min()) if n + 1 < len(spans) else t
            for f in [f for f in buffer if f < keep]:
                del buffer[f]


def field_windows(
    layout: PatchLayout,
    spans: Iterator[Tuple[int, np.ndarray]],
    chunk: int = 64,
    progress: Optional[Callable[[int, int], None]] = None,
) -> Iterator[Tuple[np.ndarray, np.ndarray]]:
    """The windows of ``layout`` cut from a depth video that arrives as
    ``spans`` (pairs (t0, depth (n, H, W)) in time order, as
    :func:`field_frames` yields them), mirrored into the layout's padding
    (numpy's "symmetric" mode, as the video is): origins (n, 3) and depths
    (n, 16, 64, 64), ``chunk`` at a time in the layout's (time-major)
    order, each as soon as the frames it covers have arrived, as
    :func:`patch_depths` yields them. Frames no window needs any more are
    dropped. ``progress(frames, total)`` after each span."""
    lt, ls, _ = PATCH
    t = layout.shape[0]
    # Padded index → video index on each axis.
    index = [np.pad(np.arange(layout.shape[a]), (layout.pad[a], layout.padded[a] - layout.shape[a] - layout.pad[a]), mode="symmetric") for a in range(3)]
    starts = sorted(set(int(o) for o in layout.origins[:, 0]))
    # The lowest video frame a window from each temporal origin on still needs.
    needs = {s: int(index[0][s:].min()) for s in starts}
    buffer: dict = {}
    done = 0
    for s in starts:
        frames = index[0][s : s + lt]
        while done <= frames.max():
            try:
                t0, depth = next(spans)
            except StopIteration:
                raise ValueError(f"spans: ended at frame {done} of the layout's {t}") from None
            if t0 != done or depth.shape[1:] != layout.shape[1:]:
                raise ValueError(f"spans: expected frames from {done} of {layout.shape[1:]}, got {depth.shape[1:]} from {t0}")
            # Each frame mirrored into the layout's spatial padding once, as it arrives.
            buffer.update((t0 + i, np.ascontiguousarray(d[index[1]][:, index[2]], dtype=np.float32)) for i, d in enumerate(depth))
            done = t0 + len(depth)
            if progress is not None:
                progress(min(done, t), t)
        padded = np.stack([buffer[int(f)] for f in frames])
        origins = layout.origins[layout.origins[:, 0] == s]
        for i in range(0, len(origins), chunk):
            part = origins[i : i + chunk]
            yield part, np.stack([padded[:, y : y + ls, x : x + ls] for _, y, x in part])
        keep = needs.get(s + lt // 2, t)
        for f in [f for f in buffer if f < keep]:
            del buffer[f]


def tile_plan(shape: Tuple[int, int, int], net: "torch.nn.Module", tile: Tuple[int, int, int] = TILE, margin: Tuple[int, int, int] = MARGIN) -> list:  # noqa: F821
    """The tiles :func:`field_frames` runs ``net`` on for a video of
    ``shape`` (T, H, W): ((t0, t1), (y0, y1), (x0, x1)) input ranges,
    margins included, over the video back-padded to the network's
    multiples."""
    size = _network_size(shape, net)
    spans = [_spans(size[0], tile[0], margin[0], _time_multiple(net))] + [_spans(size[a], tile[a], margin[a], 8) for a in (1, 2)]
    return [((t0, t1), (y0, y1), (x0, x1)) for t0, t1, _, _ in spans[0] for y0, y1, _, _ in spans[1] for x0, x1, _, _ in spans[2]]


def _network_size(shape: Tuple[int, int, int], net: "torch.nn.Module") -> Tuple[int, int, int]:  # noqa: F821
    """``shape`` rounded up to what ``net`` takes: rows and columns to multiples of 8, frames of :func:`_time_multiple`."""
    tm = _time_multiple(net)
    return (-(-shape[0] // tm) * tm, -(-shape[1] // 8) * 8, -(-shape[2] // 8) * 8)


ISOMETRIC_SCALE = 0.3
"""With a camera's ``focal`` length, the isometric depth's shape is kept above
this scale (a Gaussian's standard deviation, as a fraction of the frame's
shorter side) and the network's below it. Picked by a rule fixed
beforehand: of 0, 0.05, 0.1, 0.2 and 0.3, the best per frame on 64
generated sheets (docs/campaign.md); a long video of a sheet bent many ways,
like ``kinect_paper``, reads better at 0.1 (docs/reconstruction.md)."""


ISOMETRIC_DROP = DROP
"""With a camera's ``focal`` length, the share of the tracked points left
out of the isometric depth (:data:`nrdepth.isometric.DROP`)."""


def _sheet_camera(focal: Any, centre: Any, scale: float, sheet: Any, frame: Tuple[int, int], roi: Any, units: str, temporal: bool,
                  template: str = "joint", drop: float = ISOMETRIC_DROP) -> Optional[dict]:
    """``focal`` (pixels: one number or (f_x, f_y)), ``centre`` (the
    principal point; default the frame's centre) and ``sheet`` (where the
    points go in the first frame: bool (H, W), or a box (x, y, w, h);
    default the ``roi``, or the whole frame), all in the video's frame
    ``frame`` (H, W), with the isometric depth's ``template`` and ``drop``,
    checked; None without ``focal``."""
    if focal is None:
        if centre is not None or sheet is not None or template != "joint" or drop != ISOMETRIC_DROP:
            raise ValueError("focal: centre, sheet, isometric_template and isometric_drop shape the isometric depth; they need the camera's focal length")
        return None
    from .isometric import TEMPLATES, _camera, _cv2

    _cv2()  # the optional dependencies, before any work
    H, W = frame
    focal, centre = _camera(focal, ((W - 1) / 2, (H - 1) / 2) if centre is None else centre)
    if not (np.isfinite(scale) and scale >= 0):
        raise ValueError(f"isometric_scale: expected a fraction of the frame's shorter side >= 0, got {scale!r}")
    if units != "standard" or temporal:
        raise ValueError("focal: the isometric shape comes with units='standard' and temporal off only")
    if template not in TEMPLATES:
        raise ValueError(f"isometric_template: expected one of {TEMPLATES}, got {template!r}")
    if not (isinstance(drop, (int, float, np.floating)) and 0 <= drop < 1):
        raise ValueError(f"isometric_drop: expected a share of the points in [0, 1), got {drop!r}")
    roi = (0, 0, W, H) if roi is None else tuple(roi)
    if sheet is None or (np.ndim(sheet) == 1 and len(sheet) == 4):
        x, y, w, h = roi if sheet is None else (int(v) for v in sheet)
        if not (0 <= x and 0 <= y and w > 0 and h > 0 and x + w <= W and y + h <= H):
            raise ValueError(f"sheet: expected a box x, y, width, height inside the {W}×{H} frame, got {sheet!r}")
        points = np.zeros(frame, bool)
        points[y : y + h, x : x + w] = True
    else:
        points = np.asarray(sheet)
        if points.dtype != np.bool_ or points.shape != tuple(frame) or points.sum() < 16:
            raise ValueError(f"sheet: expected a box (x, y, w, h) or a bool array of the video's frame {tuple(frame)} with at least 16 pixels on "
                             f"the sheet, got {points.dtype} {points.shape}")
    return {"focal": focal, "centre": centre, "scale": float(scale), "sheet": points, "roi": roi, "template": template, "drop": float(drop)}


def _as_uint8(frames: np.ndarray) -> np.ndarray:
    """Gray frames as uint8 (floats in [0, 1] rounded), as the optical flow takes them."""
    return frames if frames.dtype == np.uint8 else np.rint(np.clip(frames, 0.0, 1.0) * 255).astype(np.uint8)


CHUNK = 16
"""Frames a chunk as the pipeline reads, converts and writes them."""


class _Pipeline:
    """The coarse pass, fine pass and stitch of a video of frames (H, W)
    that ``chunks()`` gives in order, in chunks, each time it is called. The
    video is read twice: for the input statistic, the frame count and the
    coarse pass's small frames (64×64), then by the fine pass, a span of
    frames at a time; at the working resolution of ``max_side``."""

    def __init__(self, frame: Tuple[int, int], chunks: Callable[[], Iterable[np.ndarray]], net: Any, device: Any, batch_size: int, fine: str,
                 alignment: str, coarse_weight: float, window: str, temporal_weight: float, max_side: Optional[int], tile: Optional[Tuple[int, int, int]],
                 mask: Optional[np.ndarray] = None) -> None:
        self.full, self.work = frame, working_shape(frame, max_side)
        # The surface's pixels (T or 1, H, W) at the video's resolution and at the working one (the majority of each working pixel's).
        self.mask = mask
        self.mask_work = None if mask is None else (mask if self.work == self.full else _resize(mask.astype(np.float32), self.work) >= 0.5)
        if self.mask_work is not None and not self.mask_work.any(axis=(1, 2)).all():
            raise ValueError(f"mask: a frame has no pixel on the surface at the working resolution {self.work} (max_side); mark more of it or raise max_side")
        self.chunks, self.net, self.device, self.batch_size, self.fine, self.tile = chunks, net, device, batch_size, fine, tile
        self.stitching = (alignment, coarse_weight, window, temporal_weight)
        statistic, small = Statistic(), []
        for chunk in self.working():
            statistic.add(chunk)
            small.append(_resize(_as_unit_float(chunk), PATCH[1:]))
        if not small:
            raise ValueError("video: holds no frames")
        self.statistic = statistic.result()
        self.half = coarse_half(np.concatenate(small), net, batch_size, device)
        self.shape = (len(self.half), *self.work)

    def working(self) -> Iterator[np.ndarray]:
        """The video's chunks at the working resolution (float32 in [0, 1] when resized)."""
        for chunk in self.chunks():
            if chunk.shape[1:] != self.full:
                raise ValueError(f"video: expected frames of {self.full}, got {chunk.shape[1:]}")
            yield chunk if self.work == self.full else _resize(_as_unit_float(chunk), self.work)

    def coarse(self, start: int, stop: int) -> np.ndarray:
        """The coarse depth of frames ``start .. stop`` at the working resolution."""
        if stop <= start:
            return np.zeros((0, *self.work), np.float32)
        coarse = _resize(self.half[start:stop], self.work)
        if self.mask_work is not None:
            # NaN off the surface: the stitcher leaves those pixels out of every alignment.
            coarse[~_frames_of(self.mask_work, start, stop)] = np.nan
        return coarse

    def stitched(self, progress: Optional[Callable[[int, int], None]] = None) -> Iterator[np.ndarray]:
        """The stitched depth at the working resolution, in chunks of frames
        in order as they are solved (the joint alignment; the paper's gives
        its video at the end)."""
        t = self.shape[0]
        layout = patch_layout(self.shape)
        alignment = self.stitching[0]
        given = 0 if alignment == "joint" else t
        stitcher = _stitcher(self.coarse(0, given), layout.patch, *self.stitching, frames=t)
        if self.fine == "field":
            frames = field_frames((self.shape, self.working()), self.net, self.device, self.tile, statistic=self.statistic)
            windows = field_windows(layout, frames, progress=progress)
        else:
            video = np.concatenate(list(self.working()))
            windows = _counted(patch_depths(video, self.net, layout, self.batch_size, self.device), layout, progress)
        for origins, depth in windows:
            if alignment == "joint":
                # The coarse depth a little ahead of the windows: a span is solved with the one after it.
                want = min(t, int(origins[:, 0].max()) - layout.pad[0] + 2 * PATCH[0])
                if want > given:
                    stitcher.push_coarse(self.coarse(given, want))
                    given = want
            stitcher.add(depth, origins)
            if alignment == "joint":
                done = stitcher.take()
                if len(done):
                    yield done
        if given < t:
            stitcher.push_coarse(self.coarse(given, t))
        rest = stitcher.finish()
        if len(rest):
            yield rest

    def finalise(self, raw: np.ndarray, temporal: bool, units: str) -> Tuple[float, float]:
        """The (offset, scale) that give the stitched depth ``raw`` (T, h, w)
        at the working resolution (an array or a memory map; written over
        with ``temporal``) :func:`reconstruct`'s units and zero mean:
        ``(full(raw) − offset) · scale``, ``full`` the resize to the video's
        resolution (:meth:`final`)."""
        t = len(raw)
        if temporal:
            raw[:] = temporal_align(np.asarray(raw))
        spans = [(a, min(a + CHUNK, t)) for a in range(0, t, CHUNK)]
        if units == "pixels":
            # The coarse pass reads the relief's scale (one window the frame); the
            # patches' fits shrink it (least squares regresses toward the fit's
            # target, and the joint alignment's agreement term falls with the
            # scale squared), so the stitched relief takes the coarse pass's.
            scale = _relief_scale((raw[a:b] for a, b in spans), (self.coarse(a, b) for a, b in spans))
            mean = sum(float(raw[a:b].sum(dtype=np.float64)) for a, b in spans) / raw.size
            h, w = self.work
            # Pixels of the video, not of the working frame.
            return mean, scale * math.sqrt(h * w) * self.full[1] / w
        # A network without a depth scale (GBR-invariant losses only): a
        # canonical one rather than whatever magnitude its weights drifted to.
        pivot = float(np.nanmean(raw[0:1], dtype=np.float64))  # sums about a value near the mean: no cancellation
        total = squares = n = 0.0
        for a, b in spans:
            frames = self._full(raw[a:b], a).astype(np.float64) - pivot
            on = np.isfinite(frames)
            total, squares, n = total + float(frames[on].sum()), squares + float(np.square(frames[on]).sum()), n + int(on.sum())
        mean = total / n
        return pivot + mean, 1.0 / (math.sqrt(max(squares / n - mean * mean, 0.0)) or 1.0)

    def isometric(self, raw: np.ndarray, camera: dict, video: np.ndarray) -> np.ndarray:
        """The stitched depth ``raw`` (T, h, w) at the working resolution with
        its shape above ``camera``'s scale from the sheet's inextensibility:
        points over ``camera["sheet"]`` followed through ``video`` (T, H, W),
        the selected frames whole (not cut to the region: the points near
        its edge stay in view), their depths with the camera's intrinsics,
        spread over the region's working frame (:mod:`nrdepth.isometric`;
        ``camera``'s ``drop`` and ``template``)."""
        from .isometric import fuse, mdh_depths, track_grid
        from .tracks import densify

        xy = track_grid(_as_uint8(video), camera["sheet"], drop=camera["drop"])
        depths = mdh_depths(xy, camera["focal"], camera["centre"], template=camera["template"])
        x, y, w_region, h_region = camera["roi"]
        (h, w) = self.work
        # Into the region's working frame: area-averaged resizes keep pixel centres' relative places.
        working = (xy - np.array([x, y]) + 0.5) * np.array([w / w_region, h / h_region]) - 0.5
        on = np.isfinite(raw)
        fused = fuse(np.where(on, raw, 0.0), densify(working, depths, raw.shape), camera["scale"] * min(h, w), mask=on)
        return np.where(on, fused, np.nan).astype(np.float32)

    def final(self, raw: np.ndarray, start: int, stop: int, offset: float, scale: float) -> np.ndarray:
        """Frames ``start .. stop`` of the final depth, float32 at the video's resolution (:meth:`finalise`)."""
        return ((self._full(raw[start:stop], start).astype(np.float64) - offset) * scale).astype(np.float32)

    def _full(self, frames: np.ndarray, start: int) -> np.ndarray:
        """Working frames from ``start`` at the video's resolution; NaN off the mask."""
        if self.work == self.full:
            return np.asarray(frames, np.float32)
        if self.mask is None:
            return _resize(frames, self.full)
        # Each pixel off the working mask takes its nearest on it, so the resize blends only the surface.
        from scipy.ndimage import distance_transform_edt

        filled = np.array(frames, np.float32)
        for frame in filled:
            off = np.isnan(frame)
            if off.any() and not off.all():
                rows, cols = distance_transform_edt(off, return_distances=False, return_indices=True)
                frame[:] = frame[rows, cols]
        full = _resize(filled, self.full)
        full[~_frames_of(self.mask, start, start + len(frames))] = np.nan
        return full


def _frames_of(mask: np.ndarray, start: int, stop: int) -> np.ndarray:
    """Frames ``start .. stop`` of a mask (T, H, W), or its one frame repeated."""
    return np.broadcast_to(mask, (stop - start, *mask.shape[1:])) if len(mask) == 1 else mask[start:stop]


def _check_mask(mask: Any, video_shape: Tuple[int, ...], frames: Optional[slice], roi: Any, alignment: str, temporal: bool, units: str) -> Optional[np.ndarray]:
    """``mask`` (bool (H, W) or (T, H, W) of the video as given) cut as the video is, (1 or T', h, w); None stays None."""
    if mask is None:
        return None
    mask = np.asarray(mask)
    if mask.dtype != bool:
        raise TypeError(f"mask: expected a bool array (True on the surface), got dtype {mask.dtype}")
    t, h, w = video_shape[:3]
    if mask.shape not in ((h, w), (t, h, w)):
        raise ValueError(f"mask: expected ({h}, {w}) or ({t}, {h}, {w}), the video's frames, got {mask.shape}")
    if alignment != "joint":
        raise ValueError("mask: the paper's alignment fits every pixel of a patch, padding included; use alignment='joint'")
    if temporal or units != "standard":
        raise ValueError("mask: works with temporal=False and units='standard'")
    mask = select(mask[None] if mask.ndim == 2 else mask, None if mask.ndim == 2 else frames, roi)
    if not mask.any(axis=(1, 2)).all():
        raise ValueError("mask: a frame has no pixel on the surface")
    return mask


def _file_mask(mask: Any, source: Any, frames: Optional[slice], roi: Any, alignment: str, temporal: bool, units: str) -> Optional[np.ndarray]:
    """:func:`reconstruct_file`'s ``mask`` (an array, or a file of one frame or
    of the input's frames) cut as the input ``source`` is, (1 or T', h, w)."""
    from .videoio import open_video

    if mask is None or not isinstance(mask, (str, os.PathLike)):
        t = source.count_all() if np.ndim(mask) == 3 else 0  # a video file is decoded to count its frames only for a mask of each
        return _check_mask(mask, (t, *source.raw_size), frames, roi, alignment, temporal, units)
    whole = open_video(mask, "mask")
    if whole.raw_size != source.raw_size:
        raise ValueError(f"mask: expected frames of the input's size {source.raw_size}, got {whole.raw_size} in {mask}")
    if whole.count_all() == 1:
        return _check_mask(next(whole.chunks(1))[0] >= 128, (0, *source.raw_size), None, roi, alignment, temporal, units)
    if whole.count_all() != source.count_all():
        raise ValueError(f"mask: expected one image or the input's {source.count_all()} frames, got {whole.count_all()} in {mask}")
    cut = np.concatenate([chunk >= 128 for chunk in open_video(mask, "mask", frames, roi).chunks(CHUNK)])
    return _check_mask(cut, cut.shape, None, None, alignment, temporal, units)


def _load_net(model: Any, units: str, dev: Any) -> Any:
    """The network of ``model`` (a module, a path, or None: the shipped one, the scaled one for pixel units) on ``dev``."""
    import torch

    if model is not None and not isinstance(model, (str, os.PathLike, torch.nn.Module)):
        raise TypeError(f"model: expected None, a path to model.safetensors or its folder, or a torch.nn.Module, got {type(model).__name__}")
    if model is None and units == "pixels":
        from .model.io import SCALED_MODEL

        model = SCALED_MODEL
    if isinstance(model, torch.nn.Module):
        net = model
        for each in _networks(net):
            each.to(dev).eval()
    else:
        net = inference_model(model, dev)
    if units == "pixels" and getattr(net, "depth_units", None) != "window":
        raise ValueError("units: 'pixels' needs a model that learnt the relief's scale (model.json's depth_units 'window', "
                         "nrdepth train --amplitude); this one gives depth up to scale: use units='standard'")
    return net


def _check_options(batch_size: Any, progress: Any, units: str, fine: str, max_side: Any, tile: Any,
                   alignment: str, coarse_weight: float, window: str, temporal_weight: float) -> None:
    if isinstance(batch_size, bool) or not isinstance(batch_size, (int, np.integer)) or batch_size < 1:
        raise ValueError(f"batch_size: expected a positive integer, got {batch_size!r}")
    if progress is not None and not callable(progress):
        raise TypeError(f"progress: expected a callable progress(done, total) or None, got {type(progress).__name__}")
    if units not in ("standard", "pixels"):
        raise ValueError(f"units: expected 'standard' or 'pixels', got {units!r}")
    if fine not in FINE_PASSES:
        raise ValueError(f"fine: expected one of {FINE_PASSES}, got {fine!r}")
    if max_side is not None and (isinstance(max_side, bool) or not isinstance(max_side, (int, np.integer)) or max_side < 8):
        raise ValueError(f"max_side: expected None or an integer ≥ 8, got {max_side!r}")
    if tile is not None:
        _check_sizes("tile", tile)
    _check_stitching(alignment, coarse_weight, window, temporal_weight)


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
    fine: str = "field",
    max_side: Optional[int] = MAX_SIDE,
    tile: Optional[Tuple[int, int, int]] = None,
    mask: Optional[np.ndarray] = None,
    focal: Union[None, float, Tuple[float, float]] = None,
    centre: Optional[Tuple[float, float]] = None,
    sheet: Union[None, np.ndarray, Tuple[int, int, int, int]] = None,
    isometric_scale: float = ISOMETRIC_SCALE,
    isometric_template: str = "joint",
    isometric_drop: float = ISOMETRIC_DROP,
) -> np.ndarray:
    """Depth video float32 (T, H, W) of a video (T, H, W) or colour video
    (T, H, W, 3) (uint8, or float in [0, 1]; colour becomes luma, ITU-R
    BT.601, as ``nrdepth reconstruct`` does) with a trained model: a module, a
    ``model.safetensors`` path or run folder, or ``None`` for the default
    model shipped in the package (whose coarse pass also reads its coarse
    companion, :func:`coarse_half`).

    - ``frames`` (a slice) and ``roi`` (x, y, width, height in pixels)
      select the part of the video to reconstruct.
    - ``max_side``: reconstruct at a working resolution whose longer side is
      at most this many pixels (area-averaged down, depth bilinearly back
      up to the selected frames' size; :data:`MAX_SIDE` by default);
      ``None`` works at the video's own. The network reads relief at the
      scale of its 64-pixel patches, so a working resolution is a choice of
      which relief it sees: an object that fills a frame of a few hundred
      pixels suits it (docs/reconstruction.md measures both real videos).
    - ``fine``: ``"field"`` (one network pass over the video in tiles of
      core ``tile``) or ``"patches"`` (every window on its own, 8× the
      work; module docstring).
    - ``progress(done, total)`` is called as frames of the fine pass are
      done.
    - ``temporal`` applies :func:`~nrdepth.stitch.temporal_align` to the
      stitched video: it gives every frame frame 0's plane and relief norm,
      which helps a model that predicts neither (one trained with per-frame
      losses) and hurts one that predicts the plane's motion, as the
      shipped model does (off by default, as in the paper).
    - ``alignment``: ``"joint"`` with ``coarse_weight`` and
      ``temporal_weight`` (the default) or ``"coarse"`` (the paper's);
      ``window``: ``"hann"`` (the default) or ``"triangle"`` (the paper's;
      :mod:`nrdepth.stitch`).
    - ``mask``: bool (H, W) or (T, H, W) of the video as given, True on
      the surface. Pixels off it take no part in the alignments and come
      back NaN (the joint alignment, ``units="standard"``, ``temporal``
      off). The network still reads them. Use it where the background
      moves on its own (hands, other objects). A still background helps
      the alignment: on ``phisft_R1``'s black matte, masking costs 0.007 to
      0.017 per frame (docs/stitching.md).
    - ``focal``: for a sheet (paper, cloth) filmed by a perspective camera
      of this focal length in pixels (one number or (f_x, f_y); ``centre``:
      the principal point, by default the frame's centre), the depth's shape
      above ``isometric_scale`` (:data:`ISOMETRIC_SCALE`) comes from
      inextensibility (:mod:`nrdepth.isometric`: points followed by optical
      flow, their depths by the maximum-depth heuristic), the relief below
      it from the network. ``sheet``: where the points go in the first
      selected frame, a bool (H, W) or a box (x, y, w, h), on the sheet only
      (a point on the background breaks the sheet's constraints; default:
      ``roi``, or the whole frame). All in pixels of the video's frame,
      before ``roi``. On a long video that bends the sheet many ways it
      reads the sheet's bend and the relief's sign whatever the light; a
      short or barely bending clip reads as a dome (docs/reconstruction.md).
      ``isometric_template``: :func:`~nrdepth.isometric.mdh_depths`'s
      template distances ("joint", or "refined": each pair held to its
      distance in every keyframe); ``isometric_drop``
      (:data:`ISOMETRIC_DROP`): the share of the points left out where the
      flow's two directions disagree most. For a long video (64 frames or
      more) of a sheet bent many ways, "refined" with ``isometric_drop=0.3``
      and ``isometric_scale=0.2`` reads both real videos best and costs
      short clips (docs/reconstruction.md). The selected frames are held
      whole; minutes for a few hundred frames.

    Depth is defined up to one GBR per frame (one for the video with
    ``temporal``) and returned with zero mean over the video, in ``units``:
    ``"standard"`` (unit standard deviation over the video) or ``"pixels"``
    (depth in pixels of the video, the relief's scale as the model reads
    it: only for a model trained with a relief-amplitude term, whose
    ``depth_units`` is ``"window"``; without ``model``, the shipped one that
    learnt it, :data:`nrdepth.model.SCALED_MODEL`. The coarse pass sees the
    whole frame as one window, so a window width is √(H·W) pixels, and the
    stitched relief is given the coarse pass's scale by one least-squares
    factor over the video). Its overall sign (convex or concave) follows
    the training data's light-from-above prior (lights within ±70° of
    image-up, row 0 being the top): under an orthographic camera a surface
    and its mirror image under mirrored lights make the same video, so a
    video lit from below reads inverted, and ``-depth`` is the other
    reading. To stream a long video from a file to a folder, see
    :func:`reconstruct_file`."""
    from .model.io import resolve_device

    gray = to_gray(video, "video")
    mask = _check_mask(mask, gray.shape, frames, roi, alignment, temporal, units)
    camera = _sheet_camera(focal, centre, isometric_scale, sheet, gray.shape[1:3], roi, units, temporal, isometric_template, isometric_drop)
    video = select(gray, frames, roi)
    _check_options(batch_size, progress, units, fine, max_side, tile, alignment, coarse_weight, window, temporal_weight)
    dev = resolve_device(device)
    net = _load_net(model, units, dev)
    chunks = lambda: (video[a : a + CHUNK] for a in range(0, len(video), CHUNK))  # noqa: E731
    pipeline = _Pipeline(video.shape[1:], chunks, net, dev, int(batch_size), fine, alignment, coarse_weight, window, temporal_weight, max_side, tile, mask)
    raw = np.concatenate(list(pipeline.stitched(progress)))
    if camera is not None:
        raw = pipeline.isometric(raw, camera, select(gray, frames, None))
    return pipeline.final(raw, 0, len(raw), *pipeline.finalise(raw, temporal, units))


def reconstruct_file(
    input: Union[str, "os.PathLike[str]"],
    out: Union[str, "os.PathLike[str]"],
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
    fine: str = "field",
    max_side: Optional[int] = MAX_SIDE,
    tile: Optional[Tuple[int, int, int]] = None,
    flip: bool = False,
    png16: bool = False,
    ply: bool = False,
    ply_relief: Optional[float] = None,
    overwrite: bool = False,
    viewer: bool = True,
    mask: Union[None, np.ndarray, str, "os.PathLike[str]"] = None,
    focal: Union[None, float, Tuple[float, float]] = None,
    centre: Optional[Tuple[float, float]] = None,
    sheet: Union[None, np.ndarray, Tuple[int, int, int, int]] = None,
    isometric_scale: float = ISOMETRIC_SCALE,
    isometric_template: str = "joint",
    isometric_drop: float = ISOMETRIC_DROP,
) -> "Path":  # noqa: F821
    """:func:`reconstruct` a video file, image folder or array file
    (:class:`~nrdepth.videoio.VideoSource`) into the folder ``out``
    (:class:`~nrdepth.videoio.ReconstructionWriter`: ``depth.npz``,
    ``depth.mp4``, ``side_by_side.mp4``, with ``viewer`` the 3-D page
    ``viewer.html``, with ``png16`` and ``ply`` their frames; all or
    nothing), streaming: the video is read a few frames at a
    time (three times: statistic and coarse pass, fine pass, writing),
    the stitched depth waits on disk in the output's temporary folder at
    the working resolution, and memory does not grow with the video's
    length, except by the coarse pass's 20 kB a frame (and with
    ``temporal``, which aligns the whole video in memory, or
    ``fine="patches"``, which holds it). ``flip`` negates the depth (the
    other convex/concave reading); ``ply_relief``: the PLYs' depth scale
    (:func:`~nrdepth.videoio.write_ply`; default: the training surfaces'
    for standard units, one frame width per pixel for pixel units).
    ``mask``: as :func:`reconstruct`'s, or a file: one image (for every
    frame) or a video, image folder or array of the input's frame count,
    of the input's frame size; pixels of 128 or more (of 255) are on the
    surface. A mask of every frame is held in memory (a byte a pixel of
    the selected frames). Off it the depth is NaN: black in the videos, 0
    in the PNGs, no point in the PLYs, a hole in the viewer. With ``focal``
    the selected frames are held whole, a byte a pixel. The other
    arguments as :func:`reconstruct`. Returns ``out``."""
    from .model.io import resolve_device
    from .videoio import PLY_RELIEF, ReconstructionWriter, check_output_folder, open_video

    _check_options(batch_size, progress, units, fine, max_side, tile, alignment, coarse_weight, window, temporal_weight)
    dev = resolve_device(device)
    net = _load_net(model, units, dev)
    out = check_output_folder(out, overwrite, inputs=(input,))
    source = open_video(input, "input", frames, roi)
    mask = _file_mask(mask, source, frames, roi, alignment, temporal, units)
    camera = _sheet_camera(focal, centre, isometric_scale, sheet, source.raw_size, roi, units, temporal, isometric_template, isometric_drop)
    pipeline = _Pipeline(source.frame_size, lambda: source.chunks(CHUNK), net, dev, int(batch_size), fine, alignment, coarse_weight, window, temporal_weight, max_side, tile, mask)
    t = pipeline.shape[0]
    if ply_relief is None:
        ply_relief = 1.0 / source.frame_size[1] if units == "pixels" else PLY_RELIEF  # pixels to frame widths, the PLY's x and y unit
    with ReconstructionWriter(out, (t, *source.frame_size), source.fps, png16=png16, ply=ply, ply_relief=ply_relief, overwrite=overwrite, viewer=viewer) as writer:
        raw = _DiskFrames(writer.scratch("stitched.f32"), pipeline.shape[1:])
        for chunk in pipeline.stitched(progress):
            raw.append(chunk)
        if camera is not None:
            whole = np.concatenate(list(open_video(input, "input", frames, None).chunks(CHUNK)))
            raw[:] = pipeline.isometric(raw[:], camera, whole)
        offset, scale = pipeline.finalise(raw, temporal, units)
        scale = -scale if flip else scale
        # The ranges from the working resolution (bilinear resizing makes no new extremes), a chunk at a time.
        stride = max(1, int(math.sqrt(raw.size / 4e6)))
        sample = np.concatenate([raw[a : a + CHUNK][:, ::stride, ::stride].ravel() for a in range(0, t, CHUNK)])
        lo, hi = np.nanpercentile((sample.astype(np.float64) - offset) * scale, [1.0, 99.0])  # NaN: off the mask
        ends = sorted(((min(float(np.nanmin(raw[a : a + CHUNK])) for a in range(0, t, CHUNK)) - offset) * scale,
                       (max(float(np.nanmax(raw[a : a + CHUNK])) for a in range(0, t, CHUNK)) - offset) * scale))
        writer.set_ranges((float(lo), float(max(hi, lo + 1e-12))), (ends[0], ends[1]))
        # A few frames a write at large sizes: the colour and side-by-side frames take 9 bytes a pixel.
        step = max(1, min(CHUNK, 4_000_000 // (source.frame_size[0] * source.frame_size[1])))
        for start, frames_in in zip(range(0, t, step), source.chunks(step)):
            writer.write(frames_in, pipeline.final(raw, start, start + len(frames_in), offset, scale))
        raw.remove()
    return out


class _DiskFrames:
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
        if frames != slice(None):
            raise ValueError("frames: only the whole video can be rewritten")
        self.file.seek(0)
        self.file.truncate()
        self.count = 0
        self.append(values)

    def __array__(self, dtype: Any = None, copy: Any = None) -> np.ndarray:
        whole = self[:]
        return whole if dtype is None else whole.astype(dtype)

    def remove(self) -> None:
        self.file.close()
        os.unlink(self.path)


def _counted(windows: Iterator[Tuple[np.ndarray, np.ndarray]], layout: PatchLayout, progress: Optional[Callable[[int, int], None]]) -> Iterator[Tuple[np.ndarray, np.ndarray]]:
    """``windows`` of :func:`patch_depths`, calling ``progress(frames,
    total)`` with the frames whose patches have all been read."""
    t = layout.shape[0]
    for origins, depth in windows:
        yield origins, depth
        if progress is not None:
            # Time-major: every window starting before the last one's origin is in.
            progress(int(min(t, max(0, origins[-1, 0] - layout.pad[0]))), t)
    if progress is not None:
        progress(t, t)


def _relief_scale(depth: Iterable[np.ndarray], reference: Iterable[np.ndarray]) -> float:
    """Least-squares s with s·r(depth) ≈ r(reference) over a video (T, H,
    W), given whole or as chunks of frames of both, r being each frame minus
    its least-squares plane; 1 if ``depth`` has no relief (planar frames, up
    to rounding)."""
    if isinstance(depth, np.ndarray):
        depth, reference = [depth], [reference]
    num = den = total = 0.0
    basis = None
    for chunk, ref_chunk in zip(depth, reference):
        if basis is None:
            h, w = chunk.shape[1:]
            y, x = np.mgrid[0:h, 0:w]
            basis, _ = np.linalg.qr(np.stack([x.ravel(), y.ravel(), np.ones(h * w)], axis=1))
        for frame, ref in zip(chunk, ref_chunk):
            f = frame.ravel().astype(np.float64)
            total += float(f @ f)
            f -= basis @ (basis.T @ f)
            num += float(f @ ref.ravel())  # the plane of ``ref`` is orthogonal to the residual ``f``
            den += float(f @ f)
    return num / den if den > 1e-12 * total else 1.0
