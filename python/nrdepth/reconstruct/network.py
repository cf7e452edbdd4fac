"""The network the main job runs: loaded once, on its device, in the
channels-last 3D layout, with its coarse companion if it has one."""

from __future__ import annotations

import os
from typing import Any, Union

from ..checks import option_error

__all__ = ["inference_model", "networks", "load_net", "native_bfloat16", "fine_precision", "PRECISIONS"]

PRECISIONS = ("auto", "float32", "bfloat16")
"""The fine pass's arithmetic (:func:`fine_precision`)."""


def inference_model(model: Union[None, str, "os.PathLike[str]"], device: "torch.device") -> "torch.nn.Module":  # noqa: F821
    """The network :func:`reconstruct` runs: ``load_model(model)`` on
    ``device`` in the channels-last 3D layout (≈ 1.4× faster on the CPU)."""
    import torch

    from ..model.io import load_model

    net = load_model(model, device=str(device))
    for each in networks(net):
        each.to(memory_format=torch.channels_last_3d)
    return net


def networks(net: "torch.nn.Module") -> list:  # noqa: F821
    """``net`` and its coarse companion's network, if it has one."""
    companion = getattr(net, "coarse_companion", None)
    return [net] if companion is None else [net, companion[0]]


def load_net(model: Any, units: str, dev: Any) -> Any:
    """The network of ``model`` (a module, a path, or None: the shipped one, the scaled one for pixel units) on ``dev``."""
    import torch

    if model is not None and not isinstance(model, (str, os.PathLike, torch.nn.Module)):
        raise option_error("model", f"expected None, a path to model.safetensors or its folder, or a torch.nn.Module, got {type(model).__name__}",
                           TypeError)
    if isinstance(model, (str, os.PathLike)) and not os.path.exists(model):
        raise option_error("model", f"{os.fspath(model)} not found")
    if model is None and units == "pixels":
        from ..model.io import SCALED_MODEL

        model = SCALED_MODEL
    if isinstance(model, torch.nn.Module):
        net = model
        for each in networks(net):
            each.to(dev).eval()
    else:
        try:
            net = inference_model(model, dev)
        except ValueError as error:
            raise option_error("model", str(error)) from None
    if units == "pixels" and getattr(net, "depth_units", None) != "window":
        raise option_error("units", "'pixels' needs a model that learnt the relief's scale (model.json's depth_units 'window', "
                           "nrdepth train --amplitude); this one gives depth up to scale: use units='standard'")
    return net


def native_bfloat16(device: "torch.device") -> bool:  # noqa: F821
    """Whether ``device`` computes bfloat16 in hardware: CUDA, or a CPU with
    AVX512-BF16 or AMX (elsewhere oneDNN emulates it: float32 is kept, its
    speed there not measured)."""
    import torch

    if device.type == "cuda":
        return True
    probes = (getattr(torch.cpu, name, None) for name in ("_is_avx512_bf16_supported", "_is_amx_tile_supported"))
    return device.type == "cpu" and any(probe is not None and probe() for probe in probes)


def fine_precision(precision: str, device: "torch.device") -> str:  # noqa: F821
    """``precision`` (:data:`PRECISIONS`) on ``device``: "auto" resolved by :func:`native_bfloat16`."""
    if precision not in PRECISIONS:
        raise option_error("precision", f"expected one of {PRECISIONS}, got {precision!r}")
    if precision == "auto":
        return "bfloat16" if native_bfloat16(device) else "float32"
    return precision
