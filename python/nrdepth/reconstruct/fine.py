"""The fine pass: the network's depth of the video at the working
resolution, cut into the stitcher's 16×64×64 windows, at the origins of
:func:`~nrdepth.reconstruct.stitch.patch_layout`. Two ways (``fine``):

- ``"field"`` (the default): the network runs **once** over the video, in
  large tiles (:data:`TILE` frames × rows × columns) that overlap by
  :data:`MARGIN` on every side, discarded: each output voxel is computed
  once (plus the margins), not eight times. The networks are fully
  convolutional, so a tile's output away from its edges is the output of
  one pass over the whole video. Tiles end at the video's own borders,
  where the network's zero padding stands in for what lies outside, as at
  every edge of a training clip. The tiles' half-resolution depth is
  assembled into one field, upsampled once, mirrored into the layout's
  padding, and the windows are cut from it. The input is standardised
  with **one statistic for the whole video**, not per tile, so a tile's
  output does not depend on where the tile boundaries fall
  (docs/reconstruction.md measures the seams; ``tests/test_fine_pass.py``).
- ``"patches"``: every window through the network on its own,
  standardised per window (the paper's way; 8× the network work).
"""

from __future__ import annotations

from contextlib import nullcontext
from typing import Any, Callable, Iterable, Iterator, Optional, Tuple, Union

import numpy as np

from ..checks import option_error
from .frames import Statistic, resize
from .network import fine_precision
from .stitch import PATCH, PatchLayout

__all__ = ["TILE", "GPU_TILE", "MARGIN", "patch_depths", "field_frames", "field_windows", "tile_plan", "check_tile", "check_sizes", "counted"]

TILE = (32, 320, 320)
"""Default core of a tile on the CPU: frames, rows, columns (rows and
columns multiples of 8, the networks' coarsest stride). Larger tiles pay
less margin but ran slower per voxel on a 2-core CPU."""
GPU_TILE = (64, 512, 512)
"""Default core of a tile on CUDA, where larger tiles keep the device busy."""
MARGIN = (8, 64, 64)
"""Overlap of a tile on each side, discarded: frames, rows, columns. At
these margins the tiled field of ``kinect_paper`` differs from one untiled
pass by 0.06 % of its standard deviation on average
(``benchmarks/bench_video.py``)."""


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
    from ..model.io import predict_depth

    lt, ls, _ = PATCH
    back = [layout.padded[a] - layout.shape[a] - layout.pad[a] for a in range(3)]
    padded = np.pad(video, [(layout.pad[a], back[a]) for a in range(3)], mode="symmetric")  # the input's dtype
    for i in range(0, len(layout.origins), chunk):
        origins = layout.origins[i : i + chunk]
        patches = np.stack([padded[t : t + lt, y : y + ls, x : x + ls] for t, y, x in origins])  # scaled by predict_depth
        half = predict_depth(net, patches, batch_size, device)
        yield origins, resize(half.reshape(-1, *half.shape[2:]), (ls, ls)).reshape(len(half), lt, ls, ls)


def axis_spans(length: int, core: int, margin: int, align: int) -> list:
    """Tiles along one axis of ``length`` (a multiple of ``align``): cores
    of at most ``core`` (about equal, their bounds multiples of ``align``),
    each widened by ``margin`` on both sides within the axis. Tuples (lo,
    hi, keep_lo, keep_hi): compute [lo, hi), keep [keep_lo, keep_hi)."""
    count = -(-length // core)
    bounds = [min(length, -(-round(i * length / count) // align) * align) for i in range(count + 1)]
    bounds = sorted(set(bounds))
    return [(max(0, a - margin), min(length, b + margin), a, b) for a, b in zip(bounds[:-1], bounds[1:])]


def time_multiple(net: "torch.nn.Module") -> int:  # noqa: F821
    """The frame count a network's input must be a multiple of: 4 for the
    paper's U-Net (it pools time twice), 1 for the (2+1)D networks."""
    from ..model.unet import UNet3D

    return 4 if isinstance(net, UNet3D) else 1


def check_sizes(name: str, value: Any) -> Tuple[int, int, int]:
    """Three integers (frames, rows, columns), named ``name`` in the complaint."""
    try:
        t, y, x = (int(v) for v in value if not isinstance(v, bool) and int(v) == v)
    except (TypeError, ValueError):
        raise option_error(name, f"expected three integers (frames, rows, columns), got {value!r}") from None
    return t, y, x


def check_tile(tile: Any) -> Tuple[int, int, int]:
    """A tile's core: positive sizes (frames, rows, columns), rows and columns multiples of 8."""
    tile = check_sizes("tile", tile)
    if min(tile) < 1 or tile[1] % 8 or tile[2] % 8:
        raise option_error("tile", f"expected positive sizes, rows and columns multiples of 8, got {tile}")
    return tile


def field_frames(
    video: Union[np.ndarray, Tuple[Tuple[int, int, int], Iterable[np.ndarray]]],
    net: "torch.nn.Module",  # noqa: F821
    device: "torch.device",  # noqa: F821
    tile: Optional[Tuple[int, int, int]] = None,
    margin: Tuple[int, int, int] = MARGIN,
    statistic: Optional[Tuple[float, float]] = None,
    precision: str = "auto",
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
    each side, discarded (:data:`MARGIN`). ``precision``: the network's
    arithmetic (:func:`~.network.fine_precision`: by default bfloat16
    autocast where ``device`` computes it in hardware)."""
    import torch

    from ..model.unet2p1d import STD_FLOOR

    tile = (GPU_TILE if device.type == "cuda" else TILE) if tile is None else check_tile(tile)
    margin = check_sizes("margin", margin)
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
    tm = time_multiple(net)
    # The network's multiples, reached by mirroring the last frames, rows and columns; the extra is discarded.
    size = network_size(shape, net)
    frame_of = np.pad(np.arange(t), (0, size[0] - t), mode="symmetric")
    standardised = getattr(net, "forward_standardised", None)
    bfloat16 = fine_precision(precision, device) == "bfloat16"
    autocast = torch.autocast(device.type, dtype=torch.bfloat16) if bfloat16 else nullcontext()
    rows = axis_spans(size[1], tile[1], margin[1], 8)
    cols = axis_spans(size[2], tile[2], margin[2], 8)
    spans = axis_spans(size[0], tile[0], margin[0], tm)
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
                yield keep_lo, resize(half[: stop - keep_lo], (size[1], size[2]))[:, :h, :w]
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
    size = network_size(shape, net)
    spans = [axis_spans(size[0], tile[0], margin[0], time_multiple(net))] + [axis_spans(size[a], tile[a], margin[a], 8) for a in (1, 2)]
    return [((t0, t1), (y0, y1), (x0, x1)) for t0, t1, _, _ in spans[0] for y0, y1, _, _ in spans[1] for x0, x1, _, _ in spans[2]]


def network_size(shape: Tuple[int, int, int], net: "torch.nn.Module") -> Tuple[int, int, int]:  # noqa: F821
    """``shape`` rounded up to what ``net`` takes: rows and columns to multiples of 8, frames of :func:`_time_multiple`."""
    tm = time_multiple(net)
    return (-(-shape[0] // tm) * tm, -(-shape[1] // 8) * 8, -(-shape[2] // 8) * 8)


def counted(windows: Iterator[Tuple[np.ndarray, np.ndarray]], layout: PatchLayout, progress: Optional[Callable[[int, int], None]]) -> Iterator[Tuple[np.ndarray, np.ndarray]]:
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
