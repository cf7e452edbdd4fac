"""Reading videos in and writing depth videos out.

Input: a video file (anything FFmpeg decodes: mp4, avi, mov, gif, …), a folder
of images (PNG, JPEG, BMP, TIFF; frames in name order) or a NumPy ``.npy`` /
``.npz`` array (T, H, W) or (T, H, W, 3), uint8 or float in [0, 1]. Colour is
turned into luma (ITU-R BT.601, FFmpeg's ``gray``). Decoding and H.264
encoding go through PyAV (FFmpeg's libraries; its wheels carry libx264).

Output writers take the float32 depth (T, H, W) of :func:`nrdepth.reconstruct`:
16-bit PNG frames, a colourised MP4 with one colour range for the whole video
(no flicker; H.264, yuv420p, ``faststart``: plays in a browser), a side-by-side
input | depth MP4 and binary PLY point clouds.
"""

from __future__ import annotations

import os
from fractions import Fraction
from pathlib import Path
from typing import NamedTuple, Optional, Tuple, Union

import numpy as np

from . import _core
from .preview import colormap

__all__ = [
    "Video",
    "read_video",
    "depth_range",
    "colorize_depth",
    "write_mp4",
    "write_depth_png16",
    "write_ply",
    "save_reconstruction",
    "IMAGE_SUFFIXES",
]

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")
PathLike = Union[str, os.PathLike]

PLY_RELIEF = 0.073
"""Default depth standard deviation of a PLY, in frame widths: the training
surfaces' median ratio of depth std to view-window width (0.073 over 64 clips,
quartiles 0.058 … 0.100; ``generate_clips(64, seed=3)``)."""


class Video(NamedTuple):
    frames: np.ndarray
    """uint8 (T, H, W) grayscale frames."""
    fps: float
    """Frame rate (25 where the source has none: image folders, arrays)."""


def _to_gray_u8(array: np.ndarray, name: str) -> np.ndarray:
    a = np.asarray(array)
    if a.ndim == 4 and a.shape[-1] in (3, 4):
        if a.dtype.kind == "f":
            a = np.clip(a, 0.0, 1.0) * 255.0
        a = a[..., :3].astype(np.float32) @ np.array([0.299, 0.587, 0.114], np.float32)
        a = np.rint(a).astype(np.uint8)
    if a.ndim != 3 or min(a.shape) < 1:
        raise ValueError(f"{name}: expected a video (T, H, W) or (T, H, W, 3), got shape {a.shape}")
    if a.dtype == np.uint8:
        return a
    if a.dtype.kind == "f":
        if not np.isfinite(a).all():
            raise ValueError(f"{name}: expected finite values")
        return np.rint(np.clip(a, 0.0, 1.0) * 255.0).astype(np.uint8)
    raise TypeError(f"{name}: expected uint8 or float frames, got dtype {a.dtype}")


def _decode(path: Path, name: str) -> Tuple[list, float]:
    """Every frame of a media file as uint8 gray arrays, and its frame rate."""
    import av

    try:
        with av.open(str(path)) as container:
            if not container.streams.video:
                raise ValueError(f"{name}: {path} holds no video stream")
            stream = container.streams.video[0]
            frames = [f.to_ndarray(format="gray") for f in container.decode(stream)]
            fps = float(stream.average_rate) if stream.average_rate else 25.0
    except av.error.FFmpegError as e:
        raise ValueError(f"{name}: cannot decode {path}: {e}") from None
    if not frames:
        raise ValueError(f"{name}: {path} holds no frames")
    return frames, fps


