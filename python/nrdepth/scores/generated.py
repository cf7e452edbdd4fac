"""The generated videos nrdepth is scored on beyond the held-out clips
(:data:`nrdepth.learning.evaluate.TEST_SEED`): shapes outside the
training ranges (the paper's Table 2) and bending sheets."""

from __future__ import annotations

import dataclasses

from ..engine.generate import GeneratorConfig

__all__ = ["out_of_range", "SHEET_FAMILIES"]

SHEET_FAMILIES = ("fractal", "stripes", "plaid", "cells", "weave", "print")
"""The texture families of the generated sheets: every procedural one and print."""


def out_of_range(config: GeneratorConfig) -> GeneratorConfig:
    """Each of the four shape parameters drawn above its training range:
    from the training maximum to 1.6× it (constraint is left alone: it only
    confines motion to the centre)."""
    s = config.surface
    beyond = {k: (getattr(s, k)[1], 1.6 * getattr(s, k)[1]) for k in ("intensity", "folding", "flexibility", "speed")}
    return dataclasses.replace(config, surface=dataclasses.replace(s, **beyond))
