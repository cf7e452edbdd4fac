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

import copy
import csv
import dataclasses
import hashlib
import json
import math
import os
import time
from pathlib import Path
from typing import Any, Dict, Iterator, Optional, Tuple, Union

import numpy as np
import torch
import torch.distributed as dist

from ..engine.dataset import ClipStore
from ..engine.generate import GeneratorConfig, generate_clips, window_widths
from ..model import build_model
from ..model.io import load_model, predict_depth, resolve_device, save_model
from ..scores.metrics import flat_baseline, mae_sn, sign_rates
from .config import TARGETS, TrainConfig
from .evaluate import load_real, relief_ratio, score_real
from .losses import get_loss, relief_amplitude_loss

__all__ = ["train", "targets", "validation_set", "evaluate_depth"]

VALIDATION_SEED_OFFSET = 1_000_003

REHEARSAL_SEED_OFFSET = 2_000_003
"""The rehearsed clips' run is the run's seed plus this: apart from its own clips and its validation clips."""

CALIBRATION_CLIPS = 32


def targets(name: str, depth: np.ndarray, params: list, window_units: bool = False) -> np.ndarray:
    """The training targets (B, T, H, W) of a batch's depths and params; in
    window widths with ``window_units`` (else in world units)."""
    # "depth" is the rendered depth itself: no per-clip copy.
    out = depth if name == "depth" else np.stack([TARGETS[name](d, p) for d, p in zip(depth, params)])
    return out / window_widths(params)[:, None, None, None] if window_units else out


def to_tensors(video: np.ndarray, depth: np.ndarray) -> Tuple[torch.Tensor, torch.Tensor]:
    """uint8 video (B, T, H, W) → float (B, 1, T, H, W) in [0, 1]; depth (B, T, H, W)
    → the network's target at half resolution (B, T, H/2, W/2), 2×2 means."""
    v = torch.from_numpy(np.ascontiguousarray(video)).float().div_(255.0).unsqueeze(1)
    d = torch.nn.functional.avg_pool2d(torch.from_numpy(np.ascontiguousarray(depth)).float(), 2)
    return v, d


class OnlineBatches(torch.utils.data.Dataset):
    """Batch k: clips k·B .. (k+1)·B of the generator run (config, seed);
    with ``rehearsed`` = R clips of each batch rehearsed, clips k·(B − R) ..
    (k+1)·(B − R) of that run, then clips k·R .. (k+1)·R of the default
    generator's run (seed + :data:`REHEARSAL_SEED_OFFSET`) at the same
    frames, size and grid."""

    def __init__(self, config: GeneratorConfig, seed: int, batch_size: int, target: str = "depth", window_units: bool = False,
                 rehearsed: int = 0) -> None:
        self.config, self.seed, self.batch_size, self.target, self.window_units = config, seed, batch_size, target, window_units
        self.rehearsed = rehearsed
        self.rehearsal = dataclasses.replace(GeneratorConfig(), frames=config.frames, size=config.size, grid=config.grid)

    def __len__(self) -> int:
        return 2**40

    def __getitem__(self, k: int):
        fresh = self.batch_size - self.rehearsed
        clips = [generate_clips(fresh, seed=self.seed, config=self.config, start=k * fresh)]
        if self.rehearsed:
            clips.append(generate_clips(self.rehearsed, seed=self.seed + REHEARSAL_SEED_OFFSET, config=self.rehearsal, start=k * self.rehearsed))
        depth = np.concatenate([targets(self.target, c.depth, c.params, self.window_units) for c in clips])
        return to_tensors(np.concatenate([c.video for c in clips]), depth)


class StoredBatches(torch.utils.data.Dataset):
    """Batch k of the train split: a permutation seeded by (seed, epoch)."""

    def __init__(self, root: str, seed: int, batch_size: int, target: str = "depth", window_units: bool = False) -> None:
        self.store = ClipStore(root, "train")
        self.seed, self.batch_size, self.target, self.window_units = seed, batch_size, target, window_units
        if len(self.store) < batch_size:
            raise ValueError(f"data: the train split has {len(self.store)} clips, fewer than batch_size {batch_size}")

    def __len__(self) -> int:
        return 2**40

    def __getitem__(self, k: int):
        per_epoch = len(self.store) // self.batch_size
        epoch, j = divmod(k, per_epoch)
        order = np.random.default_rng([self.seed, epoch]).permutation(len(self.store))
        items = [self.store[int(i)] for i in order[j * self.batch_size : (j + 1) * self.batch_size]]
        depth = targets(self.target, np.stack([d for _, d, _ in items]), [p for _, _, p in items], self.window_units)
        return to_tensors(np.stack([v for v, _, _ in items]), depth)


