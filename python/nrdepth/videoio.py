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
from typing import Iterator, NamedTuple, Optional, Tuple, Union

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
    "ReconstructionWriter",
    "Mp4Writer",
    "VideoSource",
    "open_video",
    "iter_npz_frames",
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


def _decoded(path: Path, name: str) -> Iterator[np.ndarray]:
    """The frames of a media file as uint8 gray arrays, one at a time."""
    import av

    try:
        with av.open(str(path)) as container:
            if not container.streams.video:
                raise ValueError(f"{name}: {path} holds no video stream")
            for frame in container.decode(container.streams.video[0]):
                yield frame.to_ndarray(format="gray")
    except av.error.FFmpegError as e:
        raise ValueError(f"{name}: cannot decode {path}: {e}") from None


def _frame_rate(path: Path) -> float:
    import av

    try:
        with av.open(str(path)) as container:
            rate = container.streams.video[0].average_rate if container.streams.video else None
    except av.error.FFmpegError:
        return 25.0
    return float(rate) if rate else 25.0


class VideoSource:
    """A video read as a stream of uint8 gray frames (T, H, W), a chunk at a
    time and as often as needed, so that memory does not grow with its
    length: a video file (anything FFmpeg decodes, decoded frame by frame),
    a folder of images (frames in name order) or a ``.npy`` / ``.npz`` array
    (T, H, W) or (T, H, W, 3), uint8, float in [0, 1] or bool (a ``.npy`` of
    uint8 or float is memory-mapped). Colour becomes luma (ITU-R BT.601). ``frames`` (a
    slice) and ``roi`` (x, y, width, height) select as :func:`select` does.
    Errors name ``name`` and say what was expected."""

    def __init__(self, path: PathLike, name: str = "input", frames: Optional[slice] = None, roi: Optional[Tuple[int, int, int, int]] = None) -> None:
        self.path, self.name = Path(path), name
        if not self.path.exists():
            raise ValueError(f"{name}: {self.path} does not exist")
        self.array: Optional[np.ndarray] = None
        self.images: list = []
        self._count: Optional[int] = None
        if self.path.is_dir():
            self.images = sorted(p for p in self.path.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES)
            if not self.images:
                raise ValueError(f"{name}: folder {self.path} holds no images ({', '.join(IMAGE_SUFFIXES)})")
            self.fps = 25.0
        elif self.path.suffix.lower() in (".npy", ".npz"):
            self.array = _load_array(self.path, name)
            self.fps = 25.0
        else:
            self.fps = _frame_rate(self.path)
        first = next(self._raw(), None)
        if first is None:
            raise ValueError(f"{name}: {self.path} holds no frames")
        if frames is not None:
            if not isinstance(frames, slice):
                raise TypeError(f"frames: expected a slice, got {type(frames).__name__}")
            if frames.step is not None and frames.step <= 0:
                raise ValueError(f"frames: expected a positive step, got {frames.step}")
        self.selection, self.roi = frames, roi
        self.raw_size: Tuple[int, int] = first.shape  # the frames as given
        # Checks the region against the frame size.
        self.frame_size: Tuple[int, int] = select(first[None], None, roi).shape[1:]  # type: ignore[assignment]
        if frames is not None and len(self) == 0:
            raise ValueError(f"frames: selects no frame of the video's {self.count_all()}")

    def _raw(self) -> Iterator[np.ndarray]:
        if self.array is not None:
            for frame in self.array:
                yield _to_gray_u8(frame[None], self.name)[0]
            return
        size = None
        for frame in (next(_decoded(p, self.name)) for p in self.images) if self.images else _decoded(self.path, self.name):
            if size is not None and frame.shape != size:
                raise ValueError(f"{self.name}: frames of {self.path} differ in size: {frame.shape} after {size}")
            size = frame.shape
            yield frame

    def count_all(self) -> int:
        """Frames of the whole video (a video file is decoded once to count them)."""
        if self._count is None:
            self._count = len(self.array) if self.array is not None else len(self.images) if self.images else sum(1 for _ in self._raw())
        return self._count

    def __len__(self) -> int:
        """Frames selected."""
        return self.count_all() if self.selection is None else len(range(*self.selection.indices(self.count_all())))

    def chunks(self, size: int = 16) -> Iterator[np.ndarray]:
        """The selected frames, uint8 (n, H, W), ``size`` at a time, in order."""
        import itertools

        frames: Iterator[np.ndarray] = self._raw()
        if self.selection is not None:
            frames = itertools.islice(frames, *self.selection.indices(self.count_all()))
        chunk: list = []
        for frame in frames:
            chunk.append(frame)
            if len(chunk) == size:
                yield select(np.stack(chunk), None, self.roi)
                chunk = []
        if chunk:
            yield select(np.stack(chunk), None, self.roi)


