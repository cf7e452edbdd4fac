"""A reconstruction's output folder, written all or nothing: the checks of
a folder before any work, the writer that streams every file into a
temporary folder and renames it into place, and the stale folders of
killed runs."""

from __future__ import annotations

import json
import math
import os
import shutil
import zipfile
from pathlib import Path
from typing import Optional, Tuple

import numpy as np

from ..checks import is_number, option_error
from ..interrupt import committed, raise_if_interrupted
from .colours import colorize_depth, depth_range
from .decode import PathLike, npz_header
from .viewer import FULL_RESOLUTION, ViewerFrames, sheet_note, write_page
from .writers import PLY_RELIEF, Mp4Writer, write_depth_png16, write_ply

__all__ = ["ReconstructionWriter", "save_reconstruction", "check_output_folder", "check_complete", "MARKER", "WRITTEN"]

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
        raise option_error("out", f"refusing {out} (it is the working folder, an ancestor of it, or the home or root folder); name a new folder")
    for i in inputs:
        source = Path(i).resolve()
        if source == where or where in source.parents:
            raise option_error("out", f"{out} contains the input {i}; name another folder")
    # The temporary folder goes beside ``out``: its parent, or the nearest folder that exists above it, must take it.
    above = next(p for p in where.parents if p.exists())
    if not above.is_dir():
        raise option_error("out", f"cannot make {out}: {above} is a file, not a folder")
    if not os.access(above, os.W_OK | os.X_OK):
        raise option_error("out", f"cannot write {out}: no permission to write in {above}")
    _clean_stale(out)
    if out.is_file():
        raise option_error("out", f"{out} is a file; expected a folder")
    if out.exists() and any(out.iterdir()):
        if not overwrite:
            raise option_error("out", f"{out} exists and is not empty (pass overwrite=True / --overwrite)")
        if not (out / MARKER).exists():
            raise option_error("out", f"{out} was not written by nrdepth (no {MARKER}); --overwrite replaces only nrdepth's own output")
        foreign = sorted(p.name for p in out.iterdir() if p.name not in WRITTEN)
        if foreign:
            raise option_error("out", f"{out} holds files nrdepth did not write ({', '.join(foreign[:3])}{', …' if len(foreign) > 3 else ''}); move them first")
    return out


def check_complete(out: PathLike, viewer: bool = True, png16: bool = False, ply: bool = False) -> int:
    """The frame count of ``out`` if it is a reconstruction folder that was
    finished with these outputs: its marker, ``depth.npz`` whole (a float
    depth video and its colour range), the MP4s, and with ``viewer``,
    ``png16`` and ``ply`` the page and a PNG and a PLY a frame. Otherwise a
    ValueError that says what is missing (a batch redoes that video)."""
    out = Path(out)
    if not (out / MARKER).is_file():
        raise option_error("out", f"{out} is not a folder nrdepth finished (no {MARKER})")
    try:
        with zipfile.ZipFile(out / "depth.npz") as archive:
            held = {info.filename: info.file_size for info in archive.infolist()}
    except (zipfile.BadZipFile, OSError) as e:
        raise option_error("out", f"{out / 'depth.npz'} is not a readable .npz archive ({e})") from None
    shape, dtype = npz_header(out / "depth.npz", "depth")
    if dtype.kind != "f" or len(shape) != 3 or "range.npy" not in held or held["depth.npy"] < int(np.prod(shape)) * dtype.itemsize:
        raise option_error("out", f"{out / 'depth.npz'} is not a whole depth video with its range")
    wanted = ["depth.mp4", "side_by_side.mp4"] + (["viewer.html"] if viewer else [])
    missing = [name for name in wanted if not (out / name).is_file() or (out / name).stat().st_size == 0]
    for folder, pattern, on in (("png16", "depth_*.png", png16), ("ply", "frame_*.ply", ply)):
        if on and len(list((out / folder).glob(pattern))) != shape[0]:
            missing.append(f"{folder}/ ({shape[0]} files)")
    if missing:
        raise option_error("out", f"{out} lacks {', '.join(missing)}")
    return shape[0]