def validation_set(config: TrainConfig) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Validation videos, depths (world units) and window widths."""
    if config.data is not None:
        store = ClipStore(config.data, "validation")
        if len(store) == 0:
            raise ValueError(f"data: the validation split of {config.data} is empty (it is 10 % of the clips, rounded down: write at least 10)")
        items = [store[i] for i in range(min(len(store), config.validation_clips))]
        return np.stack([v for v, _, _ in items]), np.stack([d for _, d, _ in items]), window_widths([p for _, _, p in items])
    clips = generate_clips(config.validation_clips, seed=config.seed + VALIDATION_SEED_OFFSET, config=config.generator)
    return clips.video, clips.depth, window_widths(clips.params)


def evaluate_depth(pred: np.ndarray, depth_half: np.ndarray) -> Dict[str, float]:
    """Mean MAE-SN (both alignments) of predictions and of the flat baseline,
    the sign-correct rate (frames) and the in-clip flip rate (clips)."""
    scores: Dict[str, list] = {k: [] for k in ("frame", "first", "flat_frame", "flat_first", "sign_correct", "flip")}
    for p, g in zip(pred, depth_half):
        mask = None if np.isfinite(g).all() else np.isfinite(g)  # backdrop clips: scored on the sheet
        scores["frame"].append(mae_sn(p, g, "frame", mask=mask))
        scores["first"].append(mae_sn(p, g, "first", mask=mask))
        scores["flat_frame"].append(flat_baseline(g, "frame", mask=mask))
        scores["flat_first"].append(flat_baseline(g, "first", mask=mask))
        for k, v in sign_rates(p, g, mask=mask).items():
            scores[k].append(v)
    return {k: float(np.mean(v)) for k, v in scores.items()}


def _atomic_save(obj: Any, path: Path) -> None:
    tmp = path.with_name(path.name + ".partial")
    torch.save(obj, tmp)
    os.replace(tmp, path)


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
    # The data is opened (and refused if bad) before anything is written.
    window_units = config.amplitude > 0
    data = (StoredBatches(config.data, config.seed, config.batch_size, config.target, window_units) if config.data
            else OnlineBatches(config.generator, config.seed, config.batch_size, config.target, window_units, config.rehearsed_clips))
    video_val, depth_val, widths_val = validation_set(config) if leader else (None, None, None)
    warm_start = _warm_start(config) if config.init is not None and (config.anchor > 0 or not (out / "last.pt").exists()) else None
    depth_val_half = torch.nn.functional.avg_pool2d(torch.from_numpy(depth_val).float(), 2).numpy() if leader else None
    reals = {}
    if leader and config.real is not None:
        paths = [config.real] if isinstance(config.real, str) else config.real
        reals = {("real_" if len(paths) == 1 else f"real_{Path(p).stem}_"): load_real(p) for p in paths}
    if leader:
        if out.is_file():
            raise ValueError(f"out: {out} is a file; expected a run folder")
        saved = out / "config.json"
        if saved.exists():
            try:
                previous = json.loads(saved.read_text())
            except ValueError as e:
                raise ValueError(f"{saved}: not valid JSON ({e})") from None
            if not config.resumable_as(previous):
                raise ValueError(f"out: {out} holds a run with another config; use a new folder (a resume may change workers and device and, with a constant schedule, epochs and lr)")
        out.mkdir(parents=True, exist_ok=True)
        _atomic_write_text(saved, json.dumps(config.as_dict(), indent=2, sort_keys=True) + "\n")

    torch.manual_seed(config.seed)
    model = build_model(config.arch, **config.model_config()).to(device)
    if warm_start is not None:
        model.load_state_dict(warm_start, strict=False)  # _warm_start checked that theirs ⊆ ours
    # What the anchor pulls toward (a resume reloads it from init): the warm start's parameters.
    anchored = [(p, warm_start[name].to(device)) for name, p in model.named_parameters() if name in warm_start] if config.anchor > 0 else []
    # The weights that are scored and saved: the moving average, or the model itself.
    averaged = _frozen_copy(model) if config.ema > 0 else model
    optimiser = torch.optim.Adam(model.parameters(), lr=config.lr)
    total = config.epochs * config.steps_per_epoch
    if config.schedule == "cosine":
        schedule = torch.optim.lr_scheduler.LambdaLR(optimiser, lambda s: 0.5 * (1 + math.cos(math.pi * min(s, total) / total)))
    else:
        schedule = torch.optim.lr_scheduler.LambdaLR(optimiser, lambda s: 1.0)
    state: Dict[str, Any] = {"epoch": 0, "best": math.inf, "seconds": 0.0}
    last = out / "last.pt"
    if last.exists():
        checkpoint = _load_checkpoint(last, device)
        model.load_state_dict(checkpoint["model"])
        if config.ema > 0:
            averaged.load_state_dict(checkpoint["ema"])
        optimiser.load_state_dict(checkpoint["optimiser"])
        schedule.load_state_dict(checkpoint["schedule"])
        if config.schedule == "constant":  # lr may have been stepped down for this resume
            schedule.base_lrs = [config.lr for _ in schedule.base_lrs]
            for group in optimiser.param_groups:
                group["lr"] = config.lr
        state = {"seconds": 0.0, **checkpoint["state"]}
        if leader and "row" in checkpoint:
            # A run killed after last.pt but before the epoch's other files
            # finishes them now, from the checkpoint: the same bytes.
            _finish_epoch(out, averaged, checkpoint, config)
    net: torch.nn.Module = model
    if distributed:
        net = torch.nn.parallel.DistributedDataParallel(model, device_ids=[device.index] if device.type == "cuda" else None)
    if config.compile:
        net = torch.compile(net)
    loss_fn = get_loss(config.loss)
    amp = config.amp and device.type == "cuda"

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
        started = time.perf_counter()
        for step, (video, target) in zip(steps, _batches(data, range(first * world + rank, (first + len(steps)) * world, world), config.workers)):
            video, target = video.to(device, non_blocking=True), target.to(device, non_blocking=True)
            optimiser.zero_grad(set_to_none=True)
            with torch.autocast(device.type, dtype=torch.bfloat16, enabled=amp):
                pred = net(video)[:, 0]
            loss = loss_fn(pred.float(), target)
            if window_units:
                loss = loss + config.amplitude * relief_amplitude_loss(pred.float(), target)
            loss.backward()
            optimiser.step()
            if anchored:
                with torch.no_grad():
                    pull = optimiser.param_groups[0]["lr"] * config.anchor
                    for p, start in anchored:
                        p.lerp_(start, pull)
            schedule.step()
            if config.ema > 0:
                _update_average(averaged, model, config.ema)
            losses.append(loss.item())
            if bar is not None:
                bar.set_postfix(loss=f"{loss.item():.4g}")
                bar.update(1)
        if bar is not None:
            bar.close()
        state["epoch"] = epoch + 1
        state["seconds"] += time.perf_counter() - started
        in_sync = True
        if distributed:
            digest = _weights_digest(model)
            digests = [None] * world
            dist.all_gather_object(digests, digest)
            in_sync = len(set(digests)) == 1
        if not leader:
            continue
        pred_val = predict_depth(averaged, video_val, config.batch_size, device)
        scores = evaluate_depth(pred_val, depth_val_half)
        if window_units:
            scores["relief_ratio"] = relief_ratio(pred_val, depth_val_half / widths_val[:, None, None, None])
        real_columns = {}
        for prefix, real in reals.items():
            real_columns.update({prefix + ("mae_sn_" + k if k in ("frame", "first") else k): v for k, v in score_real(averaged, real, device).items()})
        row = {"epoch": epoch + 1, "step": (epoch + 1) * config.steps_per_epoch,
               "clips_seen": (epoch + 1) * config.steps_per_epoch * config.batch_size * world,
               "train_seconds": round(state["seconds"], 1), "lr": schedule.get_last_lr()[0],
               "train_loss": float(np.mean(losses)), "first_step_loss": losses[0], "last_step_loss": losses[-1],
               **{_column(k): v for k, v in scores.items()}, **real_columns,
               "ranks_in_sync": in_sync}
        improved = scores["frame"] < state["best"]
        if improved:
            state["best"] = scores["frame"]
        checkpoint = {"model": model.state_dict(), **({"ema": averaged.state_dict()} if config.ema > 0 else {}),
                      "optimiser": optimiser.state_dict(), "schedule": schedule.state_dict(), "state": state,
                      "row": row, "improved": improved, "scores": scores}
        _atomic_save(checkpoint, last)
        _finish_epoch(out, averaged, checkpoint, config)
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


def _frozen_copy(model: torch.nn.Module) -> torch.nn.Module:
    """A copy of ``model`` that no optimiser or autograd touches: the moving average's home."""
    average = copy.deepcopy(model)
    for p in average.parameters():
        p.requires_grad_(False)
    return average