def _load_array(path: Path, name: str) -> np.ndarray:
    try:
        data = np.load(path, allow_pickle=False, mmap_mode="r" if path.suffix.lower() == ".npy" else None)
    except (OSError, ValueError, EOFError) as e:
        raise ValueError(f"{name}: cannot read {path}: {e}") from None
    if isinstance(data, np.lib.npyio.NpzFile):
        with data:
            keys = list(data.keys())
            key = "video" if "video" in keys else (keys[0] if len(keys) == 1 else None)
            if key is None:
                raise ValueError(f"{name}: {path} should hold one array or one named 'video', found {keys}")
            data = data[key]
    if data.dtype == bool:
        data = data.astype(np.uint8) * np.uint8(255)  # a mask: True white
    if data.dtype != np.uint8 and data.dtype.kind != "f":
        raise TypeError(f"{name}: expected uint8, float or bool frames, got dtype {data.dtype}")
    if data.ndim not in (3, 4) or (data.ndim == 4 and data.shape[-1] not in (3, 4)) or min(data.shape) < 1:
        raise ValueError(f"{name}: expected a video (T, H, W) or (T, H, W, 3), got shape {data.shape}")
    return data


def open_video(path: PathLike, name: str = "input", frames: Optional[slice] = None, roi: Optional[Tuple[int, int, int, int]] = None) -> VideoSource:
    """A :class:`VideoSource` of ``path``."""
    return VideoSource(path, name, frames, roi)


def read_video(path: PathLike, name: str = "input") -> Video:
    """Read a video file, an image folder or a .npy/.npz array as uint8 gray
    frames (T, H, W), all in memory (:class:`VideoSource` streams them).
    Errors name ``name`` and say what was expected."""
    source = VideoSource(path, name)
    return Video(np.concatenate(list(source.chunks(64))), source.fps)


def iter_npz_frames(path: PathLike, name: str, chunk: int = 16) -> Tuple[Tuple[int, ...], Iterator[np.ndarray]]:
    """The shape of array ``name`` (T, ...) in an .npz and an iterator over
    it ``chunk`` frames at a time, read from the archive as it goes (not
    loaded whole: a 1080p depth video is GBs)."""
    import zipfile

    archive = zipfile.ZipFile(path)
    member = archive.open(f"{name}.npy")
    version = np.lib.format.read_magic(member)
    read = {(1, 0): np.lib.format.read_array_header_1_0, (2, 0): np.lib.format.read_array_header_2_0}.get(version)
    if read is None:
        raise ValueError(f"{name}: unsupported .npy version {version} in {path}")
    shape, fortran, dtype = read(member)
    if fortran:
        raise ValueError(f"{name}: expected a C-ordered array in {path}")
    per = int(np.prod(shape[1:], dtype=np.int64)) * dtype.itemsize

    def frames() -> Iterator[np.ndarray]:
        with archive, member:
            for start in range(0, shape[0], chunk):
                n = min(chunk, shape[0] - start)
                yield np.frombuffer(member.read(n * per), dtype).reshape(n, *shape[1:])

    return tuple(shape), frames()