def _entry(name: str) -> zipfile.ZipInfo:
    """An archive member dated 1980-01-01 (the zip epoch), not now: the same depth gives the same bytes on every run."""
    return zipfile.ZipInfo(name, date_time=(1980, 1, 1, 0, 0, 0))


class ReconstructionWriter:
    """A reconstruction folder written a chunk of frames at a time, all or
    nothing: ``depth.npz`` (float32 ``depth`` (T, H, W), the colour map's
    ``range``, and with ``png16`` the ``png16_range`` its PNGs span),
    ``depth.mp4`` (colourised over ``value_range``, the same for every
    frame), ``side_by_side.mp4`` (input | depth), with ``viewer`` the 3-D
    page ``viewer.html`` (:mod:`nrdepth.io.viewer`), and optionally
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
        if not (is_number(ply_relief) and math.isfinite(ply_relief) and ply_relief > 0):
            raise option_error("ply_relief", f"expected a positive finite number, got {ply_relief!r}")
        self.out = check_output_folder(out, overwrite)
        self.shape, self.value_range, self.png16, self.ply, self.ply_relief = tuple(shape), value_range, png16, ply, float(ply_relief)
        self.fps = fps
        if viewer:
            self.viewer: Optional[ViewerFrames] = ViewerFrames(self.shape)
        else:
            self.viewer = None
        self.png16_range: Optional[Tuple[float, float]] = None
        self.metadata: dict = {}
        self.done = 0
        self.tmp = self.out.parent / f".{self.out.name}.partial-{os.getpid()}"
        try:
            self.out.parent.mkdir(parents=True, exist_ok=True)
            shutil.rmtree(self.tmp, ignore_errors=True)  # left by a killed run of this pid
            self.tmp.mkdir()
        except OSError as e:  # e.g. a read-only folder the check above could not see (root, a network share)
            raise option_error("out", f"cannot write {self.out}: {e.strerror or e} in {self.out.parent}") from None
        try:
            (self.tmp / MARKER).write_text("written by nrdepth reconstruct; --overwrite replaces this folder\n")
            # The depth streams into the archive's member; numpy reads it back as any .npz. Stored, not
            # deflated: float depth shrinks by ~15 % for 5 s of kinect_paper's 40 (np.savez's choice).
            self.archive = zipfile.ZipFile(self.tmp / "depth.npz", "w", compression=zipfile.ZIP_STORED)
            self.member = self.archive.open(_entry("depth.npy"), "w", force_zip64=True)
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

    def set_metadata(self, name: str, value: dict) -> None:
        """A record kept in ``depth.npz`` as JSON under ``name`` (a 0-d string
        array: ``json.loads(str(np.load(path)[name]))``), before :meth:`close`."""
        if name in ("depth", "range", "png16_range") or not name.isidentifier():
            raise ValueError(f"name: expected a new identifier for depth.npz's member, got {name!r}")
        self.metadata[name] = json.dumps(value, sort_keys=True)

    def write(self, frames: np.ndarray, depth: np.ndarray) -> None:
        """The next uint8 input frames (n, H, W) and their float depth (n, H, W)."""
        raise_if_interrupted()
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
            extra.update((name, np.array(text)) for name, text in self.metadata.items())
            for name, value in extra.items():
                with self.archive.open(_entry(f"{name}.npy"), "w") as f:
                    np.lib.format.write_array(f, value)
            self.archive.close()
            for video in self.videos:
                video.close()
            if self.viewer is not None:
                write_page(self.tmp / "viewer.html", [("depth", self.viewer)], self.fps, f"nrdepth: {self.out.name}",
                           " ".join(filter(None, [FULL_RESOLUTION, sheet_note(self.metadata.get("sheet"))])))
            committed()  # a Ctrl-C before this point leaves nothing; after it, the output stands
            aside = self.out.parent / f".{self.out.name}.old-{os.getpid()}"
            if self.out.exists():
                os.replace(self.out, aside)
            os.replace(self.tmp, self.out)
        except BaseException:
            self.abort()
            raise
        shutil.rmtree(aside, ignore_errors=True)
        return self.out

    def abort(self) -> None:
        """Remove the temporary folder; ``out`` is left as it was."""
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