@torch.no_grad()
def _update_average(average: torch.nn.Module, model: torch.nn.Module, decay: float) -> None:
    """``average ← decay·average + (1 − decay)·model``, tensor by tensor (buffers too)."""
    for a, w in zip(average.state_dict().values(), model.state_dict().values()):
        if a.is_floating_point():
            a.lerp_(w, 1.0 - decay)
        else:
            a.copy_(w)


def _column(score: str) -> str:
    """metrics.csv's column of a validation score: ``val_…``."""
    return f"val_mae_sn_{score}" if score in ("frame", "first", "flat_frame", "flat_first") else f"val_{score}"


def _warm_start(config: TrainConfig) -> Dict[str, torch.Tensor]:
    """The weights of ``config.init``, refused unless they fit this run's
    network: every tensor of theirs is one of the network's, with its shape.
    The network's others keep their (seeded) initialisation: a module added
    to an architecture (``unet2p1d_global``'s temporal context,
    ``unet2p1d_deep``'s coarse blocks, which start as the identity)
    warm-starts from the architecture without it. A run that learns the
    relief's scale (``amplitude`` > 0) from a model that did not has the
    model's linear head divided by its relief ratio on
    ``CALIBRATION_CLIPS`` validation clips: the same depths up to scale, at
    the right scale on average, so the amplitude term starts small."""
    model = load_model(config.init, device="cpu")
    theirs = model.state_dict()
    mine = build_model(config.arch, **config.model_config()).state_dict()
    if not theirs.keys() <= mine.keys() or any(mine[k].shape != theirs[k].shape for k in theirs):
        raise ValueError(f"init: {config.init} holds another network than this run's {config.arch} {config.model_config() or '(default width)'}")
    if config.amplitude > 0 and model.depth_units != "window":
        clips = generate_clips(CALIBRATION_CLIPS, seed=config.seed + VALIDATION_SEED_OFFSET, config=config.generator)
        truth = torch.nn.functional.avg_pool2d(torch.from_numpy(clips.depth).float(), 2).numpy() / window_widths(clips.params)[:, None, None, None]
        ratio = relief_ratio(predict_depth(model, clips.video), truth)
        theirs = {k: v / ratio if k.startswith("head.") else v for k, v in theirs.items()}
    return theirs