def read_left_half(path: PathLike, size: Tuple[int, int]) -> Tuple[float, Iterator[np.ndarray]]:
    """The frame rate of a side-by-side MP4 (input | depth) and its input
    frames, uint8 gray (H, W) = ``size``, one at a time (decoded, so
    approximately the input)."""
    h, w = size
    return _frame_rate(Path(path)), (frame[:h, :w] for frame in _decoded(Path(path), "side_by_side"))


def depth_range(depth: np.ndarray) -> Tuple[float, float]:
    """One colour range for a whole depth video: its 1st and 99th percentiles
    (robust to a few outliers, and the same for every frame, so no flicker),
    NaN (off the surface) left out."""
    if not np.isfinite(depth).any():
        raise ValueError("depth: expected some finite depth, got none")
    lo, hi = np.nanpercentile(depth, [1.0, 99.0])
    return float(lo), float(max(hi, lo + 1e-12))


_COLOURS = np.rint(colormap(np.linspace(0.0, 1.0, 1024)) * 255.0).astype(np.uint8)
"""The colour ramp in 1024 uint8 steps: a lookup keeps a frame's colours in uint8 (a 1080p chunk in floats would take GBs)."""


def colorize_depth(depth: np.ndarray, value_range: Optional[Tuple[float, float]] = None) -> np.ndarray:
    """uint8 RGB (T, H, W, 3): near (small depth) yellow, far blue, over one
    range; NaN (off the surface) black."""
    lo, hi = depth_range(depth) if value_range is None else value_range
    depth = np.asarray(depth, np.float32)
    step = np.float32(1023.0 / (hi - lo))
    off = np.isnan(depth)
    masked = bool(off.any())
    index = np.clip((np.float32(hi) - (np.where(off, np.float32(hi), depth) if masked else depth)) * step + np.float32(0.5), 0, 1023).astype(np.uint16)
    colour = _COLOURS[index]
    if masked:
        colour[off] = 0
    return colour


class Mp4Writer:
    """H.264 frames written one chunk at a time (yuv420p, padded to even
    sides by repeating the last row/column, ``faststart``: plays in a
    browser before it is fully downloaded). x264's ``preset`` trades
    encoding time for file size at the quality ``crf`` sets: "veryfast"
    encoded 30 noisy 1080p frames 3.7× faster than x264's default "medium"
    (1.43 s against 5.35 s, a file 14 % smaller).
    A context manager."""

    def __init__(self, path: PathLike, height: int, width: int, fps: float = 25.0, crf: int = 18, preset: str = "veryfast") -> None:
        import av

        self.size = (height, width)
        self.container = av.open(str(path), "w", format="mp4", options={"movflags": "faststart"})
        rate = Fraction(fps).limit_denominator(1001) if fps > 0 else Fraction(25)  # 29.97 stays 30000/1001
        self.stream = self.container.add_stream("libx264", rate=rate, options={"crf": str(crf), "preset": preset})
        self.stream.width, self.stream.height, self.stream.pix_fmt = width + width % 2, height + height % 2, "yuv420p"

    def write(self, frames: np.ndarray) -> None:
        """uint8 RGB frames (n, H, W, 3)."""
        import av

        frames = np.asarray(frames)
        if frames.dtype != np.uint8 or frames.ndim != 4 or frames.shape[1:] != (*self.size, 3):
            raise ValueError(f"frames: expected uint8 (n, {self.size[0]}, {self.size[1]}, 3), got {frames.dtype} {frames.shape}")
        h, w = self.size
        frames = np.pad(frames, ((0, 0), (0, h % 2), (0, w % 2), (0, 0)), mode="edge")
        for frame in frames:
            self.container.mux(self.stream.encode(av.VideoFrame.from_ndarray(np.ascontiguousarray(frame), format="rgb24")))

    def close(self) -> None:
        if self.container is not None:
            self.container.mux(self.stream.encode(None))
            self.container.close()
            self.container = None

    def __enter__(self) -> "Mp4Writer":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def write_mp4(path: PathLike, frames: np.ndarray, fps: float = 25.0, crf: int = 18) -> None:
    """Write uint8 RGB frames (T, H, W, 3) as an H.264 MP4 (:class:`Mp4Writer`)."""
    frames = np.asarray(frames)
    if frames.dtype != np.uint8 or frames.ndim != 4 or frames.shape[-1] != 3 or frames.shape[0] < 1:
        raise ValueError(f"frames: expected uint8 (T, H, W, 3), got {frames.dtype} {frames.shape}")
    with Mp4Writer(path, frames.shape[1], frames.shape[2], fps, crf) as writer:
        writer.write(frames)


