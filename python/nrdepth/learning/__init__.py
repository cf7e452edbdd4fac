"""Learning: the GBR-invariant losses (:mod:`.losses`), a run's settings
(:mod:`.config`), the training loop (:mod:`.train`) and held-out scores
(:mod:`.evaluate`); the networks are in :mod:`nrdepth.model`.
docs/learning.md has the recipe and the shipped model."""

from .config import PAPER, RECOMMENDED, TrainConfig

__all__ = ["TrainConfig", "RECOMMENDED", "PAPER"]
