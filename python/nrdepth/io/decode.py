"""Reading videos in: a video file (anything FFmpeg decodes: mp4, avi, mov,
gif, …), a folder of images (PNG, JPEG, BMP, TIFF; frames in name order) or
a NumPy ``.npy`` / ``.npz`` array (T, H, W) or (T, H, W, 3), uint8 or float
in [0, 1]. Colour is turned into luma (ITU-R BT.601, FFmpeg's ``gray``).
Decoding goes through PyAV (FFmpeg's libraries).
"""

from __future__ import annotations

import itertools
import os
import zipfile
import zlib
from pathlib import Path
from typing import BinaryIO, Iterator, NamedTuple, Optional, Tuple, Union

import numpy as np

from ..checks import option_error

__all__ = ["Video", "VideoSource", "open_video", "read_video", "iter_npz_frames", "npz_header", "read_left_half", "to_gray", "select", "IMAGE_SUFFIXES", "KEEP_DECODED", "PathLike"]

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")

KEEP_DECODED = 256 * 2**20
"""Bytes of decoded gray frames a :class:`VideoSource` keeps after reading
its selection to the end, so that reading it again does not decode again:
the main job reads its input four times (``kinect_paper``'s 191 PNGs:
5.8 s of decoding, one read 1.5 s). A longer video (more than 873 frames of
640×480, 129 of 1080p) is decoded at every read, in memory that does not
grow with its length."""
PathLike = Union[str, os.PathLike]

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
        raise option_error(name, f"expected uint8 or float frames, got dtype {a.dtype}", TypeError)
    if a.dtype.kind == "f":
        if not np.isfinite(a).all():
            raise option_error(name, "expected finite values (found NaN or inf)")
        if a.size and (a.min() < 0.0 or a.max() > 1.0):
            hint = "; divide 0..255 data by 255" if a.max() > 1.0 else ""
            raise option_error(name, f"expected float frames in [0, 1], got values in [{a.min():.4g}, {a.max():.4g}]{hint}")
    if a.ndim == 4 and a.shape[-1] in (3, 4):
        luma = a[..., :3].astype(np.float32) @ LUMA
        a = np.rint(luma).astype(np.uint8) if a.dtype == np.uint8 else luma
    if a.ndim != 3 or min(a.shape) < 1:
        raise option_error(name, f"expected a video (T, H, W) or (T, H, W, 3), got shape {a.shape}")
    return a if a.dtype == np.uint8 else a.astype(np.float32, copy=False)


def _to_gray_u8(array: np.ndarray, name: str) -> np.ndarray:
    a = to_gray(array, name)
    return a if a.dtype == np.uint8 else np.rint(a * 255.0).astype(np.uint8)


def select(video: np.ndarray, frames: Optional[slice] = None, roi: Optional[Tuple[int, int, int, int]] = None) -> np.ndarray:
    """The frames (a slice with a positive step) and region (x, y, width,
    height in pixels, inside the frame) of a video (T, H, W) to work on."""
    if frames is not None:
        if not isinstance(frames, slice):
            raise option_error("frames", f"expected a slice, got {type(frames).__name__}", TypeError)
        if frames.step is not None and frames.step <= 0:
            raise option_error("frames", f"expected a positive step, got {frames.step}")
        count = len(video)
        video = video[frames]
        if len(video) == 0:
            raise option_error("frames", f"selects no frame of the video's {count}")
    if roi is not None:
        try:
            x, y, w, h = (int(v) for v in roi if not isinstance(v, bool) and float(v) == int(v))
        except (TypeError, ValueError):
            raise option_error("roi", f"expected four integers (x, y, width, height), got {roi!r}") from None
        height, width = video.shape[1:3]
        if w < 1 or h < 1 or x < 0 or y < 0 or x + w > width or y + h > height:
            raise option_error("roi", f"expected x, y, width, height inside the {width}×{height} frame, got {x},{y},{w},{h}")
        video = video[:, y : y + h, x : x + w]
    return video