def write_depth_png16(folder: PathLike, depth: np.ndarray, value_range: Optional[Tuple[float, float]] = None, start: int = 0) -> Tuple[float, float]:
    """One 16-bit PNG per frame (``depth_0000.png`` …, numbered from
    ``start``): 1 … 65535 spans ``value_range`` (default: the whole video's
    min and max), the same for every frame, and 0 is no depth (NaN: off the
    surface), as in depth cameras' PNGs. Returns the range, so depth =
    lo + (v − 1) / 65534 · (hi − lo)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    lo, hi = (float(np.nanmin(depth)), float(np.nanmax(depth))) if value_range is None else value_range
    scale = 65534.0 / max(hi - lo, 1e-12)
    for t, frame in enumerate(depth, start):
        values = np.rint(np.clip((frame - lo) * scale, 0.0, 65534.0) + 1.0)
        values[np.isnan(frame)] = 0.0
        values = values.astype(np.uint16)
        _core.write_png16(os.fspath(folder / f"depth_{t:04d}.png"), values)
    return lo, hi


def write_ply(path: PathLike, depth: np.ndarray, gray: np.ndarray, relief: float = PLY_RELIEF) -> None:
    """A binary PLY point cloud of one depth frame (H, W): a point per pixel
    with depth (NaN, off the surface, has none) at
    x = (col + ½)/W, y = −(row + ½)/W (the frame is one unit wide) and
    z = −relief · depth, coloured by the input frame ``gray`` (H, W) uint8.
    Orthographic, like the training data. With the standardised depth of
    :func:`nrdepth.reconstruct`, ``relief`` is the depth's standard deviation
    in frame widths (the network fixes no scale; choose what looks right)."""
    h, w = depth.shape
    rows, cols = np.nonzero(~np.isnan(depth))
    vertex = np.empty(len(rows), dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("red", "u1"), ("green", "u1"), ("blue", "u1")])
    vertex["x"] = (cols + 0.5) / w
    vertex["y"] = -(rows + 0.5) / w
    vertex["z"] = -relief * depth[rows, cols]
    for channel in ("red", "green", "blue"):
        vertex[channel] = gray[rows, cols]
    header = (
        "ply\nformat binary_little_endian 1.0\ncomment nrdepth depth frame, orthographic\n"
        f"element vertex {len(rows)}\nproperty float x\nproperty float y\nproperty float z\n"
        "property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n"
    )
    with open(path, "wb") as f:
        f.write(header.encode("ascii"))
        f.write(vertex.tobytes())


MARKER = ".nrdepth-reconstruction"
"""Written into every output folder: ``overwrite`` replaces only folders that hold it."""
WRITTEN = {MARKER, "depth.npz", "depth.mp4", "side_by_side.mp4", "viewer.html", "png16", "ply"}
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


class ReconstructionWriter:
    """A reconstruction folder written a chunk of frames at a time, all or
    nothing: ``depth.npz`` (float32 ``depth`` (T, H, W), the colour map's
    ``range``, and with ``png16`` the ``png16_range`` its PNGs span),
    ``depth.mp4`` (colourised over ``value_range``, the same for every
    frame), ``side_by_side.mp4`` (input | depth), with ``viewer`` the 3-D
    page ``viewer.html`` (:mod:`nrdepth.viewer`), and optionally
    ``png16/depth_NNNN.png`` and ``ply/frame_NNNN.ply``. Everything goes
    into a temporary folder beside ``out``, renamed at :meth:`close` once
    all T frames are in (:meth:`set_ranges` first, unless ``value_range`` is
    given); an error or an interrupt (leaving the ``with``
    block by an exception) removes it, so nothing partial is left. With
    ``overwrite`` an old result is moved aside, the new one renamed in,
    then the old one deleted: a kill at any point leaves one of the two at
    ``out`` (or aside, put back by the next run). The folder is checked by
    :func:`check_output_folder` first. Memory does not grow with T. NaN
    depth (off the surface: :func:`nrdepth.reconstruct`'s ``mask``) is black
    in the videos, 0 in the PNGs, no point in the PLYs and a hole in the
    viewer."""

    def __init__(self, out: PathLike, shape: Tuple[int, int, int], fps: float, value_range: Optional[Tuple[float, float]] = None,
                 png16: bool = False, ply: bool = False, ply_relief: float = PLY_RELIEF, overwrite: bool = False, viewer: bool = True) -> None:
        import shutil
        import zipfile

        if isinstance(ply_relief, bool) or not isinstance(ply_relief, (int, float, np.floating)) or not (math.isfinite(ply_relief) and ply_relief > 0):
            raise ValueError(f"ply_relief: expected a positive finite number, got {ply_relief!r}")
        self.out = check_output_folder(out, overwrite)
        self.shape, self.value_range, self.png16, self.ply, self.ply_relief = tuple(shape), value_range, png16, ply, float(ply_relief)
        self.fps = fps
        if viewer:
            from .viewer import ViewerFrames

            self.viewer: Optional["ViewerFrames"] = ViewerFrames(self.shape)
        else:
            self.viewer = None
        self.png16_range: Optional[Tuple[float, float]] = None
        self.done = 0
        self.out.parent.mkdir(parents=True, exist_ok=True)
        self.tmp = self.out.parent / f".{self.out.name}.partial-{os.getpid()}"
        shutil.rmtree(self.tmp, ignore_errors=True)  # left by a killed run of this pid
        self.tmp.mkdir()
        try:
            (self.tmp / MARKER).write_text("written by nrdepth reconstruct; --overwrite replaces this folder\n")
            # The depth streams into the archive's member; numpy reads it back as any .npz. Stored, not
            # deflated: float depth shrinks by ~15 % for 5 s of kinect_paper's 40 (np.savez's choice).
            self.archive = zipfile.ZipFile(self.tmp / "depth.npz", "w", compression=zipfile.ZIP_STORED)
            self.member = self.archive.open("depth.npy", "w", force_zip64=True)
            np.lib.format.write_array_header_2_0(self.member, {"descr": "<f4", "fortran_order": False, "shape": self.shape})
            _, h, w = self.shape
            self.videos = [Mp4Writer(self.tmp / "depth.mp4", h, w, fps), Mp4Writer(self.tmp / "side_by_side.mp4", h, 2 * w, fps)]
            for folder in (("png16",) if png16 else ()) + (("ply",) if ply else ()):
                (self.tmp / folder).mkdir()
        except BaseException:
            self.abort()
            raise

    def scratch(self, name: str) -> Path:
        """A path inside the temporary folder for the caller's own scratch
        file, removed with the folder (delete it before :meth:`close`)."""
        return self.tmp / name

    def set_ranges(self, value_range: Tuple[float, float], png16_range: Optional[Tuple[float, float]] = None) -> None:
        """The colour map's range and, with ``png16``, the range the PNGs span (default: ``value_range``), before the first :meth:`write`."""
        self.value_range = value_range
        self.png16_range = value_range if png16_range is None else png16_range

    def write(self, frames: np.ndarray, depth: np.ndarray) -> None:
        """The next uint8 input frames (n, H, W) and their float depth (n, H, W)."""
        if self.value_range is None:
            raise ValueError("value_range: give the colour range (set_ranges) before the first frames")
        frames, depth = np.asarray(frames), np.asarray(depth, dtype=np.float32)
        if frames.dtype != np.uint8 or frames.ndim != 3 or depth.shape != frames.shape or frames.shape[1:] != self.shape[1:]:
            raise ValueError(f"depth: expected float (n, H, W) matching uint8 frames of {self.shape[1:]}, got {depth.shape} and {frames.shape}")
        if self.done + len(frames) > self.shape[0]:
            raise ValueError(f"depth: more than the {self.shape[0]} frames announced")
        self.member.write(np.ascontiguousarray(depth, dtype="<f4").tobytes())
        colour = colorize_depth(depth, self.value_range)
        self.videos[0].write(colour)
        self.videos[1].write(np.concatenate([np.repeat(frames[..., None], 3, axis=-1), colour], axis=2))
        if self.png16:
            write_depth_png16(self.tmp / "png16", depth, self.png16_range or self.value_range, start=self.done)
        if self.viewer is not None:
            self.viewer.add(depth, frames)
        if self.ply:
            for t, (d, g) in enumerate(zip(depth, frames), self.done):
                write_ply(self.tmp / "ply" / f"frame_{t:04d}.ply", d, g, self.ply_relief)
        self.done += len(frames)

    def close(self) -> Path:
        """Finish the files and rename the folder into place (every frame must be in)."""
        if self.done != self.shape[0]:
            raise ValueError(f"depth: {self.done} of the {self.shape[0]} frames announced were written")
        try:
            self.member.close()
            extra = {"range": np.array(self.value_range, np.float32)}
            if self.png16:
                extra["png16_range"] = np.array(self.png16_range or self.value_range, np.float32)
            for name, value in extra.items():
                with self.archive.open(f"{name}.npy", "w") as f:
                    np.lib.format.write_array(f, value)
            self.archive.close()
            for video in self.videos:
                video.close()
            if self.viewer is not None:
                from .viewer import FULL_RESOLUTION, write_page

                write_page(self.tmp / "viewer.html", [("depth", self.viewer)], self.fps, f"nrdepth: {self.out.name}", FULL_RESOLUTION)
            aside = self.out.parent / f".{self.out.name}.old-{os.getpid()}"
            if self.out.exists():
                os.replace(self.out, aside)
            os.replace(self.tmp, self.out)
        except BaseException:
            self.abort()
            raise
        import shutil

        shutil.rmtree(aside, ignore_errors=True)
        return self.out

    def abort(self) -> None:
        """Remove the temporary folder; ``out`` is left as it was."""
        import shutil

        for closing in [getattr(self, "member", None), getattr(self, "archive", None), *getattr(self, "videos", [])]:
            try:
                if closing is not None:
                    closing.close()
            except Exception:  # noqa: BLE001 - the folder goes anyway
                pass
        shutil.rmtree(self.tmp, ignore_errors=True)

    def __enter__(self) -> "ReconstructionWriter":
        return self

    def __exit__(self, kind: object, *rest: object) -> None:
        if kind is None:
            self.close()
        else:
            self.abort()


def save_reconstruction(
    out: PathLike,
    frames: np.ndarray,
    depth: np.ndarray,
    fps: float = 25.0,
    png16: bool = False,
    ply: bool = False,
    ply_relief: float = PLY_RELIEF,
    overwrite: bool = False,
    viewer: bool = True,
) -> Path:
    """Write a whole reconstruction into the folder ``out``, all or nothing
    (:class:`ReconstructionWriter`: its files, guarantees and
    ``png16``/``ply``/``viewer`` options); ``ply_relief``: see :func:`write_ply`."""
    frames, depth = np.asarray(frames), np.asarray(depth, dtype=np.float32)
    if frames.dtype != np.uint8 or frames.ndim != 3 or depth.shape != frames.shape:
        raise ValueError(f"depth: expected float (T, H, W) matching uint8 frames {frames.shape}, got {depth.shape}")
    with ReconstructionWriter(out, depth.shape, fps, png16=png16, ply=ply, ply_relief=ply_relief, overwrite=overwrite, viewer=viewer) as writer:
        writer.set_ranges(depth_range(depth), (float(np.nanmin(depth)), float(np.nanmax(depth))))
        writer.write(frames, depth)
    return writer.out