def read_video(path: PathLike, name: str = "input") -> Video:
    """Read a video file, an image folder or a .npy/.npz array as uint8 gray
    frames (T, H, W). Errors name ``name`` and say what was expected."""
    path = Path(path)
    if not path.exists():
        raise ValueError(f"{name}: {path} does not exist")
    if path.is_dir():
        images = sorted(p for p in path.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES)
        if not images:
            raise ValueError(f"{name}: folder {path} holds no images ({', '.join(IMAGE_SUFFIXES)})")
        frames = [_decode(p, name)[0][0] for p in images]
        shapes = {f.shape for f in frames}
        if len(shapes) != 1:
            raise ValueError(f"{name}: images in {path} differ in size: {sorted(shapes)}")
        return Video(np.stack(frames), 25.0)
    if path.suffix.lower() in (".npy", ".npz"):
        try:
            data = np.load(path, allow_pickle=False)
        except (OSError, ValueError, EOFError) as e:
            raise ValueError(f"{name}: cannot read {path}: {e}") from None
        if isinstance(data, np.lib.npyio.NpzFile):
            with data:
                keys = list(data.keys())
                key = "video" if "video" in keys else (keys[0] if len(keys) == 1 else None)
                if key is None:
                    raise ValueError(f"{name}: {path} should hold one array or one named 'video', found {keys}")
                data = data[key]
        return Video(_to_gray_u8(data, name), 25.0)
    frames, fps = _decode(path, name)
    shapes = {f.shape for f in frames}
    if len(shapes) != 1:
        raise ValueError(f"{name}: frames of {path} differ in size: {sorted(shapes)}")
    return Video(np.stack(frames), fps)


def depth_range(depth: np.ndarray) -> Tuple[float, float]:
    """One colour range for a whole depth video: its 1st and 99th percentiles
    (robust to a few outliers, and the same for every frame, so no flicker)."""
    lo, hi = np.percentile(depth, [1.0, 99.0])
    return float(lo), float(max(hi, lo + 1e-12))


def colorize_depth(depth: np.ndarray, value_range: Optional[Tuple[float, float]] = None) -> np.ndarray:
    """uint8 RGB (T, H, W, 3): near (small depth) yellow, far blue, over one range."""
    lo, hi = depth_range(depth) if value_range is None else value_range
    return np.rint(colormap((hi - depth) / (hi - lo)) * 255.0).astype(np.uint8)


def write_mp4(path: PathLike, frames: np.ndarray, fps: float = 25.0, crf: int = 18) -> None:
    """Write uint8 RGB frames (T, H, W, 3) as H.264 (yuv420p, padded to even
    sides by repeating the last row/column) in an MP4 that starts playing
    before it is fully downloaded."""
    import av

    frames = np.asarray(frames)
    if frames.dtype != np.uint8 or frames.ndim != 4 or frames.shape[-1] != 3 or frames.shape[0] < 1:
        raise ValueError(f"frames: expected uint8 (T, H, W, 3), got {frames.dtype} {frames.shape}")
    _, h, w, _ = frames.shape
    frames = np.pad(frames, ((0, 0), (0, h % 2), (0, w % 2), (0, 0)), mode="edge")
    with av.open(str(path), "w", format="mp4", options={"movflags": "faststart"}) as container:
        rate = Fraction(fps).limit_denominator(1001) if fps > 0 else Fraction(25)  # 29.97 stays 30000/1001
        stream = container.add_stream("libx264", rate=rate, options={"crf": str(crf)})
        stream.width, stream.height, stream.pix_fmt = frames.shape[2], frames.shape[1], "yuv420p"
        for frame in frames:
            container.mux(stream.encode(av.VideoFrame.from_ndarray(np.ascontiguousarray(frame), format="rgb24")))
        container.mux(stream.encode(None))


