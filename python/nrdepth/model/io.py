"""Models by name, on disk and at work: the architectures nrdepth knows,
weights as ``model.safetensors`` with ``model.json`` beside it (architecture
name and constructor config), the shipped default model, and batched
inference.

``model.json`` is ``{"architecture": NAME, "config": {...}, ...}`` where NAME
is a key of :data:`ARCHITECTURES` (older files name the class, ``"UNet3D"``,
which is read as ``"unet3d"``); anything else in it (training loss, scores)
is carried along untouched.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any, Callable, Dict, Optional, Tuple, Union

import numpy as np
import torch
from torch import nn

from .unet import UNet3D
from .unet2p1d import UNet2p1D, UNet2p1DDeep, UNet2p1DGlobal

__all__ = ["ARCHITECTURES", "DEFAULT_MODEL", "SCALED_MODEL", "build_model", "architecture_name", "save_model", "load_model", "predict_depth", "READINGS", "resolve_device"]

ARCHITECTURES: Dict[str, Callable[..., nn.Module]] = {"unet3d": UNet3D, "unet2p1d": UNet2p1D, "unet2p1d_global": UNet2p1DGlobal, "unet2p1d_deep": UNet2p1DDeep}
"""Architecture name → constructor; every model stores its keyword arguments in ``.config``."""

DEFAULT_MODEL = Path(__file__).resolve().parent.parent / "weights" / "default.safetensors"
"""The shipped default model (weights; its architecture, training loss and
held-out scores are in ``default.json`` beside it)."""

SCALED_MODEL = DEFAULT_MODEL.with_name("scaled.safetensors")
"""The shipped model that learnt the relief's scale (``depth_units``
"window"; trained with a relief-amplitude term): what ``reconstruct(...,
units="pixels")`` uses without a model. A flat sheet comes back flat; its
MAE-SN is a little behind :data:`DEFAULT_MODEL`'s (``scaled.json``)."""


def build_model(architecture: str, **config: Any) -> nn.Module:
    """A fresh model of the named architecture (a key of :data:`ARCHITECTURES`)."""
    try:
        cls = ARCHITECTURES[architecture]
    except (KeyError, TypeError):
        raise ValueError(f"architecture: expected one of {sorted(ARCHITECTURES)}, got {architecture!r}") from None
    return cls(**config)


def architecture_name(model: nn.Module) -> str:
    """The :data:`ARCHITECTURES` name of a model (unwrapping DDP and ``torch.compile``)."""
    module = unwrap(model)
    for name, cls in ARCHITECTURES.items():
        if type(module) is cls:
            return name
    raise ValueError(f"model: expected one of the architectures {sorted(ARCHITECTURES)}, got {type(module).__name__}")


def unwrap(model: nn.Module) -> nn.Module:
    """The network inside a DistributedDataParallel or ``torch.compile`` wrapper (``model`` itself if it has none)."""
    module = getattr(model, "module", model)
    return getattr(module, "_orig_mod", module)


def resolve_device(device: str) -> torch.device:
    """``auto`` (CUDA when available), ``cpu``, ``cuda`` or ``cuda:N`` as a torch device."""
    if device == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    if not isinstance(device, str) or not (device == "cpu" or device == "cuda" or (device.startswith("cuda:") and device[5:].isdigit())):
        raise ValueError(f"device: expected auto, cpu, cuda or cuda:N, got {device!r}")
    if device.startswith("cuda") and not torch.cuda.is_available():
        raise ValueError(f"device: {device} requested but CUDA is not available here")
    return torch.device(device)


def save_model(model: nn.Module, path: Union[str, os.PathLike], extra: Optional[Dict[str, Any]] = None) -> None:
    """Weights as safetensors at ``path`` and the architecture as JSON beside
    it (``path`` with suffix ``.json``), each written atomically."""
    from safetensors.torch import save_file

    path = Path(path)
    module = unwrap(model)
    meta = {"architecture": architecture_name(module), "config": module.config, **(extra or {})}
    tmp = path.with_name(path.name + ".partial")
    save_file({k: v.detach().cpu().contiguous() for k, v in module.state_dict().items()}, str(tmp))
    os.chmod(tmp, 0o644)  # safetensors writes 0600; weights are meant to be shared and packaged
    meta_path = path.with_suffix(".json")
    meta_tmp = meta_path.with_name(meta_path.name + ".partial")
    meta_tmp.write_text(json.dumps(meta, indent=2, sort_keys=True) + "\n")
    # Each file is replaced atomically; a training run killed between the two
    # rewrites both when it resumes (nrdepth.learning.train, at the end of an epoch).
    os.replace(meta_tmp, meta_path)
    os.replace(tmp, path)


def load_model(path: Optional[Union[str, os.PathLike]] = None, device: str = "cpu") -> nn.Module:
    """The model in ``model.safetensors`` (and the ``model.json`` beside it),
    a run folder holding them, or, with ``path=None``, the default model that
    ships in the package (:data:`DEFAULT_MODEL`). The model's
    ``depth_units`` is ``model.json``'s: ``"window"`` where its output is depth
    in widths of the view window, else None (depth up to scale). Its
    ``coarse_companion`` is None, or (network, share) where ``model.json``
    names a second network for ``reconstruct``'s coarse pass (the shipped
    model's, docs/reconstruction.md). Errors name the file and what is
    wrong with it (``ValueError``)."""
    if path is not None and not isinstance(path, (str, os.PathLike)):
        raise TypeError(f"model: expected a path to model.safetensors or its folder, got {type(path).__name__}")
    return _load_model(DEFAULT_MODEL if path is None else Path(path), device, companion_allowed=True)


