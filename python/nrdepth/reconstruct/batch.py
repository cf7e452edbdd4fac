"""Many videos: :func:`reconstruct_many` runs :func:`~.api.reconstruct_file`
on each into a folder of its own under one output folder, side by side on
this machine (a process pool) or on a Ray cluster (``engine="ray"``, the
``nrdepth[ray]`` extra).

Each video is all or nothing (the writer's temporary folder); a video whose
folder is complete (:func:`~nrdepth.io.check_complete`) is skipped on a
rerun, so an interrupted batch resumes where it stopped. A video that
fails, for any reason, is reported in ``summary.csv`` with its error and
the batch goes on. A worker runs its videos one at a time with the torch
threads it is given: its depth is byte-identical to a single
``reconstruct_file`` run at that thread count (torch's convolutions round
differently at other thread counts).
"""

from __future__ import annotations

import csv
import ctypes
import glob
import io
import json
import os
import signal
import socket
import sys
import threading
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from dataclasses import asdict, dataclass, fields
from multiprocessing import active_children, get_context
from pathlib import Path
from typing import Callable, Iterable, Iterator, List, Optional, Sequence, Tuple, Union

import numpy as np

from ..checks import option_error
from ..io.decode import IMAGE_SUFFIXES, PathLike, npz_header
from ..io.folder import check_complete
from ..memory import keep_freed_memory
from .api import reconstruct_file
from .options import ReconstructOptions

__all__ = ["reconstruct_many", "list_videos", "BatchRow", "VIDEO_SUFFIXES", "ENGINES", "SUMMARY", "THREADS"]

VIDEO_SUFFIXES = (".mp4", ".avi", ".mov", ".mkv", ".webm", ".m4v", ".mpg", ".mpeg", ".gif", ".npy", ".npz")
"""The files a folder or glob of inputs contributes (an image folder is one video too)."""
ENGINES = ("local", "ray")
THREADS = 4
"""Torch threads a video by default (fewer on a smaller machine or node): on this project's 2 cores one video on
both ran 8 copies of a 640×480×64 clip at 2.82 videos a minute, two videos on one each at 2.30
(``benchmarks/bench_batch.py``, docs/reconstruction.md#many-videos); fewer workers also hold less memory."""
SUMMARY = "summary.csv"
"""The batch's table, in the output folder: one row per video, rewritten as each one ends."""

@dataclass
class BatchRow:
    """One video of a batch, as ``summary.csv`` has it."""

    input: str
    output: str
    status: str = "pending"
    """``done`` (written now), ``skipped`` (complete from an earlier run), ``failed``, or ``pending`` (not reached)."""
    seconds: float = 0.0
    frames: int = 0
    error: str = ""
    sheet_used: str = ""
    """The sheet stage's decision (``depth.npz``'s ``sheet``): ``yes`` where the sheet's shape was used, ``no`` where not, "" before a run."""
    sheet_reason: str = ""
    sheet_focal: str = ""
    """The focal length in pixels the shape was read through (``FX FY``), "" where the stage did not run."""

    def take_sheet(self, folder: PathLike) -> None:
        """The sheet columns from the written ``folder``'s ``depth.npz``."""
        with np.load(Path(folder) / "depth.npz") as saved:
            sheet = json.loads(str(saved["sheet"])) if "sheet" in saved.files else None
        if sheet is not None:
            self.sheet_used, self.sheet_reason = ("yes" if sheet["used"] else "no"), sheet["reason"]
            self.sheet_focal = "" if sheet["focal"] is None else " ".join(f"{f:g}" for f in sheet["focal"])


def _is_image_folder(folder: Path) -> bool:
    return any(p.suffix.lower() in IMAGE_SUFFIXES for p in folder.iterdir())


