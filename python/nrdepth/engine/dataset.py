"""Sharded clip datasets on disk (HDF5) and a random-access reader.

Layout of a dataset folder::

    manifest.json        config, seed, clip count, shard size, split, version
    shard-00000.h5       clips [0, S): video u8 (m, T, H, W), depth f32 (m, T, H, W),
    shard-00001.h5       params (m,) JSON strings; chunked one clip per chunk
    ...

Shard k holds clips ``[k·S, min((k+1)·S, clips))`` and, like every clip, is a
pure function of (config, seed): any number of processes can write disjoint
shards (``shard=(i, N)`` takes the shards k with k mod N = i). A shard is
written under a temporary name and renamed when complete, so an interrupted
run leaves no truncated shard and re-running skips the finished ones. Memory
stays bounded: clips are generated ``batch`` at a time. The split is the
paper's 80/10/10 by clip index: train, validation, test.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any, Dict, Iterator, Optional, Tuple, Union

import numpy as np

from .. import __version__
from ..checks import check_int, check_seed
from .generate import GeneratorConfig, generate_clips

__all__ = ["write_dataset", "ClipStore", "SPLITS"]

SPLITS = ("train", "validation", "test")
MANIFEST = "manifest.json"
FORMAT = 1


def shard_name(k: int) -> str:
    return f"shard-{k:05d}.h5"


def split_ranges(clips: int) -> Dict[str, Tuple[int, int]]:
    """The 80/10/10 split of clip indices [0, clips) into contiguous ranges."""
    train = clips * 8 // 10
    validation = train + clips // 10
    return {"train": (0, train), "validation": (train, validation), "test": (validation, clips)}


def _write_json_atomic(path: Path, data: Dict[str, Any]) -> None:
    tmp = path.with_name(path.name + ".partial")
    tmp.write_text(json.dumps(data, indent=2, sort_keys=True) + "\n")
    os.replace(tmp, path)


def _manifest(clips: int, seed: int, config: GeneratorConfig, shard_size: int) -> Dict[str, Any]:
    return {
        "format": FORMAT,
        "nrdepth": __version__,
        "clips": clips,
        "seed": seed,
        "shard_size": shard_size,
        "shards": -(-clips // shard_size),
        "split": {k: list(v) for k, v in split_ranges(clips).items()},
        "config": config.as_dict(),
    }


def write_dataset(
    out: Union[str, os.PathLike],
    clips: int,
    seed: int = 0,
    config: Optional[GeneratorConfig] = None,
    shard_size: int = 1024,
    shard: Tuple[int, int] = (0, 1),
    batch: int = 64,
    progress: bool = True,
) -> Path:
    """Write (or finish) the dataset folder ``out``; returns the manifest path.

    Re-running with the same arguments skips complete shards; a folder holding
    a different run (config, seed, clips or shard size) is refused.
    """
    import h5py

    # Everything is validated before the first byte is written.
    config = GeneratorConfig() if config is None else config
    if not isinstance(config, GeneratorConfig):
        raise TypeError(f"config: expected a GeneratorConfig or None, got {type(config).__name__}")
    clips, shard_size, batch = (_positive(name, v) for name, v in (("clips", clips), ("shard_size", shard_size), ("batch", batch)))
    seed = check_seed("seed", seed)
    try:
        index, count = (check_int("shard", v) for v in shard)
    except (TypeError, ValueError):
        raise ValueError(f"shard: expected (i, N) with 0 <= i < N, got {shard!r}") from None
    if not 0 <= index < count:
        raise ValueError(f"shard: expected (i, N) with 0 <= i < N, got {shard!r}")
    out = Path(out)
    if out.is_file():
        raise ValueError(f"out: {out} is a file; expected a dataset folder")
    manifest = _manifest(clips, seed, config, shard_size)
    path = out / MANIFEST
    out.mkdir(parents=True, exist_ok=True)
    if path.exists():
        existing = _read_manifest(path)
        expected = json.loads(json.dumps(manifest))  # tuples become lists, as on disk
        keys = ("format", "clips", "seed", "shard_size")
        try:  # generator fields added since the folder was written take their defaults
            same_config = json.loads(json.dumps(GeneratorConfig.from_dict(existing["config"]).as_dict())) == expected["config"]
        except (TypeError, ValueError):
            same_config = False
        if not same_config or any(existing.get(k) != expected[k] for k in keys):
            raise ValueError(f"out: {out} holds a different dataset (config, seed, clips or shard size differ); use a new folder")
    else:
        _write_json_atomic(path, manifest)

    todo = [k for k in range(manifest["shards"]) if k % count == index and not _shard_complete(out / shard_name(k), min(shard_size, clips - k * shard_size))]
    total = sum(min(shard_size, clips - k * shard_size) for k in todo)
    bar = _Bar(total, progress)
    for k in todo:
        first, last = k * shard_size, min((k + 1) * shard_size, clips)
        final = out / shard_name(k)
        tmp = final.with_name(final.name + ".partial")
        m, shape = last - first, (config.frames, config.size, config.size)
        with h5py.File(tmp, "w", track_order=False) as f:
            f.attrs["first_clip"] = first
            f.attrs["clips"] = m
            video = f.create_dataset("video", (m, *shape), dtype=np.uint8, chunks=(1, *shape), track_times=False)
            depth = f.create_dataset("depth", (m, *shape), dtype=np.float32, chunks=(1, *shape), track_times=False)
            params = f.create_dataset("params", (m,), dtype=h5py.string_dtype(), track_times=False)
            for start in range(first, last, batch):
                n = min(batch, last - start)
                data = generate_clips(n, seed=seed, config=config, start=start)
                video[start - first : start - first + n] = data.video
                depth[start - first : start - first + n] = data.depth
                params[start - first : start - first + n] = [json.dumps(p, sort_keys=True) for p in data.params]
                bar.update(n)
        os.replace(tmp, final)
    bar.close()
    return path


def _positive(name: str, value: Any) -> int:
    value = check_int(name, value)
    if value < 1:
        raise ValueError(f"{name}: expected a positive integer, got {value}")
    return value


def _read_manifest(path: Path) -> Dict[str, Any]:
    try:
        manifest = json.loads(path.read_text())
    except (ValueError, UnicodeDecodeError) as e:
        raise ValueError(f"{path}: not valid JSON ({e}); is it an nrdepth dataset?") from None
    missing = [k for k in ("format", "clips", "seed", "shard_size", "split", "config") if not isinstance(manifest, dict) or k not in manifest]
    if missing:
        raise ValueError(f"{path}: not an nrdepth dataset manifest (missing {', '.join(missing)})")
    return manifest


def _shard_complete(path: Path, clips: int) -> bool:
    """Whether the shard file exists and holds its ``clips`` clips (a damaged
    or truncated file counts as missing, and is written again)."""
    import h5py

    if not path.exists():
        return False
    try:
        with h5py.File(path, "r") as f:
            return int(f.attrs["clips"]) == clips and all(f[k].shape[0] == clips for k in ("video", "depth", "params"))
    except (OSError, KeyError, ValueError):
        return False


class _Bar:
    """tqdm when available and wanted; otherwise silent."""

    def __init__(self, total: int, enabled: bool) -> None:
        self._bar = None
        if enabled:
            try:
                from tqdm import tqdm

                self._bar = tqdm(total=total, unit="clip", smoothing=0.1)
            except ImportError:  # pragma: no cover - tqdm is a dependency
                pass

    def update(self, n: int) -> None:
        if self._bar is not None:
            self._bar.update(n)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()


class ClipStore:
    """Random access to the clips of a dataset folder, optionally one split.

    ``store[i]`` is ``(video u8 (T, H, W), depth f32 (T, H, W), params dict)``
    of the i-th clip of the split. Shard files are opened lazily and reopened
    after a fork, so a store can be handed to DataLoader workers.
    """

    def __init__(self, root: Union[str, os.PathLike], split: Optional[str] = None) -> None:
        self.root = Path(root)
        path = self.root / MANIFEST
        if not path.exists():
            raise ValueError(f"root: no {MANIFEST} in {self.root}; is it an nrdepth dataset?")
        self.manifest: Dict[str, Any] = _read_manifest(path)
        if split is not None and split not in SPLITS:
            raise ValueError(f"split: expected one of {SPLITS} or None, got {split!r}")
        self.split = split
        self.first, self.last = self.manifest["split"][split] if split else (0, self.manifest["clips"])
        self.config = GeneratorConfig.from_dict(self.manifest["config"])
        self._files: Dict[int, Any] = {}
        self._pid = os.getpid()

    def __len__(self) -> int:
        return self.last - self.first

    def clip_index(self, i: int) -> int:
        """Global clip index of the i-th clip of this store."""
        if isinstance(i, bool) or not isinstance(i, (int, np.integer)):
            raise TypeError(f"index: expected an int, got {type(i).__name__}")
        i = int(i)
        if not -len(self) <= i < len(self):
            raise IndexError(f"clip {i} out of range for {len(self)} clips")
        return self.first + (i % len(self))

    def _shard(self, k: int):
        import h5py

        if os.getpid() != self._pid:
            self._files, self._pid = {}, os.getpid()
        if k not in self._files:
            path = self.root / shard_name(k)
            if not path.exists():
                raise FileNotFoundError(f"{path} is missing: run `nrdepth generate` again on {self.root} to finish the dataset")
            try:
                self._files[k] = h5py.File(path, "r")
            except OSError as e:
                raise ValueError(f"{path}: not a readable shard ({e}); delete it and run `nrdepth generate` again on {self.root}") from None
        return self._files[k]

    def __getitem__(self, i: int) -> Tuple[np.ndarray, np.ndarray, Dict[str, Any]]:
        g = self.clip_index(i)
        k, j = divmod(g, self.manifest["shard_size"])
        f = self._shard(k)
        return f["video"][j], f["depth"][j], json.loads(f["params"][j])

    def __iter__(self) -> Iterator[Tuple[np.ndarray, np.ndarray, Dict[str, Any]]]:
        for i in range(len(self)):
            yield self[i]

    def close(self) -> None:
        for f in self._files.values():
            f.close()
        self._files = {}
