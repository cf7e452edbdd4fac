"""Training the depth network: online generation or dataset shards, Adam with
a cosine schedule, validation MAE-SN every epoch, exact resume, metrics as
CSV (and TensorBoard when installed), data-parallel under ``torchrun``.

Every batch is a pure function of (seed, batch index): online, batch k holds
clips ``k·B .. (k+1)·B`` of the generator run ``seed``; from a dataset, a
permutation of the train split seeded by (seed, epoch). Checkpoints are
written at the end of every epoch (atomically); a run restarted on the same
folder resumes from the last one and takes the same steps it would have
taken without stopping. Under ``torchrun`` (DistributedDataParallel; gloo on
the CPU, NCCL on CUDA) rank r takes batches ``k·world + r`` and only rank 0
writes files.

Files in the run folder: ``config.json`` (this run's TrainConfig),
``last.pt`` / ``best.pt`` (full state), ``model.safetensors`` + ``model.json``
(best weights, loadable by :func:`load_model`), ``metrics.csv``.
"""

from __future__ import annotations

import csv
import hashlib
import json
import math
import os
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Dict, Iterator, Optional, Tuple, Union

import numpy as np
import torch
import torch.distributed as dist

from .generate import GeneratorConfig, generate_clips
from .losses import get_loss
from .metrics import flat_baseline, mae_sn
from .model import UNet3D

__all__ = ["TrainConfig", "train", "load_model", "save_model", "predict_depth"]

VALIDATION_SEED_OFFSET = 1_000_003