def _expand(item: PathLike) -> List[Path]:
    """The videos one input names: a video, an image folder, a folder of
    videos (and image folders), a glob pattern, or a text file listing one
    a line (relative to the list; blank lines and ``#`` comments skipped)."""
    text = os.fspath(item)
    path = Path(text)
    if path.is_dir():
        if _is_image_folder(path) and not any(p.suffix.lower() in VIDEO_SUFFIXES for p in path.iterdir()):
            return [path]
        found = sorted(p for p in path.iterdir() if (p.is_file() and p.suffix.lower() in VIDEO_SUFFIXES) or (p.is_dir() and _is_image_folder(p)))
        if not found:
            raise option_error("inputs", f"{text} holds no video ({', '.join(VIDEO_SUFFIXES)}) and no folder of images")
        return found
    if path.is_file() and path.suffix.lower() == ".txt":
        listed = [line.strip() for line in path.read_text(encoding="utf-8").splitlines()]
        return [path.parent / line for line in listed if line and not line.startswith("#")]
    if path.exists():
        return [path]
    if glob.has_magic(text):
        found = sorted(Path(p) for p in glob.glob(text, recursive=True)
                       if (Path(p).is_file() and Path(p).suffix.lower() in VIDEO_SUFFIXES) or (Path(p).is_dir() and _is_image_folder(Path(p))))
        if not found:
            raise option_error("inputs", f"the pattern {text} matches no video")
        return found
    return [path]  # a missing video is the batch's to report, as any video that fails


def list_videos(inputs: Union[PathLike, Sequence[PathLike]], out: PathLike) -> List[Tuple[Path, Path]]:
    """Each video of ``inputs`` (see :func:`reconstruct_many`) with its own
    folder under ``out``: its name without the suffix; where names meet,
    with it (``clip_mp4``, ``clip_avi``), or numbered in input order where
    that is not enough (``clip_1``, ``clip_2``). A name made so that meets
    another video's own name (``clip_1.npy``), or another made name, takes
    the next free number (``clip_1_2``); names are compared as a
    case-insensitive file system would. Every name is decided before any
    work, from the inputs alone: the same inputs, the same folders. A video
    listed twice is run once."""
    if isinstance(inputs, (str, os.PathLike)):
        inputs = [inputs]
    if not inputs:
        raise option_error("inputs", "expected at least one video, folder, glob pattern or list")
    videos: List[Path] = []
    seen = set()
    for item in inputs:
        for video in _expand(item):
            if video.resolve() not in seen:
                seen.add(video.resolve())
                videos.append(video)
    return [(video, Path(out) / name) for video, name in zip(videos, _folder_names(videos))]


def _folder_names(videos: List[Path]) -> List[str]:
    """:func:`list_videos`' folder names, none meeting another (case-insensitively)."""
    stems = [v.name if v.is_dir() else v.stem for v in videos]
    folded = [stem.casefold() for stem in stems]
    wanted = list(stems)
    for stem in set(folded):
        group = [i for i, s in enumerate(folded) if s == stem]
        suffixes = [videos[i].suffix.lstrip(".").lower() or "images" for i in group]
        if len(group) > 1:
            for k, i in enumerate(group, 1):
                wanted[i] = f"{stems[i]}_{suffixes[k - 1]}" if len(set(suffixes)) == len(group) else f"{stems[i]}_{k}"
    names: List[Optional[str]] = [None] * len(videos)
    taken = set()
    # A video's own name first (clip_1.npy keeps clip_1), then the names made, in input order, each the next free one.
    for i in sorted(range(len(videos)), key=lambda i: (wanted[i] != stems[i], i)):
        name, k = wanted[i], 2
        while name.casefold() in taken:
            name, k = f"{wanted[i]}_{k}", k + 1
        taken.add(name.casefold())
        names[i] = name
    return names


def _earlier_inputs(out: Path) -> dict:
    """The input each output folder of an earlier batch into ``out`` was written from (its ``summary.csv``), by folder name."""
    try:
        with open(out / SUMMARY, encoding="utf-8", newline="") as table:
            return {Path(row["output"]).name.casefold(): row["input"] for row in csv.DictReader(table) if row.get("output") and row.get("input")}
    except (OSError, csv.Error, KeyError):
        return {}


