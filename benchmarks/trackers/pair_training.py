"""The training loop shared by the Siamese-family trackers trained here (SiamFC, SiamRPN, SiamMask, GOTURN, Ocean,
AutoMatch) on frame pairs.

Data as SiamFC's training (benchmarks/trackers/siamfc/train.py): the usable segments of the training files (ground
truth of at least `min_box_px` a side), every 10th held out for validation unless validation files are given (then
those are the validation sequences and every usable training segment trains). A training item is one search
segment; its partner (the template segment) is drawn by the model's trainer. The model's own `batch`, `loss` and
`evaluate` make a step; sctn.training.loop.fit runs the steps, validation and the time budget.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import torch
from pydantic import Field

from dvsot.core.bounds import MAX_LEARNING_RATE
from sctn.training.loop import TrainBudget, Validation, fit, held_out, score_note, spread


class PairTrainConfig(TrainBudget):
    """Settings of a training on frame pairs: TrainBudget's with these defaults, the pairs' gap (segments between
    template and search) and the search crop's augmentation (shift in crop px, scale by up to 1 +- stretch)."""

    epochs: int = Field(20, ge=1)
    segments_per_epoch: int | None = Field(400, ge=1)  # search segments (training pairs) per epoch
    batch_segments: int = Field(8, ge=1)  # pairs per step
    lr: float = Field(1e-3, gt=0, le=MAX_LEARNING_RATE)
    max_gap: int = Field(100, ge=1)  # segments between template and search
    shift_px: float = Field(32.0, ge=0)
    stretch: float = Field(0.05, ge=0)


def split_items(lengths: Sequence[int], n_train: int, has_val_files: bool) -> tuple[list, list, list]:
    """(training items, validation items, template pools): items are (sequence, frame) pairs; sequences from
    n_train on are validation sequences; a pool holds the frames a sequence's templates may come from."""
    train_items, val_items, pools = [], [], []
    for s, n in enumerate(lengths):
        everything = np.arange(n)
        if s >= n_train:
            pools.append(everything)
            val_items += [(s, int(k)) for k in everything]
            continue
        fit_ks, val_ks = (everything, everything[:0]) if has_val_files else held_out(everything)
        pools.append(fit_ks)
        val_items += [(s, int(k)) for k in val_ks]
        train_items += [(s, int(k)) for k in fit_ks]
    return train_items, val_items, pools


def train_pairs(name: str, build: Callable[[], torch.nn.Module], seqs: list, n_train: int,
                val_files: list[Path] | None, cfg: TrainBudget, batch: Callable[[list, np.random.Generator], tuple],
                loss: Callable[[torch.nn.Module, tuple], torch.Tensor | tuple[torch.Tensor, dict]],
                evaluate: Callable[[torch.nn.Module, tuple], dict],
                report: Callable[[dict], str], progress: bool = True,
                val_score: Callable[[torch.nn.Module], dict] | None = None) -> tuple[torch.nn.Module, dict]:
    """Train a new network `build()` with Adam on items of `seqs` (objects with a `segments` array); `batch(items,
    rng)` makes a step's tensors from (sequence, frame) items, `loss(model, batch)` its loss (or the loss and its
    terms, a dict the history keeps), `evaluate(model, batch)` the validation figures (a dict with "loss") on a
    fixed validation batch. The network is built after the data's checks. Returns the model and its history."""
    rng = np.random.default_rng(cfg.seed)
    train_items, val_items, _ = split_items([len(s.segments) for s in seqs], n_train, bool(val_files))
    if not train_items:
        raise ValueError("no training segments with a ground-truth box")
    cfg.check_steps(len(train_items))
    if val_files and not val_items:
        raise ValueError(f"{', '.join(map(str, val_files))}: no validation segments with a ground-truth box")
    model = build()
    opt = torch.optim.Adam(model.parameters(), lr=cfg.lr)
    val_pick = spread(val_items, cfg.val_segments)
    val_batch = batch(val_pick, np.random.default_rng(cfg.seed + 1)) if val_pick else None

    def step_loss(picks: list) -> tuple[torch.Tensor, dict]:
        value = loss(model, batch(picks, rng))
        return value if isinstance(value, tuple) else (value, {})

    history: dict = {"train_loss": [], "val": [], "validation": "files" if val_files else "held_out"}
    validate = Validation(model, cfg, history, lambda: evaluate(model, val_batch), val_score)
    history = fit(model, opt, train_items, cfg, rng, step_loss, validate if val_batch is not None else None,
                  lambda m: report(m) + score_note(m), history, progress, f"train {name}")
    if val_batch is not None:
        validate.score_last()
    history.update(train_segments=len(train_items), val_segments=len(val_pick))
    return model, history


def pools_of(seqs: list, n_train: int, has_val_files: bool) -> list[np.ndarray]:
    """The template pools of split_items (frames a sequence's templates may come from)."""
    return split_items([len(s.segments) for s in seqs], n_train, has_val_files)[2]


def load_pairs(load: Callable[[Path, float], object], files: list[Path], val_files: list[Path] | None,
               min_box_px: float) -> tuple[list, int, list[np.ndarray]]:
    """(sequences, n_train, template pools): `load(path, min_box_px)` of the training files then the validation
    files, how many of them are training sequences, and split_items's template pools."""
    seqs = [load(f, min_box_px) for f in files]
    n_train = len(seqs)
    seqs += [load(f, min_box_px) for f in (val_files or [])]
    return seqs, n_train, pools_of(seqs, n_train, bool(val_files))
