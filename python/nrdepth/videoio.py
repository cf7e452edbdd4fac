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

import math
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
    "check_output_folder",
    "to_gray",
    "select",
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


LUMA = np.array([0.299, 0.587, 0.114], np.float32)
"""ITU-R BT.601 luma weights (FFmpeg's ``gray``)."""


def to_gray(video: np.ndarray, name: str = "video") -> np.ndarray:
    """A video (T, H, W) or colour video (T, H, W, 3 or 4) as gray frames
    (T, H, W): uint8 stays uint8 (colour → luma, rounded), floats become
    float32 and must lie in [0, 1] (never clipped silently: 0..255 data must be
    divided by 255 first)."""
    a = np.asarray(video)
    if a.dtype != np.uint8 and a.dtype.kind != "f":
        raise TypeError(f"{name}: expected uint8 or float frames, got dtype {a.dtype}")
    if a.dtype.kind == "f":
        if not np.isfinite(a).all():
            raise ValueError(f"{name}: expected finite values (found NaN or inf)")
        if a.size and (a.min() < 0.0 or a.max() > 1.0):
            hint = "; divide 0..255 data by 255" if a.max() > 1.0 else ""
            raise ValueError(f"{name}: expected float frames in [0, 1], got values in [{a.min():.4g}, {a.max():.4g}]{hint}")
    if a.ndim == 4 and a.shape[-1] in (3, 4):
        luma = a[..., :3].astype(np.float32) @ LUMA
        a = np.rint(luma).astype(np.uint8) if a.dtype == np.uint8 else luma
    if a.ndim != 3 or min(a.shape) < 1:
        raise ValueError(f"{name}: expected a video (T, H, W) or (T, H, W, 3), got shape {a.shape}")
    return a if a.dtype == np.uint8 else a.astype(np.float32, copy=False)


def _to_gray_u8(array: np.ndarray, name: str) -> np.ndarray:
    a = to_gray(array, name)
    return a if a.dtype == np.uint8 else np.rint(a * 255.0).astype(np.uint8)


def select(video: np.ndarray, frames: Optional[slice] = None, roi: Optional[Tuple[int, int, int, int]] = None) -> np.ndarray:
    """The frames (a slice with a positive step) and region (x, y, width,
    height in pixels, inside the frame) of a video (T, H, W) to work on."""
    if frames is not None:
        if not isinstance(frames, slice):
            raise TypeError(f"frames: expected a slice, got {type(frames).__name__}")
        if frames.step is not None and frames.step <= 0:
            raise ValueError(f"frames: expected a positive step, got {frames.step}")
        count = len(video)
        video = video[frames]
        if len(video) == 0:
            raise ValueError(f"frames: selects no frame of the video's {count}")
    if roi is not None:
        try:
            x, y, w, h = (int(v) for v in roi if not isinstance(v, bool) and float(v) == int(v))
        except (TypeError, ValueError):
            raise ValueError(f"roi: expected four integers (x, y, width, height), got {roi!r}") from None
        height, width = video.shape[1:3]
        if w < 1 or h < 1 or x < 0 or y < 0 or x + w > width or y + h > height:
            raise ValueError(f"roi: expected x, y, width, height inside the {width}×{height} frame, got {x},{y},{w},{h}")
        video = video[:, y : y + h, x : x + w]
    return video


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


MARKER = ".nrdepth-reconstruction"
"""Written into every output folder: ``overwrite`` replaces only folders that hold it."""
WRITTEN = {MARKER, "depth.npz", "depth.mp4", "side_by_side.mp4", "png16", "ply"}
"""Every name :func:`save_reconstruction` writes into its folder."""


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _clean_stale(out: Path) -> None:
    """Remove temporary folders beside ``out`` left by killed runs (dead
    PIDs); an old result moved aside by a run killed mid-swap is put back
    when nothing took its place."""
    import shutil

    if not out.parent.is_dir():
        return
    for p in out.parent.iterdir():
        for kind in ("partial", "old"):
            prefix = f".{out.name}.{kind}-"
            if p.name.startswith(prefix) and p.name[len(prefix):].isdigit() and not _pid_alive(int(p.name[len(prefix):])):
                if kind == "old" and not out.exists():
                    os.replace(p, out)
                else:
                    shutil.rmtree(p, ignore_errors=True)


def check_output_folder(out: PathLike, overwrite: bool = False, inputs: Tuple[PathLike, ...] = ()) -> Path:
    """Refuse an output folder before any work: one that exists and is not
    empty (without ``overwrite``); with ``overwrite``, one nrdepth did not
    write (no marker file) or holding files it did not write; and always the
    working folder, an ancestor of it, the home or root folder, or one that
    contains (or is) an input. Returns ``out`` as a Path."""
    out = Path(out)
    where = out.resolve()
    cwd = Path.cwd().resolve()
    if where == cwd or where in cwd.parents or where in (Path.home().resolve(), Path(where.anchor)):
        raise ValueError(f"out: refusing {out} (it is the working folder, an ancestor of it, or the home or root folder); name a new folder")
    for i in inputs:
        source = Path(i).resolve()
        if source == where or where in source.parents:
            raise ValueError(f"out: {out} contains the input {i}; name another folder")
    _clean_stale(out)
    if out.is_file():
        raise ValueError(f"out: {out} is a file; expected a folder")
    if out.exists() and any(out.iterdir()):
        if not overwrite:
            raise ValueError(f"out: {out} exists and is not empty (pass overwrite=True / --overwrite)")
        if not (out / MARKER).exists():
            raise ValueError(f"out: {out} was not written by nrdepth (no {MARKER}); --overwrite replaces only nrdepth's own output")
        foreign = sorted(p.name for p in out.iterdir() if p.name not in WRITTEN)
        if foreign:
            raise ValueError(f"out: {out} holds files nrdepth did not write ({', '.join(foreign[:3])}{', …' if len(foreign) > 3 else ''}); move them first")
    return out


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
    so an error or an interrupt leaves no partial output. With ``overwrite``
    an old result is moved aside, the new one renamed in, then the old one
    deleted: a kill at any point leaves one of the two at ``out`` (or aside,
    put back by the next run). The folder is checked by
    :func:`check_output_folder` first. ``ply_relief``: see :func:`write_ply`."""
    import shutil

    frames, depth = np.asarray(frames), np.asarray(depth, dtype=np.float32)
    if frames.dtype != np.uint8 or frames.ndim != 3 or depth.shape != frames.shape:
        raise ValueError(f"depth: expected float (T, H, W) matching uint8 frames {frames.shape}, got {depth.shape}")
    if isinstance(ply_relief, bool) or not isinstance(ply_relief, (int, float, np.floating)) or not (math.isfinite(ply_relief) and ply_relief > 0):
        raise ValueError(f"ply_relief: expected a positive finite number, got {ply_relief!r}")
    out = check_output_folder(out, overwrite)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.parent / f".{out.name}.partial-{os.getpid()}"
    shutil.rmtree(tmp, ignore_errors=True)  # left by a killed run of this pid
    tmp.mkdir()
    try:
        (tmp / MARKER).write_text("written by nrdepth reconstruct; --overwrite replaces this folder\n")
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
        aside = out.parent / f".{out.name}.old-{os.getpid()}"
        if out.exists():
            os.replace(out, aside)
        os.replace(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    shutil.rmtree(aside, ignore_errors=True)
    return out