def _check_against_earlier(pairs: List[Tuple[Path, Path]], out: Path) -> None:
    """Refuses a video whose folder holds another video's result from an earlier batch into ``out``, naming both."""
    earlier = _earlier_inputs(out)
    for video, folder in pairs:
        before = earlier.get(folder.name.casefold())
        if before is not None and folder.exists() and os.path.realpath(before) != os.path.realpath(video):
            raise option_error("inputs", f"{video} would be written to {folder}, which holds {before} from an earlier batch "
                               "(its summary.csv); give another output folder, or remove that one")


def _one_line(error: BaseException) -> str:
    text = " ".join(str(error).split())
    return f"{type(error).__name__}: {text}" if text else type(error).__name__


def _run_one(video: str, folder: str, model: Optional[str], options: ReconstructOptions, threads: int) -> BatchRow:
    """A worker's video: its folder written, or its error; never raises but on an interrupt."""
    import torch

    torch.set_num_threads(threads)
    keep_freed_memory()  # the worker's process is the batch's own
    global _RUNNING
    row = BatchRow(video, folder)
    start = time.perf_counter()
    _RUNNING = True
    try:
        reconstruct_file(video, folder, model, ReconstructOptions.of(options, overwrite=True))  # a folder left incomplete is redone
        row.status, row.frames = "done", npz_header(Path(folder) / "depth.npz", "depth")[0][0]
        row.take_sheet(folder)
    except Exception as error:  # noqa: BLE001 - whatever a video does, the batch goes on and says why
        row.status, row.error = "failed", _one_line(error)
    finally:
        _RUNNING = False
    row.seconds = round(time.perf_counter() - start, 2)
    return row


def _absolute(row: BatchRow) -> Tuple[str, str]:
    """A video's input and output for a worker, which may start in another folder (a Ray worker does)."""
    return os.path.abspath(row.input), os.path.abspath(row.output)