@dataclass
class TrainConfig:
    loss: str = "gbr"
    """One of nrdepth.losses.LOSSES: gbr, tr_sc, aligned, aligned_clip."""
    base: int = 16
    """Width of the network's first stage."""
    batch_size: int = 8
    steps_per_epoch: int = 500
    epochs: int = 20
    lr: float = 1e-3
    seed: int = 0
    data: Optional[str] = None
    """A dataset folder (``nrdepth generate``); None: fresh clips every step."""
    generator: GeneratorConfig = field(default_factory=GeneratorConfig)
    """Online generation config (ignored with ``data``)."""
    validation_clips: int = 64
    workers: int = 2
    device: str = "auto"
    """auto (CUDA when available), cpu, cuda or cuda:N."""
    amp: bool = True
    """bfloat16 autocast on CUDA (ignored on the CPU)."""
    compile: bool = False

    def __post_init__(self) -> None:
        get_loss(self.loss)
        for name in ("base", "batch_size", "steps_per_epoch", "epochs", "validation_clips"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ValueError(f"{name}: expected a positive int, got {value!r}")
        if not (isinstance(self.lr, (int, float)) and math.isfinite(self.lr) and self.lr > 0):
            raise ValueError(f"lr: expected a positive number, got {self.lr!r}")
        if self.workers < 0:
            raise ValueError(f"workers: expected >= 0, got {self.workers}")
        if isinstance(self.generator, dict):
            self.generator = GeneratorConfig.from_dict(self.generator)
        resolve_device(self.device)

    def as_dict(self) -> Dict[str, Any]:
        d = asdict(self)
        d["generator"] = self.generator.as_dict()
        return d


def resolve_device(device: str) -> torch.device:
    if device == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    if not isinstance(device, str) or not (device == "cpu" or device.startswith("cuda")):
        raise ValueError(f"device: expected auto, cpu, cuda or cuda:N, got {device!r}")
    if device.startswith("cuda") and not torch.cuda.is_available():
        raise ValueError(f"device: {device} requested but CUDA is not available here")
    return torch.device(device)


def to_tensors(video: np.ndarray, depth: np.ndarray) -> Tuple[torch.Tensor, torch.Tensor]:
    """uint8 video (B, T, H, W) → float (B, 1, T, H, W) in [0, 1]; depth (B, T, H, W)
    → the network's target at half resolution (B, T, H/2, W/2), 2×2 means."""
    v = torch.from_numpy(np.ascontiguousarray(video)).float().div_(255.0).unsqueeze(1)
    d = torch.nn.functional.avg_pool2d(torch.from_numpy(np.ascontiguousarray(depth)).float(), 2)
    return v, d


class OnlineBatches(torch.utils.data.Dataset):
    """Batch k: clips k·B .. (k+1)·B of the generator run (config, seed)."""

    def __init__(self, config: GeneratorConfig, seed: int, batch_size: int) -> None:
        self.config, self.seed, self.batch_size = config, seed, batch_size

    def __len__(self) -> int:
        return 2**40

    def __getitem__(self, k: int):
        clips = generate_clips(self.batch_size, seed=self.seed, config=self.config, start=k * self.batch_size)
        return to_tensors(clips.video, clips.depth)


class StoredBatches(torch.utils.data.Dataset):
    """Batch k of the train split: a permutation seeded by (seed, epoch)."""

    def __init__(self, root: str, seed: int, batch_size: int) -> None:
        from .dataset import ClipStore

        self.store = ClipStore(root, "train")
        self.seed, self.batch_size = seed, batch_size
        if len(self.store) < batch_size:
            raise ValueError(f"data: the train split has {len(self.store)} clips, fewer than batch_size {batch_size}")

    def __len__(self) -> int:
        return 2**40

    def __getitem__(self, k: int):
        per_epoch = len(self.store) // self.batch_size
        epoch, j = divmod(k, per_epoch)
        order = np.random.default_rng([self.seed, epoch]).permutation(len(self.store))
        items = [self.store[int(i)] for i in order[j * self.batch_size : (j + 1) * self.batch_size]]
        return to_tensors(np.stack([v for v, _, _ in items]), np.stack([d for _, d, _ in items]))


def validation_set(config: TrainConfig) -> Tuple[np.ndarray, np.ndarray]:
    if config.data is not None:
        from .dataset import ClipStore

        store = ClipStore(config.data, "validation")
        items = [store[i] for i in range(min(len(store), config.validation_clips))]
        return np.stack([v for v, _, _ in items]), np.stack([d for _, d, _ in items])
    clips = generate_clips(config.validation_clips, seed=config.seed + VALIDATION_SEED_OFFSET, config=config.generator)
    return clips.video, clips.depth


def predict_depth(model: torch.nn.Module, video: np.ndarray, batch_size: int = 8, device: Optional[torch.device] = None) -> np.ndarray:
    """Network depth (n, T, H/2, W/2) float32 of videos (n, T, H, W), uint8 or
    float in [0, 1]. Inputs go in channels-last 3D layout, which a model laid
    out the same way (``reconstruct``'s) runs ≈ 1.4× faster on the CPU."""
    device = device or next(model.parameters()).device
    was_training = model.training
    model.eval()
    out = []
    with torch.inference_mode():
        for i in range(0, len(video), batch_size):
            v = torch.from_numpy(np.ascontiguousarray(video[i : i + batch_size])).float()
            if video.dtype == np.uint8:
                v = v.div_(255.0)
            v = v.unsqueeze(1).to(device).contiguous(memory_format=torch.channels_last_3d)
            out.append(model(v)[:, 0].float().cpu().numpy())
    model.train(was_training)
    return np.concatenate(out)


def evaluate_depth(pred: np.ndarray, depth_half: np.ndarray) -> Dict[str, float]:
    """Mean MAE-SN (both alignments) of predictions and of the flat baseline."""
    scores: Dict[str, list] = {k: [] for k in ("frame", "first", "flat_frame", "flat_first")}
    for p, g in zip(pred, depth_half):
        scores["frame"].append(mae_sn(p, g, "frame"))
        scores["first"].append(mae_sn(p, g, "first"))
        scores["flat_frame"].append(flat_baseline(g, "frame"))
        scores["flat_first"].append(flat_baseline(g, "first"))
    return {k: float(np.mean(v)) for k, v in scores.items()}


def _atomic_save(obj: Any, path: Path) -> None:
    tmp = path.with_name(path.name + ".partial")
    torch.save(obj, tmp)
    os.replace(tmp, path)


DEFAULT_MODEL = Path(__file__).with_name("weights") / "default.safetensors"
"""The shipped default model (weights; its architecture, training loss and
held-out scores are in ``default.json`` beside it)."""


def save_model(model: torch.nn.Module, path: Union[str, os.PathLike], extra: Optional[Dict[str, Any]] = None) -> None:
    """Weights as safetensors at ``path`` and the architecture as JSON beside it."""
    from safetensors.torch import save_file

    path = Path(path)
    module = getattr(model, "module", model)
    module = getattr(module, "_orig_mod", module)
    tmp = path.with_name(path.name + ".partial")
    save_file({k: v.detach().cpu().contiguous() for k, v in module.state_dict().items()}, str(tmp))
    os.chmod(tmp, 0o644)  # safetensors writes 0600; weights are meant to be shared and packaged
    os.replace(tmp, path)
    meta = {"architecture": "UNet3D", "config": module.config, **(extra or {})}
    path.with_suffix(".json").write_text(json.dumps(meta, indent=2, sort_keys=True) + "\n")


def load_model(path: Optional[Union[str, os.PathLike]] = None, device: str = "cpu") -> UNet3D:
    """A UNet3D from ``model.safetensors`` (and the ``model.json`` beside it),
    a run folder holding them, or, with ``path=None``, the default model that
    ships in the package (:data:`DEFAULT_MODEL`)."""
    from safetensors.torch import load_file

    path = DEFAULT_MODEL if path is None else Path(path)
    if path.is_dir():
        path = path / "model.safetensors"
    meta_path = path.with_suffix(".json")
    if not path.exists() or not meta_path.exists():
        raise ValueError(f"path: expected {path} and {meta_path}")
    meta = json.loads(meta_path.read_text())
    if meta.get("architecture") != "UNet3D":
        raise ValueError(f"path: unknown architecture {meta.get('architecture')!r} in {meta_path}")
    model = UNet3D(**meta["config"])
    model.load_state_dict(load_file(str(path)))
    return model.to(resolve_device(device)).eval()


def _weights_digest(model: torch.nn.Module) -> str:
    h = hashlib.sha256()
    for _, p in sorted(getattr(model, "module", model).state_dict().items()):
        h.update(p.detach().cpu().numpy().tobytes())
    return h.hexdigest()


def _batches(data: torch.utils.data.Dataset, indices: range, workers: int) -> Iterator:
    loader = torch.utils.data.DataLoader(
        data, batch_size=None, sampler=list(indices), num_workers=workers,
        multiprocessing_context="fork" if workers > 0 else None, prefetch_factor=2 if workers > 0 else None,
    )
    return iter(loader)


def train(out: Union[str, os.PathLike], config: Optional[TrainConfig] = None, progress: bool = True, max_epochs: Optional[int] = None) -> Dict[str, Any]:
    """Train (or resume) the run in folder ``out``; returns the last epoch's
    metrics. ``max_epochs`` caps the epochs run by this call (a time budget):
    call again to continue."""
    config = TrainConfig() if config is None else config
    out = Path(out)
    distributed = dist.is_available() and "WORLD_SIZE" in os.environ and int(os.environ["WORLD_SIZE"]) > 1
    device = resolve_device(config.device)
    if distributed:
        if device.type == "cuda":
            device = torch.device("cuda", int(os.environ.get("LOCAL_RANK", 0)))
            torch.cuda.set_device(device)
        dist.init_process_group("nccl" if device.type == "cuda" else "gloo")
    rank, world = (dist.get_rank(), dist.get_world_size()) if distributed else (0, 1)
    leader = rank == 0
    if leader:
        out.mkdir(parents=True, exist_ok=True)
        saved = out / "config.json"
        if saved.exists() and json.loads(saved.read_text()) != json.loads(json.dumps(config.as_dict())):
            raise ValueError(f"out: {out} holds a run with another config; use a new folder")
        saved.write_text(json.dumps(config.as_dict(), indent=2, sort_keys=True) + "\n")

    torch.manual_seed(config.seed)
    model = UNet3D(base=config.base).to(device)
    optimiser = torch.optim.Adam(model.parameters(), lr=config.lr)
    total = config.epochs * config.steps_per_epoch
    schedule = torch.optim.lr_scheduler.LambdaLR(optimiser, lambda s: 0.5 * (1 + math.cos(math.pi * min(s, total) / total)))
    state = {"epoch": 0, "best": math.inf}
    last = out / "last.pt"
    if last.exists():
        checkpoint = torch.load(last, map_location=device, weights_only=False)
        model.load_state_dict(checkpoint["model"])
        optimiser.load_state_dict(checkpoint["optimiser"])
        schedule.load_state_dict(checkpoint["schedule"])
        state = checkpoint["state"]
    net: torch.nn.Module = model
    if distributed:
        net = torch.nn.parallel.DistributedDataParallel(model, device_ids=[device.index] if device.type == "cuda" else None)
    if config.compile:
        net = torch.compile(net)
    loss_fn = get_loss(config.loss)
    amp = config.amp and device.type == "cuda"
    data = StoredBatches(config.data, config.seed, config.batch_size) if config.data else OnlineBatches(config.generator, config.seed, config.batch_size)
    video_val, depth_val = validation_set(config) if leader else (None, None)
    depth_val_half = torch.nn.functional.avg_pool2d(torch.from_numpy(depth_val).float(), 2).numpy() if leader else None

    writer = None
    if leader:
        try:
            from torch.utils.tensorboard import SummaryWriter

            writer = SummaryWriter(str(out / "tensorboard"))
        except ImportError:
            writer = None
    summary: Dict[str, Any] = {}
    stop = config.epochs if max_epochs is None else min(config.epochs, state["epoch"] + max_epochs)
    for epoch in range(state["epoch"], stop):
        first = epoch * config.steps_per_epoch
        steps = range(first, first + config.steps_per_epoch)
        bar = _bar(len(steps), f"epoch {epoch + 1}/{config.epochs}", progress and leader)
        losses = []
        for step, (video, target) in zip(steps, _batches(data, range(first * world + rank, (first + len(steps)) * world, world), config.workers)):
            video, target = video.to(device, non_blocking=True), target.to(device, non_blocking=True)
            optimiser.zero_grad(set_to_none=True)
            with torch.autocast(device.type, dtype=torch.bfloat16, enabled=amp):
                pred = net(video)[:, 0]
            loss = loss_fn(pred.float(), target)
            loss.backward()
            optimiser.step()
            schedule.step()
            losses.append(loss.item())
            if bar is not None:
                bar.set_postfix(loss=f"{loss.item():.4g}")
                bar.update(1)
        if bar is not None:
            bar.close()
        state["epoch"] = epoch + 1
        in_sync = True
        if distributed:
            digest = _weights_digest(model)
            digests = [None] * world
            dist.all_gather_object(digests, digest)
            in_sync = len(set(digests)) == 1
        if not leader:
            continue
        scores = evaluate_depth(predict_depth(model, video_val, config.batch_size, device), depth_val_half)
        row = {"epoch": epoch + 1, "step": (epoch + 1) * config.steps_per_epoch, "lr": schedule.get_last_lr()[0],
               "train_loss": float(np.mean(losses)), "first_step_loss": losses[0], "last_step_loss": losses[-1],
               **{f"val_mae_sn_{k}": v for k, v in scores.items()}, "ranks_in_sync": in_sync}
        improved = scores["frame"] < state["best"]
        if improved:
            state["best"] = scores["frame"]
        checkpoint = {"model": model.state_dict(), "optimiser": optimiser.state_dict(), "schedule": schedule.state_dict(), "state": state}
        _atomic_save(checkpoint, last)
        if improved:
            _atomic_save(checkpoint, out / "best.pt")
            save_model(model, out / "model.safetensors", {"loss": config.loss, "validation": scores, "epoch": epoch + 1})
        # After the checkpoint: a run killed in between repeats no row on resume.
        _append_csv(out / "metrics.csv", row)
        if writer is not None:
            for k, v in row.items():
                if isinstance(v, float):
                    writer.add_scalar(k, v, row["step"])
        summary = row
    if writer is not None:
        writer.close()
    if distributed:
        dist.barrier()
        dist.destroy_process_group()
    return summary


def _append_csv(path: Path, row: Dict[str, Any]) -> None:
    new = not path.exists()
    with path.open("a", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(row))
        if new:
            w.writeheader()
        w.writerow(row)
        f.flush()
        os.fsync(f.fileno())


def _bar(total: int, desc: str, enabled: bool):
    if not enabled:
        return None
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, unit="step")