def _load_model(path: Path, device: str, companion_allowed: bool) -> nn.Module:
    from safetensors.torch import load_file

    if path.is_dir():
        path = path / "model.safetensors"
    meta_path = path.with_suffix(".json")
    for p in (path, meta_path):
        if not p.is_file():
            raise ValueError(f"{p}: not found (a model is model.safetensors with model.json beside it)")
    try:
        meta = json.loads(meta_path.read_text())
    except (ValueError, UnicodeDecodeError) as e:
        raise ValueError(f"{meta_path}: not valid JSON ({e})") from None
    if not isinstance(meta, dict) or not isinstance(meta.get("config"), dict):
        raise ValueError(f"{meta_path}: expected an object with 'architecture' and 'config', got {str(meta)[:80]}")
    name = meta.get("architecture")
    name = "unet3d" if name == "UNet3D" else name
    try:
        model = build_model(name, **meta["config"])
    except (TypeError, ValueError) as e:
        raise ValueError(f"{meta_path}: cannot build the model it describes ({e})") from None
    try:
        weights = load_file(str(path))
    except Exception as e:  # safetensors raises its own error types for every kind of corruption
        raise ValueError(f"{path}: not a readable safetensors file ({type(e).__name__}: {e})") from None
    try:
        model.load_state_dict(weights)
    except RuntimeError as e:
        first = str(e).strip().splitlines()[1:2] or [str(e)[:200]]
        raise ValueError(f"{path}: the weights do not fit the architecture in {meta_path.name} ({name}, {meta['config']}): {first[0].strip()}") from None
    # What the output's scale means: "window" (depth in view-window widths,
    # a model trained with a relief-amplitude term) or None (no scale).
    model.depth_units = meta.get("depth_units")
    # A tuple, not a submodule: the companion stays out of this model's state_dict and parameters.
    model.coarse_companion = None
    if meta.get("coarse_companion") is not None:
        if not companion_allowed:
            raise ValueError(f"{meta_path}: a coarse companion cannot have a companion of its own")
        model.coarse_companion = _load_companion(meta, path, meta_path, device)
    return model.to(resolve_device(device)).eval()


def _load_companion(meta: Dict[str, Any], path: Path, meta_path: Path, device: str) -> Tuple[nn.Module, float]:
    """(network, share) of ``model.json``'s ``"coarse_companion"``: ``{"model":
    a model file in the same folder, "share": its weight in (0, 1]}``, a
    second network that ``reconstruct``'s coarse pass reads beside this one
    (:func:`nrdepth.reconstruct.coarse_half`)."""
    spec = meta["coarse_companion"]
    model, share = (spec.get("model"), spec.get("share")) if isinstance(spec, dict) else (None, None)
    if not isinstance(model, str) or Path(model).name != model or isinstance(share, bool) or not isinstance(share, (int, float)) or not 0 < share <= 1:
        raise ValueError(f"{meta_path}: 'coarse_companion' expected {{\"model\": a file name beside it, \"share\": a number in (0, 1]}}, got {spec!r}")
    if meta.get("depth_units") is not None:
        raise ValueError(f"{meta_path}: a model with depth_units {meta['depth_units']!r} cannot have a coarse companion (the blend standardises the coarse pass, which sets the relief's scale)")
    companion = _load_model(path.parent / model, device, companion_allowed=False)
    if companion.depth_units is not None:
        raise ValueError(f"{path.parent / model}: a coarse companion gives depth up to scale (no depth_units), got {companion.depth_units!r}")
    return companion, float(share)


READINGS = (1, 2, 4)
"""The numbers of readings :func:`predict_depth` averages (see there)."""

# Each reading: the axes of a clip (n, T, H, W) it flips, and the sign it gives the depth read back.
_SYMMETRIES = (((), 1.0), ((-1,), 1.0), ((-2,), -1.0), ((-2, -1), -1.0))


def predict_depth(model: nn.Module, video: np.ndarray, batch_size: int = 8, device: Optional[torch.device] = None, readings: int = 1) -> np.ndarray:
    """Network depth (n, T, H/2, W/2) float32 of videos (n, T, H, W), uint8 or
    float in [0, 1]. Inputs go in channels-last 3D layout, which a model laid
    out the same way (``reconstruct``'s) runs ≈ 1.4× faster on the CPU.

    ``readings`` (1, 2 or 4) averages that many readings of each clip, each
    taken through a symmetry of the training data and mapped back: 2 adds
    the clip mirrored left-right, 4 adds both turned upside down with the
    depth negated. Under an orthographic camera an upside-down video shows
    the mirrored, negated relief lit from above again, so both symmetries
    keep the light-from-above prior and the relief's sign; they hold for a
    model trained with a light prior symmetric about image-up (every
    nrdepth default), not for one trained with lights from one side. Cost:
    ``readings`` times one reading."""
    check_readings(readings)
    total = None
    for axes, sign in _SYMMETRIES[:readings]:
        depth = _read(model, np.flip(video, axes) if axes else video, batch_size, device)
        depth = np.flip(depth, axes) if axes else depth
        total = depth if total is None else total + sign * depth
    return total if readings == 1 else total / np.float32(readings)


def check_readings(readings: Any) -> None:
    """ValueError unless ``readings`` is one of :data:`READINGS`."""
    if isinstance(readings, bool) or readings not in READINGS:
        raise ValueError(f"readings: expected one of {READINGS}, got {readings!r}")


def _read(model: nn.Module, video: np.ndarray, batch_size: int, device: Optional[torch.device]) -> np.ndarray:
    """One reading of :func:`predict_depth`."""
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