def _write_summary(out: Path, rows: Iterable[BatchRow]) -> None:
    """``summary.csv``, atomically: the table is whole at any moment."""
    text = io.StringIO()
    writer = csv.DictWriter(text, [f.name for f in fields(BatchRow)], lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow(asdict(row))
    tmp = out / f".{SUMMARY}.partial-{os.getpid()}"
    tmp.write_text(text.getvalue(), encoding="utf-8")
    os.replace(tmp, out / SUMMARY)


_RUNNING = False
"""In a worker: whether a video is being reconstructed (a Ctrl-C then stops it cleanly; between videos the worker just exits)."""


def _worker_start(parent: int, counter, gpus: int) -> None:
    """A local worker's start: it dies with its batch, a Ctrl-C between videos
    ends it without a word, and with ``gpus`` it sees a GPU of its own, in turn
    (set before torch starts)."""
    _die_with(parent)
    signal.signal(signal.SIGINT, _worker_sigint)
    if gpus:
        with counter.get_lock():
            index, counter.value = counter.value, counter.value + 1
        visible = os.environ.get("CUDA_VISIBLE_DEVICES")
        os.environ["CUDA_VISIBLE_DEVICES"] = visible.split(",")[index % gpus] if visible else str(index % gpus)


def _die_with(parent: int) -> None:
    """This process ends when ``parent`` does, even by ``kill -9``: the kernel's
    parent-death signal on Linux, and everywhere a thread that watches the parent."""
    if sys.platform.startswith("linux"):
        try:
            ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
        except (OSError, AttributeError):
            pass

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(1.0)
        os._exit(1)

    if os.getppid() != parent:  # the parent died before the signal was set
        os._exit(1)
    threading.Thread(target=watch, name="nrdepth batch parent watch", daemon=True).start()


def _worker_sigint(signum: int, frame: object) -> None:
    if _RUNNING:
        raise KeyboardInterrupt  # the video's job stops and leaves nothing behind; the batch says so, once
    os._exit(130)  # between videos: nothing to stop, and no traceback to print


def _local(jobs: List[Tuple[int, BatchRow]], model: Optional[str], options: ReconstructOptions, workers: int, threads: int,
           gpus: int) -> Iterator[Tuple[int, BatchRow]]:
    """The jobs through a pool of ``workers`` processes (spawned: a forked
    torch may hang), each on a GPU of its own with ``gpus``. A worker that
    dies takes its video with it (failed); the others go on in a fresh pool."""
    context = get_context("spawn")
    left = dict(jobs)
    while left:
        starting = dict(initializer=_worker_start, initargs=(os.getpid(), context.Value("i", 0), gpus))
        ours = {child.pid for child in active_children()}  # the caller's own children, not to be signalled below
        pool = ProcessPoolExecutor(max_workers=min(workers, len(left)), mp_context=context, **starting)
        try:
            # After a worker died: one video a pool, so that a death names its video and spares the others.
            submitted = list(left.items()) if workers > 1 else list(left.items())[:1]
            futures = {pool.submit(_run_one, *_absolute(row), model, options, threads): i for i, row in submitted}
            for future in as_completed(futures):
                i = futures[future]
                try:
                    row = future.result()
                except BrokenProcessPool:
                    # Every unfinished video sees the break, not only the one whose worker died: they are run
                    # again one at a time.
                    if workers > 1:
                        workers = 1
                        break
                    row = left[i]
                    row.status, row.error = "failed", "the worker process died (out of memory, or a crash in native code)"
                yield i, row
                del left[i]
        except KeyboardInterrupt:
            for child in active_children():  # the workers may not have had the signal (kill -INT to this process alone)
                if child.pid not in ours:
                    os.kill(child.pid, signal.SIGINT)
            raise
        finally:
            pool.shutdown(wait=True, cancel_futures=True)


RAY_REACH = 10.0
"""Seconds within which a Ray cluster's address must answer a TCP connection, or the batch is refused naming it
(Ray's own client retries for many minutes, and names another address when it gives up)."""


def _check_ray_address(address: str) -> None:
    """Refuses a Ray ``address`` (``host:port`` or ``ray://host:port``) that no TCP connection reaches within :data:`RAY_REACH`."""
    if address in ("auto", "local") or not isinstance(address, str):
        return
    host, _, port = address.split("://", 1)[-1].rpartition(":")
    try:
        socket.create_connection((host.strip("[]") or "127.0.0.1", int(port)), timeout=RAY_REACH).close()
    except ValueError:
        raise option_error("address", f"expected host:port, ray://host:port, 'auto' or 'local', got {address!r}") from None
    except OSError as error:
        raise option_error("address", f"no Ray cluster answers at {address} ({error.strerror or error}); start one (ray start --head) "
                           "or leave address out to start one here") from None


def _ray(jobs: List[Tuple[int, BatchRow]], model: Optional[str], options: ReconstructOptions, threads: Optional[int], address: Optional[str]) -> Iterator[Tuple[int, BatchRow]]:
    """The jobs as Ray tasks: ``threads`` CPUs each, and one GPU with a CUDA device."""
    try:
        import ray
    except ImportError as error:
        raise ImportError("engine='ray' needs Ray: pip install 'nrdepth[ray]'") from error
    started = not ray.is_initialized()
    if started:
        ray.init(address=address, include_dashboard=False, logging_level="ERROR", log_to_driver=False)
    # No more CPUs a task than a node has: a task that fits nowhere would wait for ever.
    threads = min(threads or THREADS, max(int(node["Resources"].get("CPU", 1)) for node in ray.nodes() if node["Alive"]))
    gpus = 1 if str(options.device).startswith("cuda") else 0
    if gpus:
        options = ReconstructOptions.of(options, device="cuda")  # Ray gives each task its GPU as the only visible one
    task = ray.remote(num_cpus=threads, num_gpus=gpus, max_retries=0)(_run_one)
    pending = {task.remote(*_absolute(row), model, options, threads): (i, row) for i, row in jobs}
    try:
        while pending:
            done, _ = ray.wait(list(pending), num_returns=1)
            i, row = pending.pop(done[0])
            try:
                row = ray.get(done[0])
            except ray.exceptions.RayError as error:  # the task's worker died, or the cluster lost it
                row.status, row.error = "failed", _one_line(error).splitlines()[0][:500]
            yield i, row
    finally:
        for ref in pending:
            ray.cancel(ref, force=True)
        if started:
            ray.shutdown()


def reconstruct_many(inputs: Union[PathLike, Sequence[PathLike]], out: PathLike, model: Optional[PathLike] = None,
                     options: Optional[ReconstructOptions] = None, *, engine: str = "local", workers: Optional[int] = None,
                     threads: Optional[int] = None, address: Optional[str] = None,
                     progress: Optional[Callable[[int, int, Optional[BatchRow]], None]] = None, **settings) -> List[BatchRow]:
    """:func:`~.api.reconstruct_file` on every video of ``inputs``, each into
    its own folder under ``out`` (:func:`list_videos`), with the same
    ``model`` (a path, or None for the shipped one) and options (an
    :class:`~nrdepth.ReconstructOptions` and/or its fields as keywords).

    ``inputs``: videos, image folders, folders of videos, glob patterns,
    or text files listing videos. A video whose folder is already complete
    is skipped; one that fails is reported and the batch goes on.
    ``out/summary.csv`` (:class:`BatchRow`'s fields) is rewritten as each
    video ends. Returns the rows in input order.

    ``engine``: ``"local"``, a pool of ``workers`` processes on this machine
    (default: one per :data:`THREADS` cores, or one per GPU with a CUDA
    device) of ``threads`` torch threads each (default: the cores shared
    between them); or ``"ray"``, one Ray task per video (``threads`` CPUs
    each, default :data:`THREADS` or a node's CPUs if fewer, and a GPU with a
    CUDA device) on the cluster at ``address`` (default: a running one,
    else one started on this machine). ``progress(done,
    total, row)`` is called once the complete folders are counted (row
    None), then as each video ends."""
    options = ReconstructOptions.of(options, **settings)
    if options.overwrite:
        raise option_error("overwrite", "a batch keeps complete folders and redoes the others; remove OUT/NAME to redo a video")
    if engine not in ENGINES:
        raise option_error("engine", f"expected one of {ENGINES}, got {engine!r}")
    if progress is not None and not callable(progress):
        raise TypeError(f"progress: expected a callable progress(done, total, row) or None, got {type(progress).__name__}")
    if engine == "ray" and address is not None:
        _check_ray_address(address)
    cores = os.cpu_count() or 1
    gpus = _gpu_count() if engine == "local" and options.device in ("auto", "cuda") else 0  # cuda:N: that GPU alone
    for name, value in (("workers", workers), ("threads", threads)):
        if value is not None and not (isinstance(value, int) and not isinstance(value, bool) and value >= 1):
            raise option_error(name, f"expected a positive int or None, got {value!r}", TypeError if not isinstance(value, int) else ValueError)
    out = Path(out)
    if out.is_file():
        raise option_error("out", f"{out} is a file; expected a folder")
    pairs = list_videos(inputs, out)
    _check_against_earlier(pairs, out)
    out.mkdir(parents=True, exist_ok=True)
    rows = [BatchRow(str(video), str(folder)) for video, folder in pairs]
    todo: List[Tuple[int, BatchRow]] = []
    for i, row in enumerate(rows):
        try:
            row.frames, row.status = check_complete(row.output, viewer=options.viewer, png16=options.png16, ply=options.ply), "skipped"
            row.take_sheet(row.output)
        except ValueError:
            todo.append((i, row))
    _write_summary(out, rows)
    model = None if model is None else os.fspath(model)
    if engine == "local":
        workers = workers or max(1, gpus or min(cores // THREADS, len(todo)))
        threads = threads or max(1, cores // workers)
        results = _local(todo, model, ReconstructOptions.of(options, device="cuda") if gpus else options, workers, threads, gpus) if todo else iter(())
    else:
        results = _ray(todo, model, options, threads, address) if todo else iter(())
    done = len(rows) - len(todo)
    if progress is not None:
        progress(done, len(rows), None)
    for i, row in results:
        row.input, row.output = rows[i].input, rows[i].output  # as the user wrote them (the workers had them absolute)
        rows[i] = row
        done += 1
        _write_summary(out, rows)
        if progress is not None:
            progress(done, len(rows), row)
    return rows


def _gpu_count() -> int:
    import torch

    return torch.cuda.device_count() if torch.cuda.is_available() else 0