def _decoded(path: Path, name: str) -> Iterator[np.ndarray]:
    """The frames of a media file as uint8 gray arrays, one at a time."""
    import av

    try:
        with av.open(str(path)) as container:
            if not container.streams.video:
                raise option_error(name, f"{path} holds no video stream")
            for frame in container.decode(container.streams.video[0]):
                yield frame.to_ndarray(format="gray")
    except av.error.FFmpegError as e:
        raise option_error(name, f"cannot decode {path}: {e}") from None


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
    A selection of at most :data:`KEEP_DECODED` bytes is decoded once, at
    the first read to its end, and kept. Errors name ``name`` and say what
    was expected."""

    def __init__(self, path: PathLike, name: str = "input", frames: Optional[slice] = None, roi: Optional[Tuple[int, int, int, int]] = None) -> None:
        self.path, self.name = Path(path), name
        if not self.path.exists():
            raise option_error(name, f"{self.path} does not exist")
        self.array: Optional[np.ndarray] = None
        self.images: list = []
        self._count: Optional[int] = None
        self._kept: Optional[list] = None
        if self.path.is_dir():
            self.images = sorted(p for p in self.path.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES)
            if not self.images:
                raise option_error(name, f"folder {self.path} holds no images ({', '.join(IMAGE_SUFFIXES)})")
            self.fps = 25.0
        elif self.path.suffix.lower() in (".npy", ".npz"):
            self.array = _load_array(self.path, name)
            self.fps = 25.0
        else:
            self.fps = _frame_rate(self.path)
        first = next(self._raw(), None)
        if first is None:
            raise option_error(name, f"{self.path} holds no frames")
        if frames is not None:
            if not isinstance(frames, slice):
                raise option_error("frames", f"expected a slice, got {type(frames).__name__}", TypeError)
            if frames.step is not None and frames.step <= 0:
                raise option_error("frames", f"expected a positive step, got {frames.step}")
        self.selection, self.roi = frames, roi
        self.raw_size: Tuple[int, int] = first.shape  # the frames as given
        # Checks the region against the frame size.
        self.frame_size: Tuple[int, int] = select(first[None], None, roi).shape[1:]  # type: ignore[assignment]
        if frames is not None and len(self) == 0:
            raise option_error("frames", f"selects no frame of the video's {self.count_all()}")

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

    def _selected(self) -> Iterator[np.ndarray]:
        """The selected frames, whole (no ``roi``), as decoded; decoded once
        where they fit in :data:`KEEP_DECODED` bytes, kept read-only."""
        if self._kept is not None:
            yield from self._kept
            return
        frames: Iterator[np.ndarray] = self._raw()
        if self.selection is not None:
            frames = itertools.islice(frames, *self.selection.indices(self.count_all()))
        kept: Optional[list] = []
        held = 0
        for frame in frames:
            if kept is not None:
                held += frame.nbytes
                if held <= KEEP_DECODED:
                    frame.flags.writeable = False
                    kept.append(frame)
                else:
                    kept = None
            yield frame
        if kept is not None:  # only a read to the end
            self._kept = kept

    def chunks(self, size: int = 16, roi: bool = True) -> Iterator[np.ndarray]:
        """The selected frames, uint8 (n, H, W), ``size`` at a time, in
        order; cut to the source's ``roi`` unless ``roi`` is False (a region
        is given when the source is opened)."""
        if not isinstance(roi, bool):
            raise option_error("roi", f"expected True (the source's region) or False (whole frames), got {roi!r}", TypeError)
        region = self.roi if roi else None
        chunk: list = []
        for frame in self._selected():
            chunk.append(frame)
            if len(chunk) == size:
                yield select(np.stack(chunk), None, region)
                chunk = []
        if chunk:
            yield select(np.stack(chunk), None, region)


def _load_array(path: Path, name: str) -> np.ndarray:
    try:
        data = np.load(path, allow_pickle=False, mmap_mode="r" if path.suffix.lower() == ".npy" else None)
    except (OSError, ValueError, EOFError) as e:
        raise option_error(name, f"cannot read {path}: {e}") from None
    if isinstance(data, np.lib.npyio.NpzFile):
        with data:
            keys = list(data.keys())
            key = "video" if "video" in keys else (keys[0] if len(keys) == 1 else None)
            if key is None:
                raise option_error(name, f"{path} should hold one array or one named 'video', found {keys}")
            data = data[key]
    if data.dtype == bool:
        data = data.astype(np.uint8) * np.uint8(255)  # a mask: True white
    if data.dtype != np.uint8 and data.dtype.kind != "f":
        raise option_error(name, f"expected uint8, float or bool frames, got dtype {data.dtype}", TypeError)
    if data.ndim not in (3, 4) or (data.ndim == 4 and data.shape[-1] not in (3, 4)) or min(data.shape) < 1:
        raise option_error(name, f"expected a video (T, H, W) or (T, H, W, 3), got shape {data.shape}")
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


_UNREADABLE = (zipfile.BadZipFile, zlib.error, EOFError, ValueError, OSError)
"""What a damaged .npz raises while read: a bad archive, a bad deflate stream, a cut member, a bad header."""


def _open_npz_member(path: PathLike, name: str) -> Tuple[zipfile.ZipFile, BinaryIO, Tuple[int, ...], np.dtype]:
    """The archive ``path``, its member ``name``.npy opened at the data, and
    the array's shape and dtype, read from the header alone. A file that is
    not a readable .npz, or holds no such array, is refused by ``name``."""
    if not Path(path).is_file():
        raise option_error(name, f"{path} not found (expected an .npz file)")
    try:
        archive = zipfile.ZipFile(path)
    except _UNREADABLE as e:
        raise option_error(name, f"{path} is not a readable .npz archive ({e})") from None
    try:
        member = archive.open(f"{name}.npy")
    except KeyError:
        held = sorted(n[: -len(".npy")] for n in archive.namelist() if n.endswith(".npy"))
        archive.close()
        raise option_error(name, f"{path} holds no array '{name}' (it holds {', '.join(held) or 'none'})") from None
    except _UNREADABLE as e:
        archive.close()
        raise option_error(name, f"{path} is not a readable .npz archive ({e})") from None
    try:
        version = np.lib.format.read_magic(member)
        read = {(1, 0): np.lib.format.read_array_header_1_0, (2, 0): np.lib.format.read_array_header_2_0}.get(version)
        if read is None:
            raise ValueError(f"unsupported .npy version {version}")
        shape, fortran, dtype = read(member)
        if fortran:
            raise ValueError("expected a C-ordered array")
    except _UNREADABLE as e:
        member.close()
        archive.close()
        raise option_error(name, f"{path}: the array '{name}' has no readable .npy header ({e})") from None
    return archive, member, tuple(shape), dtype


def npz_header(path: PathLike, name: str) -> Tuple[Tuple[int, ...], np.dtype]:
    """The shape and dtype of array ``name`` in the .npz ``path``, read from its header alone."""
    archive, member, shape, dtype = _open_npz_member(path, name)
    member.close()
    archive.close()
    return shape, dtype


def iter_npz_frames(path: PathLike, name: str, chunk: int = 16) -> Tuple[Tuple[int, ...], np.dtype, Iterator[np.ndarray]]:
    """The shape and dtype of array ``name`` (T, ...) in an .npz and an
    iterator over it ``chunk`` frames at a time, read from the archive as it
    goes (not loaded whole: a 1080p depth video is GBs). A damaged file is
    refused by ``name`` (ValueError), also when the damage is met mid-way."""
    archive, member, shape, dtype = _open_npz_member(path, name)
    if not shape:
        member.close()
        archive.close()
        raise option_error(name, f"{path}: expected frames (T, ...), got a scalar '{name}'")
    per = int(np.prod(shape[1:], dtype=np.int64)) * dtype.itemsize

    def frames() -> Iterator[np.ndarray]:
        with archive, member:
            for start in range(0, shape[0], chunk):
                n = min(chunk, shape[0] - start)
                try:
                    data = member.read(n * per)
                except _UNREADABLE as e:
                    raise option_error(name, f"{path} is damaged at frame {start} ({e})") from None
                if len(data) != n * per:
                    raise option_error(name, f"{path} is cut short: its data ends in frame {start + len(data) // per} of the {shape[0]} its header gives")
                yield np.frombuffer(data, dtype).reshape(n, *shape[1:])

    return shape, dtype, frames()


def read_left_half(path: PathLike, size: Tuple[int, int]) -> Tuple[float, Iterator[np.ndarray]]:
    """The frame rate of a side-by-side MP4 (input | depth) and its input
    frames, uint8 gray (H, W) = ``size``, one at a time (decoded, so
    approximately the input)."""
    h, w = size
    return _frame_rate(Path(path)), (frame[:h, :w] for frame in _decoded(Path(path), "side_by_side"))
