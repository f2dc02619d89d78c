"""What every training loop here shares (SCTN and its ANN twin in sctn/training/snn.py, SiamFC in benchmarks/siamfc):
the budget settings as a typed model whose bad values raise one line naming the field, the held-out split, and the
loop over epochs (batches, validation every `val_every` steps, the `max_minutes` budget, progress, history)."""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from typing import Any, Literal

import numpy as np
import torch
from pydantic import BaseModel, Field, ValidationError

from dvsot.core.bounds import MAX_LEARNING_RATE
from dvsot.core.errors import RunError
from dvsot.core.strict import Strict

HELD_OUT_EVERY = 10  # every 10th usable segment of each file is a validation segment, never a training one


class TrainConfigError(ValueError):
    """A training setting out of range: `field` names it, `problem` says what is wrong with its value."""

    def __init__(self, field_name: str, problem: str, model: str = "TrainConfig") -> None:
        super().__init__(f"{model}.{field_name} {problem}")
        self.field, self.problem = field_name, problem


class TrainBudget(Strict):
    """Settings every trainer has: epochs, segments per epoch and per step, Adam's rate, seed, the smallest usable
    box (px), validation (every N steps, on M segments; a tracking score every K steps) and a time budget
    (minutes). Bad values raise TrainConfigError naming the first bad field (numbers are not strict here: Python
    callers pass numpy ones)."""

    epochs: int = Field(3, ge=1)
    segments_per_epoch: int | None = Field(400, ge=1)
    batch_segments: int = Field(4, ge=1)
    lr: float = Field(
        2e-3, gt=0, le=MAX_LEARNING_RATE
    )  # checked here: Adam's own ValueError on a NaN rate would look like a data problem
    # the paper gives none: constant (the default) or cosine, from lr to 0 over the planned steps (an ablation row)
    lr_schedule: Literal["constant", "cosine"] = "constant"
    seed: int = Field(0, ge=0, lt=2**63 - 1)  # numpy seeds are non-negative, torch's fit in int64 (seed + 1 is used)
    min_box_px: float = Field(8.0, ge=0)
    val_every: int = Field(50, ge=1)
    val_segments: int = Field(40, ge=0)
    val_arscore_every: int | None = Field(None, ge=1)  # steps between validation tracking scores; None = off
    max_minutes: float | None = Field(None, gt=0)

    def __init__(self, **data: Any) -> None:
        try:
            super().__init__(**data)
        except ValidationError as exc:
            raise TrainConfigError(*field_problem(type(self), exc), model=type(self).__name__) from None
        if self.segments_per_epoch is not None and self.segments_per_epoch < self.batch_segments:
            # a step takes batch_segments segments of an epoch's: fewer would train nothing and save the start
            raise TrainConfigError("segments_per_epoch", f"is {self.segments_per_epoch}, fewer than batch_segments "
                                   f"{self.batch_segments}: no epoch would take a training step",
                                   model=type(self).__name__)

    def planned_steps(self, items: int) -> int:
        """The training steps of a run over `items` usable training segments (before any max_minutes stop)."""
        per_epoch = min(items, self.segments_per_epoch or items)
        return self.epochs * (per_epoch // self.batch_segments)

    def check_steps(self, items: int) -> None:
        """ValueError (one line, naming the settings) if `items` training segments give no training step."""
        if self.planned_steps(items) < 1:
            raise ValueError(f"{items} usable training segment{'s' * (items != 1)}, fewer than batch_segments "
                             f"{self.batch_segments} (with segments_per_epoch {self.segments_per_epoch}, epochs "
                             f"{self.epochs}): no training step would run; lower batch_segments or add data")


def _bounds(model: type[BaseModel], name: str) -> dict[str, Any]:
    """The gt / ge / lt / le bounds declared on a field of `model`."""
    info = model.model_fields[name]
    return {key: getattr(m, key) for m in info.metadata for key in ("gt", "ge", "lt", "le") if hasattr(m, key)}


def _number(v: Any) -> str:
    """A bound as the messages write it (2**63 - 1, not its 19 digits)."""
    return "2**63 - 1" if v == 2**63 - 1 else str(v)


def field_problem(model: type[BaseModel], exc: ValidationError) -> tuple[str, str]:
    """(field, what is wrong with its value) for the first error of a validation of `model`."""
    err = exc.errors()[0]
    name = str(err["loc"][0]) if err["loc"] else "?"
    value = err.get("input")
    if err["type"] == "extra_forbidden":
        return name, "is not a setting"
    if name not in model.model_fields:
        return name, f"{err['msg'][:1].lower()}{err['msg'][1:]}, got {value!r}"
    b = _bounds(model, name)
    if err["type"] == "less_than_equal" and "le" in b:
        return name, f"must be at most {_number(b['le'])} (the bound), got {value}"
    bounded = err["type"] in ("greater_than", "greater_than_equal", "less_than", "finite_number")
    if not bounded or not ("gt" in b or "ge" in b):
        return name, f"{err['msg'][:1].lower()}{err['msg'][1:]}, got {value!r}"
    is_float = "float" in str(model.model_fields[name].annotation)
    text = "positive" if b.get("gt") == 0 else (f"> {_number(b['gt'])}" if "gt" in b else f">= {_number(b['ge'])}")
    if is_float:
        text += " and finite"
    if "lt" in b:
        text += f" (and below {_number(b['lt'])})"
    return name, f"must be {text}, got {value}"


def held_out(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(training, validation) parts of an ordered array: every HELD_OUT_EVERY-th value from the first is held out."""
    values = np.asarray(values)
    keep = np.arange(len(values)) % HELD_OUT_EVERY != 0
    return values[keep], values[~keep]


def spread(items: Sequence, n: int) -> list:
    """At most n of items, evenly spread from the first to the last (validation segments)."""
    if not len(items):
        return []
    return [items[i] for i in np.linspace(0, len(items) - 1, min(n, len(items))).astype(int)]


def lr_factor(schedule: str, step: int, planned: int) -> float:
    """The learning rate of step `step` (0-based) over the configured one: 1 for constant; for cosine
    (1 + cos(pi step / planned)) / 2, from 1 at the first step towards 0 at the last of `planned` steps."""
    if schedule == "constant":
        return 1.0
    return 0.5 * (1.0 + math.cos(math.pi * min(step, planned) / max(planned, 1)))


def fit(model: torch.nn.Module, opt: torch.optim.Optimizer, items: Sequence, cfg: TrainBudget,
        rng: np.random.Generator, batch_loss: Callable[[list], tuple[torch.Tensor, dict[str, float]]],
        validate: Callable[[], dict] | None, report: Callable[[dict], str], history: dict,
        progress: bool = True, desc: str = "train") -> dict:
    """The training loop: each epoch a permutation of `items` (at most cfg.segments_per_epoch), in steps of
    cfg.batch_segments; `batch_loss(batch)` gives a step's loss and extra figures (appended to history under their
    names); every cfg.val_every steps and at the end `validate()` (eval mode) adds to history["val"] with `report`
    on the progress bar; stops after cfg.max_minutes. Returns history with train_loss, steps and minutes. A loss that
    is NaN or infinite stops it with a RunError."""
    from tqdm import tqdm

    history.setdefault("train_loss", [])
    history.setdefault("val", [])
    start = time.monotonic()
    step = 0
    cfg.check_steps(len(items))  # untrained weights are no result
    per_epoch = min(len(items), cfg.segments_per_epoch or len(items))
    planned = cfg.planned_steps(len(items))
    schedule = torch.optim.lr_scheduler.LambdaLR(opt, lambda k: lr_factor(cfg.lr_schedule, k, planned))
    bar = tqdm(total=planned, unit="batch", disable=not progress, desc=desc)
    stop = False
    for epoch in range(cfg.epochs):
        order = rng.permutation(len(items))[:per_epoch]
        for b in range(0, len(order) - cfg.batch_segments + 1, cfg.batch_segments):
            model.train()
            loss, extra = batch_loss([items[k] for k in order[b:b + cfg.batch_segments]])
            if not bool(torch.isfinite(loss.detach()).all()):  # diverged: every later step and the weights are lost
                bar.close()
                raise RunError(f"training diverged at step {step + 1} (epoch {epoch + 1}): the loss is "
                               f"{float(loss.detach())} (a learning rate of {cfg.lr:g} may be too large)")
            opt.zero_grad()
            loss.backward()
            opt.step()
            schedule.step()
            history["train_loss"].append(float(loss.detach()))
            for key, value in extra.items():
                history.setdefault(key, []).append(value)
            step += 1
            bar.update(1)
            bar.set_postfix(epoch=epoch, loss=f"{history['train_loss'][-1]:.4f}", refresh=False)
            if validate is not None and step % cfg.val_every == 0:
                model.eval()
                history["val"].append({**validate(), "step": step})
                if progress:  # --quiet: the history holds the curve, nothing is printed
                    bar.write(f"step {step}: {report(history['val'][-1])}")
            if cfg.max_minutes is not None and time.monotonic() - start > 60 * cfg.max_minutes:
                stop = True
                break
        if stop:
            break
    bar.close()
    model.eval()
    if validate is not None:
        history["val"].append({**validate(), "step": step})
    history.update(steps=step, minutes=(time.monotonic() - start) / 60)
    return history


class Validation:
    """fit's `validate` for a trainer: `measure()` (figures of the fixed validation batch), the mean training loss
    since the previous validation (train_loss_mean), and every cfg.val_arscore_every steps `score(model)` (a
    tracking score on the validation sequences, e.g. {"arscore": ...}), each step scored at most once (fit
    validates the last step twice when it falls on val_every)."""

    def __init__(self, model: torch.nn.Module, cfg: TrainBudget, history: dict, measure: Callable[[], dict],
                 score: Callable[[torch.nn.Module], dict] | None = None) -> None:
        self.model, self.cfg, self.history, self.measure, self.score = model, cfg, history, measure, score
        self.scored: dict[int, dict] = {}
        self.since = 0  # the step of the previous validation

    def _due(self, step: int) -> bool:
        """Whether this validation is the first at or after a multiple of val_arscore_every (the two periods
        need not divide each other)."""
        every = self.cfg.val_arscore_every
        if self.score is None or not every:
            return False
        last = max(self.scored, default=0)
        return step // every > last // every

    def __call__(self) -> dict:
        step = len(self.history["train_loss"])
        m = self.measure()
        recent = self.history["train_loss"][self.since:step]
        m["train_loss_mean"] = float(np.mean(recent)) if recent else None
        self.since = step
        if step not in self.scored and self._due(step):
            self.scored[step] = self.score(self.model)
        if step in self.scored:
            m.update(self.scored[step])
        return m

    def score_last(self) -> None:
        """After fit: the final validation entry gets the tracking score too, if the last step was not one of
        val_arscore_every's (the curve then always ends with one)."""
        if self.score is None or not self.cfg.val_arscore_every or not self.history["val"]:
            return
        if self.history["steps"] not in self.scored:
            self.model.eval()
            self.scored[self.history["steps"]] = self.score(self.model)
            self.history["val"][-1].update(self.scored[self.history["steps"]])


def score_note(m: dict) -> str:
    """The tracking score of a validation entry for the progress line ("" if it has none)."""
    return f" arscore {m['arscore']:.3f}" if "arscore" in m else ""
