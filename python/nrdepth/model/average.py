"""Weight averages of models (a "model soup", Wortsman et al., ICML 2022):
θ = Σᵢ wᵢ θᵢ over models of one lineage, one trained on from another.

Models fine-tuned from a common ancestor usually lie in one basin of the
loss, where the average of their weights is itself a good model, and
often better than the straight line between their scores. nrdepth ships
one: the default model is a weighted average of the CPU campaign's epoch 178
and the GPU-trained ``unet2p1d_deep`` (docs/learning.md, "The shipped model").

Architectures that extend one another average too. ``unet2p1d_deep`` is
``unet2p1d`` plus residual blocks that start as the identity (their temporal
convolution at zero; ``unet2p1d_global``'s temporal context likewise, its
fusion at zero): such modules name that layer in ``ZERO_START``. A model
without them enters the average as the same function in the larger
architecture: the zero-start layer at zero, so its share scales the added
residual branch down, and the module's other weights, which then do not
change its function, left to the models that have them (their weighted
mean). Every model's embedding is checked to compute what the model does.
"""

from __future__ import annotations

import copy
import math
import os
from typing import Dict, List, Optional, Sequence, Set, Tuple, Union

import torch
from torch import nn

from .io import architecture_name, build_model, load_model, unwrap

__all__ = ["average_models"]

ModelLike = Union[None, str, "os.PathLike[str]", nn.Module]


def average_models(models: Sequence[ModelLike], weights: Optional[Sequence[float]] = None) -> nn.Module:
    """The weighted average of two or more models' weights, as a model of the
    largest one's architecture (on the CPU, in eval mode).

    ``models``: modules, ``model.safetensors`` paths or run folders, ``None``
    for the shipped default model. ``weights``: one non-negative number per
    model, scaled to sum to 1 (default: equal). Every model's weights must be
    those of the largest one's architecture, or of a part of it whose
    missing modules start as the identity (``ZERO_START``), computing the
    same function; all must agree on ``depth_units``. The result's
    ``depth_units`` is theirs. ValueError otherwise, naming the model."""
    if isinstance(models, (str, os.PathLike, nn.Module)) or not isinstance(models, Sequence) or len(models) < 2:
        raise ValueError(f"models: expected a sequence of two or more models, got {models!r:.80}")
    shares = _shares(weights, len(models))
    loaded = [_load(m, i) for i, m in enumerate(models)]
    units = {getattr(m, "depth_units", None) for m in loaded}
    if len(units) > 1:
        raise ValueError(f"models: expected one depth_units for all (a model with a relief scale and one without do not average), got {sorted(map(str, units))}")
    states = [{k: v.detach().float().cpu() for k, v in unwrap(m).state_dict().items()} for m in loaded]
    largest = max(range(len(loaded)), key=lambda i: (len(states[i]), -i))
    target = unwrap(loaded[largest])
    zero, free = _identity_start_parameters(target)
    reference = states[largest]
    for i, state in enumerate(states):
        extra = [k for k in state if k not in reference or state[k].shape != reference[k].shape]
        missing = [k for k in reference if k not in state and k not in zero and k not in free]
        if extra or missing:
            raise ValueError(f"models[{i}]: its weights are not those of models[{largest}]'s {architecture_name(target)} {target.config} "
                             f"or of a part of it that starts as the identity (first mismatch: {(extra + missing)[0]})")
    averaged: Dict[str, torch.Tensor] = {}
    for key, ref in reference.items():
        present = [(w, s[key]) for w, s in zip(shares, states) if key in s]
        total = sum(w * v for w, v in present)
        if key in free:  # the models without it do not depend on it
            mass = sum(w for w, _ in present)
            total = total / mass if mass > 0 else ref
        averaged[key] = total  # a zero-start weight: the models without it hold zero there
    result = build_model(architecture_name(target), **target.config)
    result.load_state_dict(averaged)
    for i, state in enumerate(states):
        if i != largest:  # the largest is its own embedding
            _check_embedding(i, loaded[i], {**reference, **{k: torch.zeros_like(reference[k]) for k in zero if k not in state}, **state}, result)
    result.depth_units = units.pop()
    return result.eval()


def _shares(weights: Optional[Sequence[float]], n: int) -> List[float]:
    if weights is None:
        return [1.0 / n] * n
    if isinstance(weights, (str, bytes)) or not isinstance(weights, Sequence) or len(weights) != n:
        raise ValueError(f"weights: expected {n} numbers, one per model, got {weights!r:.80}")
    for w in weights:
        if isinstance(w, bool) or not isinstance(w, (int, float)) or not math.isfinite(w) or w < 0:
            raise ValueError(f"weights: expected finite numbers ≥ 0, got {list(weights)!r:.80}")
    total = float(sum(weights))
    if total <= 0:
        raise ValueError(f"weights: expected a positive sum, got {list(weights)!r:.80}")
    return [float(w) / total for w in weights]


def _load(model: ModelLike, i: int) -> nn.Module:
    if isinstance(model, nn.Module):
        return model
    if model is not None and not isinstance(model, (str, os.PathLike)):
        raise TypeError(f"models[{i}]: expected a module, a path to model.safetensors or its folder, or None, got {type(model).__name__}")
    try:
        return load_model(model, device="cpu")
    except ValueError as e:
        raise ValueError(f"models[{i}]: {e}") from None


def _identity_start_parameters(model: nn.Module) -> Tuple[Set[str], Set[str]]:
    """The state-dict keys of ``model``'s identity-start modules: those of
    their zero-start layer, and the rest of theirs."""
    zero: Set[str] = set()
    free: Set[str] = set()
    for name, module in model.named_modules():
        layer = getattr(type(module), "ZERO_START", None)
        if layer is None:
            continue
        prefix = f"{name}." if name else ""
        for key in module.state_dict():
            (zero if key.startswith(f"{layer}.") else free).add(prefix + key)
    return zero, free


def _check_embedding(i: int, model: nn.Module, state: Dict[str, torch.Tensor], result: nn.Module) -> None:
    """ValueError unless ``model`` and its embedding ``state`` in ``result``'s
    architecture give the same depth for a fixed random patch."""
    embedded = build_model(architecture_name(result), **unwrap(result).config)
    embedded.load_state_dict(state)
    patch = torch.rand((1, 1, 16, 64, 64), generator=torch.Generator().manual_seed(0))
    with torch.inference_mode():
        want = copy.deepcopy(unwrap(model)).float().cpu().eval()(patch)
        got = embedded.eval()(patch)
    if not torch.allclose(got, want, rtol=1e-4, atol=1e-5 * float(want.abs().max())):
        raise ValueError(f"models[{i}]: it does not compute the same function in {architecture_name(result)} {unwrap(result).config} "
                         "(its configuration differs in something other than identity-start modules)")
