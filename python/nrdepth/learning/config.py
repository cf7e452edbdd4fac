"""A training run's settings: :class:`TrainConfig`, checked when it is
made, saved as the run's ``config.json``, and the two recipes (the
recommended one and the paper's)."""

from __future__ import annotations

import json
import math
import os
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Dict, List, Optional, Union

import numpy as np

from ..checks import check_int, check_seed
from ..engine.generate import GeneratorConfig, observable_depth
from ..model import ARCHITECTURES
from ..model.io import resolve_device
from .evaluate import load_real
from .losses import MASKED_LOSSES, get_loss

__all__ = ["TrainConfig", "RECOMMENDED", "PAPER", "TARGETS"]

TARGETS = {
    "depth": lambda depth, params: depth,
    "observable": observable_depth,
}
"""TrainConfig.target: the training target of one clip from its depth and params."""

RECOMMENDED = {"arch": "unet2p1d_deep", "loss": "aligned_both_signed", "target": "observable", "lr": 3e-4}
"""The recipe the README recommends, what ``nrdepth train`` runs without
``--paper``: the factorised network with the deep coarse level, the
sign-aware loss on each frame and the clip, the observable target."""

PAPER = {"arch": "unet3d", "loss": "gbr", "target": "depth", "lr": 1e-3}
"""The paper's recipe (``nrdepth train --paper``), also ``TrainConfig``'s defaults."""

