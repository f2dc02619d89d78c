"""Training AutoMatch from scratch on ATSLTD frames of the training split: Ocean's pairs, augmentation, loss and
validation (benchmarks/trackers/ocean/train.py train_anchor_free) on AutoMatch's network."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from pydantic import Field
from torch import nn

from benchmarks.trackers.automatch.model import AutoMatch, AutoMatchConfig
from benchmarks.trackers.ocean.train import train_anchor_free
from benchmarks.trackers.pair_training import PairTrainConfig


class AutoMatchTrainConfig(PairTrainConfig):
    """AutoMatch's training settings and network."""

    network: AutoMatchConfig = Field(default_factory=AutoMatchConfig)


def train_automatch(files: list[Path], cfg: AutoMatchTrainConfig, progress: bool = True,
                    val_files: list[Path] | None = None,
                    val_score: Callable[[nn.Module], dict] | None = None) -> tuple[AutoMatch, dict]:
    """Train a new AutoMatch on the given dataset files; the model and a history of metrics."""
    return train_anchor_free(lambda: AutoMatch(cfg.network), "automatch", files, cfg, progress, val_files, val_score)