def _load_checkpoint(path: Path, device: torch.device) -> Dict[str, Any]:
    try:
        checkpoint = torch.load(path, map_location=device, weights_only=False)
    except Exception as e:  # torch raises many types for a damaged file
        raise ValueError(f"{path}: not a readable checkpoint ({type(e).__name__}: {e}); remove it to restart the run") from None
    if not isinstance(checkpoint, dict) or not {"model", "optimiser", "schedule", "state"} <= set(checkpoint):
        raise ValueError(f"{path}: not an nrdepth checkpoint; remove it to restart the run")
    return checkpoint


def _finish_epoch(out: Path, model: torch.nn.Module, checkpoint: Dict[str, Any], config: TrainConfig) -> None:
    """Every file an epoch writes after ``last.pt``, from its checkpoint;
    idempotent, so a resume after a kill at any point redoes what is missing
    and gives the bytes an uninterrupted run gives."""
    row, epoch = checkpoint["row"], checkpoint["row"]["epoch"]
    units = {"depth_units": "window"} if config.amplitude > 0 else {}
    meta = {"loss": config.loss, "validation": checkpoint["scores"], "epoch": epoch, **units}
    if checkpoint["improved"]:
        _atomic_save(checkpoint, out / "best.pt")
        save_model(model, out / "model.safetensors", meta)
    if config.keep_every and epoch % config.keep_every == 0:
        (out / "epochs").mkdir(exist_ok=True)
        save_model(model, out / "epochs" / f"epoch_{epoch}.safetensors", meta)
    _write_metrics_row(out / "metrics.csv", row)


def _write_metrics_row(path: Path, row: Dict[str, Any]) -> None:
    """Rows of earlier epochs kept, this epoch's written once (the file is
    rewritten atomically, so a kill leaves the old file or the new one)."""
    rows = []
    if path.exists():
        with path.open(newline="") as f:
            rows = [r for r in csv.DictReader(f) if r.get("epoch") and int(r["epoch"]) < row["epoch"]]
    fields = list(row) + [k for r in rows for k in r if k not in row]
    fields = list(dict.fromkeys(fields))
    tmp = path.with_name(path.name + ".partial")
    with tmp.open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=fields)
        w.writeheader()
        w.writerows(rows + [row])
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


def _atomic_write_text(path: Path, text: str) -> None:
    tmp = path.with_name(path.name + ".partial")
    tmp.write_text(text)
    os.replace(tmp, path)


def _bar(total: int, desc: str, enabled: bool):
    if not enabled:
        return None
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, unit="step")