@dataclass
class TrainConfig:
    loss: str = "gbr"
    """One of nrdepth.learning.losses.LOSSES: gbr, tr_sc, aligned, aligned_clip,
    aligned_signed, aligned_clip_signed, aligned_both_signed."""
    arch: str = "unet3d"
    """One of nrdepth.model.ARCHITECTURES: unet3d (the paper's), unet2p1d."""
    base: Optional[int] = None
    """Width of the network's first stage (UNet3D's ``base``, UNet2p1D's
    ``width``); None: the architecture's default."""
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
    schedule: str = "cosine"
    """Learning rate over the run: ``cosine`` (from lr to 0 over all epochs)
    or ``constant`` (a campaign of open length: a resume may change ``epochs``
    and ``lr``)."""
    target: str = "depth"
    """What the loss compares the prediction with: ``depth`` (the rendered
    depth, the paper's) or ``observable`` (the depth without the surface's
    motion along the optical axis, which the video cannot show:
    :func:`nrdepth.engine.generate.observable_depth`). Validation scores the
    rendered depth either way."""
    amplitude: float = 0.0
    """Weight of :func:`nrdepth.learning.losses.relief_amplitude_loss` added to the
    loss; above 0, targets are in window widths and the model learns the
    relief's scale (``model.json``'s ``depth_units`` says ``"window"``), so
    ``reconstruct(..., units="pixels")`` can give depth in pixels and a flat
    sheet can come back flat."""
    init: Optional[str] = None
    """A model (``model.safetensors`` or its run folder) whose weights start
    a new run (a warm start; same architecture and width); ignored on
    resume."""
    real: Union[None, str, List[str]] = None
    """A real video with ground truth (``.npz``, dense or sparse:
    :func:`nrdepth.learning.evaluate.load_real`), or a list of them, reconstructed and
    scored after every epoch: a watch on how training on generated clips
    carries over to real footage, which validation cannot show. One video
    writes ``real_mae_sn_frame``, ``real_mae_sn_first``, ``real_flat_frame``
    and ``real_sign_correct`` (sparse truth: ``real_mae``,
    ``real_flat_mae``, ``real_sign_correct``) in ``metrics.csv``; several
    write the same under ``real_STEM_``, STEM each file's name. It never
    chooses the best weights (validation does), so the videos stay a fair
    test."""
    anchor: float = 0.0
    """Rate of a pull of the weights back toward the warm start's
    (``init``): after every optimiser step ``w ← w0 + (1 − lr·anchor)(w − w0)``,
    decoupled from the loss as AdamW's weight decay is, but toward the
    start instead of zero (L2-SP). A warm start that learns a new kind of
    clip drifts away from what its start read well the longer it runs; the
    pull bounds how far. Above 0 it needs ``init``, and ``lr · anchor`` < 1."""
    ema: float = 0.0
    """Decay of an exponential moving average of the weights, updated after
    every step (``w_ema ← ema·w_ema + (1 − ema)·w``); above 0, the average
    is what validation and ``--real`` score and what ``model.safetensors``
    and ``epochs/`` hold (``last.pt`` keeps both). 0.999 averages over about
    the last 1,000 steps: it smooths the step-to-step noise that a constant
    learning rate leaves in the weights."""
    rehearsal: float = 0.0
    """Share of each batch's clips drawn by the default generator
    (``GeneratorConfig()`` at ``generator``'s frames, size and grid:
    orthographic coloured noise, the recipe the CPU line learnt the real
    cloth on), the rest by ``generator``. A warm start that learns a new
    kind of clip forgets what its start read well (docs/campaign.md, "the
    cloth at scale"); rehearsal keeps the old clips in view. The share
    times ``batch_size`` is rounded to whole clips (a share that rounds to
    none, or to the whole batch, is refused); online clips only (not with
    ``data``)."""
    keep_every: int = 0
    """Also keep every N-th epoch's weights (``epochs/epoch_E.safetensors``
    and ``.json``), so that checkpoints along a curve can be scored later;
    0 keeps none."""

    def __post_init__(self) -> None:
        get_loss(self.loss)
        if self.schedule not in ("cosine", "constant"):
            raise ValueError(f"schedule: expected 'cosine' or 'constant', got {self.schedule!r}")
        if self.target not in TARGETS:
            raise ValueError(f"target: expected one of {sorted(TARGETS)}, got {self.target!r}")
        if self.real is not None:
            paths = [os.fspath(p) for p in (self.real if isinstance(self.real, (list, tuple)) else [self.real])]
            if not paths or len({Path(p).stem for p in paths}) != len(paths):
                raise ValueError(f"real: expected one or more .npz files with different names, got {paths}")
            self.real = paths[0] if len(paths) == 1 else paths
            for path in paths:
                try:
                    load_real(path)  # refused now, not after the first epoch
                except ValueError as e:
                    raise ValueError(f"real: {e}") from None
        if isinstance(self.ema, bool) or not (isinstance(self.ema, (int, float, np.floating)) and 0.0 <= self.ema < 1.0):
            raise ValueError(f"ema: expected a decay in [0, 1) (0: no average), got {self.ema!r}")
        self.ema = float(self.ema)
        self.keep_every = check_int("keep_every", self.keep_every)
        if self.keep_every < 0:
            raise ValueError(f"keep_every: expected >= 0 (0: keep no epoch's weights), got {self.keep_every}")
        if self.init is not None:
            self.init = os.fspath(self.init)
            if not os.path.exists(self.init):
                raise ValueError(f"init: not found: {self.init} (expected model.safetensors or its run folder)")
        if self.arch not in ARCHITECTURES:
            raise ValueError(f"arch: expected one of {sorted(ARCHITECTURES)}, got {self.arch!r}")
        for name in ("batch_size", "steps_per_epoch", "epochs", "validation_clips") + (("base",) if self.base is not None else ()):
            value = check_int(name, getattr(self, name))
            if value < 1:
                raise ValueError(f"{name}: expected a positive int, got {value!r}")
            setattr(self, name, value)
        if isinstance(self.lr, bool) or not (isinstance(self.lr, (int, float, np.floating)) and math.isfinite(self.lr) and self.lr > 0):
            raise ValueError(f"lr: expected a positive number, got {self.lr!r}")
        self.lr = float(self.lr)
        if isinstance(self.amplitude, bool) or not (isinstance(self.amplitude, (int, float, np.floating)) and math.isfinite(self.amplitude) and self.amplitude >= 0):
            raise ValueError(f"amplitude: expected a weight >= 0, got {self.amplitude!r}")
        self.amplitude = float(self.amplitude)
        if isinstance(self.anchor, bool) or not (isinstance(self.anchor, (int, float, np.floating)) and math.isfinite(self.anchor) and self.anchor >= 0):
            raise ValueError(f"anchor: expected a rate >= 0 (0: no pull), got {self.anchor!r}")
        self.anchor = float(self.anchor)
        if self.anchor > 0 and self.init is None:
            raise ValueError("anchor: a pull toward the warm start needs init (the weights to pull toward)")
        if self.lr * self.anchor >= 1:
            raise ValueError(f"anchor: expected lr · anchor < 1 (a step's pull is that share of the way back), got {self.lr} · {self.anchor}")
        self.seed = check_seed("seed", self.seed)
        self.workers = check_int("workers", self.workers)
        if self.workers < 0:
            raise ValueError(f"workers: expected >= 0, got {self.workers}")
        if isinstance(self.generator, dict):
            self.generator = GeneratorConfig.from_dict(self.generator)
        if not isinstance(self.generator, GeneratorConfig):
            raise TypeError(f"generator: expected a GeneratorConfig, got {type(self.generator).__name__}")
        if self.generator.backdrop_probability > 0 and (self.loss not in MASKED_LOSSES or self.amplitude > 0):
            raise ValueError(f"loss: backdrop clips have no depth off the sheet; they need a loss of {', '.join(MASKED_LOSSES)} "
                             f"and no amplitude term, got {self.loss!r} with amplitude {self.amplitude}")
        if isinstance(self.rehearsal, bool) or not (isinstance(self.rehearsal, (int, float, np.floating)) and 0.0 <= self.rehearsal < 1.0):
            raise ValueError(f"rehearsal: expected a share of each batch in [0, 1) (0: none), got {self.rehearsal!r}")
        self.rehearsal = float(self.rehearsal)
        if self.rehearsal > 0 and not 1 <= self.rehearsed_clips < self.batch_size:
            raise ValueError(f"rehearsal: {self.rehearsal:g} of batch_size {self.batch_size} rounds to {self.rehearsed_clips} clips; "
                             f"expected between 1 and {self.batch_size - 1}")
        if self.rehearsal > 0 and self.data is not None:
            raise ValueError("rehearsal: draws clips online; it cannot join a dataset (data)")
        if self.data is not None:
            self.data = os.fspath(self.data)
            if not os.path.isdir(self.data):
                raise ValueError(f"data: not a dataset folder: {self.data}")
        resolve_device(self.device)

    @property
    def rehearsed_clips(self) -> int:
        """Clips of each batch drawn by the default generator (:attr:`rehearsal`)."""
        return int(round(self.rehearsal * self.batch_size))

    def model_config(self) -> Dict[str, Any]:
        """The constructor arguments of this run's network."""
        if self.base is None:
            return {}
        return {"base": self.base} if self.arch == "unet3d" else {"width": self.base}

    def as_dict(self) -> Dict[str, Any]:
        d = asdict(self)
        d["generator"] = self.generator.as_dict()
        return d


    def resumable_as(self, saved: Dict[str, Any]) -> bool:
        """Whether a run saved with config ``saved`` (a dict) may continue
        under this config: the same but for fields that do not change what
        is computed (workers, device; init, which only starts a run; real and
        keep_every, which only watch it) and,
        with a constant schedule, epochs (it only moves the end) and lr (a
        campaign steps it down by hand)."""
        free = ("workers", "device", "init", "real", "keep_every") + (("epochs", "lr") if self.schedule == "constant" else ())
        mine = json.loads(json.dumps(self.as_dict()))
        saved = {"target": "depth", "amplitude": 0.0, "ema": 0.0, "anchor": 0.0, "rehearsal": 0.0, **saved}  # runs saved before these options had their defaults
        try:  # generator fields added since take their defaults
            saved["generator"] = json.loads(json.dumps(GeneratorConfig.from_dict(saved["generator"]).as_dict()))
        except (KeyError, TypeError, ValueError):
            pass  # compared as saved
        return {k: v for k, v in mine.items() if k not in free} == {k: v for k, v in saved.items() if k not in free}