def write_depth_png16(folder: PathLike, depth: np.ndarray, value_range: Optional[Tuple[float, float]] = None) -> Tuple[float, float]:
    """One 16-bit PNG per frame (``depth_0000.png`` …): 0 … 65535 spans
    ``value_range`` (default: the whole video's min and max), the same for
    every frame. Returns the range, so depth = lo + v / 65535 · (hi − lo)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    lo, hi = (float(depth.min()), float(depth.max())) if value_range is None else value_range
    scale = 65535.0 / max(hi - lo, 1e-12)
    for t, frame in enumerate(depth):
        values = np.rint(np.clip((frame - lo) * scale, 0.0, 65535.0)).astype(np.uint16)
        _core.write_png16(os.fspath(folder / f"depth_{t:04d}.png"), values)
    return lo, hi


def write_ply(path: PathLike, depth: np.ndarray, gray: np.ndarray, relief: float = PLY_RELIEF) -> None:
    """A binary PLY point cloud of one depth frame (H, W): a point per pixel at
    x = (col + ½)/W, y = −(row + ½)/W (the frame is one unit wide) and
    z = −relief · depth, coloured by the input frame ``gray`` (H, W) uint8.
    Orthographic, like the training data. With the standardised depth of
    :func:`nrdepth.reconstruct`, ``relief`` is the depth's standard deviation
    in frame widths (the network fixes no scale; choose what looks right)."""
    h, w = depth.shape
    rows, cols = np.mgrid[0:h, 0:w]
    vertex = np.empty(h * w, dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("red", "u1"), ("green", "u1"), ("blue", "u1")])
    vertex["x"] = ((cols + 0.5) / w).ravel()
    vertex["y"] = (-(rows + 0.5) / w).ravel()
    vertex["z"] = (-relief * depth).ravel()
    for channel in ("red", "green", "blue"):
        vertex[channel] = gray.ravel()
    header = (
        "ply\nformat binary_little_endian 1.0\ncomment nrdepth depth frame, orthographic\n"
        f"element vertex {h * w}\nproperty float x\nproperty float y\nproperty float z\n"
        "property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n"
    )
    with open(path, "wb") as f:
        f.write(header.encode("ascii"))
        f.write(vertex.tobytes())


def save_reconstruction(
    out: PathLike,
    frames: np.ndarray,
    depth: np.ndarray,
    fps: float = 25.0,
    png16: bool = False,
    ply: bool = False,
    ply_relief: float = PLY_RELIEF,
    overwrite: bool = False,
) -> Path:
    """Write a reconstruction into the folder ``out``, all or nothing:
    ``depth.npz`` (float32 ``depth`` (T, H, W), the ``range`` of the colour
    map, and with ``png16`` the ``png16_range`` its PNGs span),
    ``depth.mp4`` (colourised), ``side_by_side.mp4`` (input | depth), and
    optionally ``png16/depth_NNNN.png`` and ``ply/frame_NNNN.ply``. Everything
    is written into a temporary folder beside ``out`` and renamed at the end,
    so an error or an interrupt leaves no partial output. ``ply_relief``: see
    :func:`write_ply`."""
    import shutil

    out = Path(out)
    frames, depth = np.asarray(frames), np.asarray(depth, dtype=np.float32)
    if frames.dtype != np.uint8 or frames.ndim != 3 or depth.shape != frames.shape:
        raise ValueError(f"depth: expected float (T, H, W) matching uint8 frames {frames.shape}, got {depth.shape}")
    if out.exists() and not overwrite and (out.is_file() or any(out.iterdir())):
        raise ValueError(f"out: {out} exists and is not empty (pass overwrite=True / --overwrite)")
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.parent / f".{out.name}.partial-{os.getpid()}"
    shutil.rmtree(tmp, ignore_errors=True)  # left by a killed run of this pid
    tmp.mkdir()
    try:
        value_range = depth_range(depth)
        colour = colorize_depth(depth, value_range)
        extra = {"png16_range": np.array(write_depth_png16(tmp / "png16", depth), np.float32)} if png16 else {}
        np.savez_compressed(tmp / "depth.npz", depth=depth, range=np.array(value_range, np.float32), **extra)
        write_mp4(tmp / "depth.mp4", colour, fps)
        write_mp4(tmp / "side_by_side.mp4", np.concatenate([np.repeat(frames[..., None], 3, axis=-1), colour], axis=2), fps)
        if ply:
            (tmp / "ply").mkdir()
            for t in range(len(depth)):
                write_ply(tmp / "ply" / f"frame_{t:04d}.ply", depth[t], frames[t], ply_relief)
        if out.exists():
            shutil.rmtree(out) if out.is_dir() else out.unlink()
        os.replace(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return out
