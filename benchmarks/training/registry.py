"""The training registry: model name -> its trainer, its config type, its defaults and the settings only it has.

A new model registers itself here (or from its own module, with `register_trainer`); `dvsot train --model` and
`benchmarks.train_model` read nothing else. SCTN-like models (a `network` type) share the layer settings
(channels, fc, tail_steps, bias, no_background_neuron), checked here. Functions and types are named as
"module:attribute" and imported when a run uses them, so reading the registry (the command's --help) imports no torch.
"""

from __future__ import annotations

import importlib
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from dvsot.core.errors import UserError, label

# settings every model has (TrainBudget's fields); the rest belong to the models that list them
COMMON_SETTINGS = ("epochs", "segments_per_epoch", "batch_segments", "lr", "lr_schedule", "val_every",
                   "val_segments", "val_arscore_every", "seed", "max_minutes")
MAX_WIDTH = 1024  # channels and fc: weights and activations grow with them (1024 x 107^2 x T: 0.5 GB a sample)


def resolve(name: str) -> Any:
    """The attribute a "module:attribute" name gives, looked up now (so a patched attribute is the one used)."""
    module, _, attribute = name.partition(":")
    return getattr(importlib.import_module(module), attribute)


@dataclass(frozen=True)
class Trainer:
    """One trainable model: `train` (files, cfg, progress, val_files=, val_score=) -> (model, history); `config` its
    settings' type; `network` the type of config.network made from the layer settings (SCTN's and its twin's
    networks; None: the config's own); `tracker` (model, seed) -> a benchmark tracker for the validation sequences'
    ARscore; `settings` the optional settings only this model has (those in `network_settings` go to its network),
    filled from `defaults` when not given; `rescue` (setting, values): what else to try when a trained network
    is silent."""

    train: str
    config: str
    tracker: str
    network: str | None = None
    settings: tuple[str, ...] = ()
    network_settings: tuple[str, ...] = ()
    defaults: Mapping[str, Any] = field(default_factory=dict)
    rescue: tuple[str, str] | None = None


TRAINERS: dict[str, Trainer] = {}


def register_trainer(name: str, trainer: Trainer) -> None:
    """Make `name` a model that `dvsot train --model` and `train_model` can train."""
    TRAINERS[name] = trainer


def trainer(name: str, labels: Mapping[str, str] | None = None) -> Trainer:
    """The registered trainer of model `name`; UserError naming the known ones otherwise."""
    if name not in TRAINERS:
        raise UserError(f"{label('model', labels)} {name!r}: not a model that trains here "
                        f"(known: {', '.join(TRAINERS)})")
    return TRAINERS[name]


def setting_names() -> list[str]:
    """Every training setting some registered model has: the common ones, then each model's own."""
    names = list(COMMON_SETTINGS)
    for entry in TRAINERS.values():
        names += [n for n in entry.settings if n not in names]
    return names


def model_settings(model: str, given: Mapping[str, Any], labels: Mapping[str, str] | None = None) -> dict:
    """The settings of `model` from those given (None = not given), its defaults filling the rest of its own;
    UserError naming a setting the model lacks."""
    entry = trainer(model, labels)
    out = dict(entry.defaults)
    for name, value in given.items():
        if value is None:
            continue
        if name not in COMMON_SETTINGS and name not in entry.settings:
            owners = [m for m, t in TRAINERS.items() if name in t.settings]
            if not owners:
                raise UserError(f"{label(name, labels)}: not a training setting of any model")
            raise UserError(f"{label(name, labels)}: not a setting of {label('model', labels)} {model} "
                            f"(only of {', '.join(owners)})")
        out[name] = value
    return out


def _network(settings: dict, labels: Mapping[str, str] | None) -> dict:
    """The layer sizes and deviations of SCTN's network (and its twin's) from the settings, checked."""
    from dvsot.core.bounds import (  # here: dvsot.core.bounds imports numpy, --help must not
        MAX_TAIL_STEPS,
        range_problem,
    )

    tail = settings.pop("tail_steps", 0)
    problem = range_problem(label("tail_steps", labels), tail, 0, MAX_TAIL_STEPS, "steps of 1 ms")
    if problem:
        raise UserError(problem)
    net = {"tail_steps": tail, "bias": settings.pop("bias", False),
           "background_neuron": not settings.pop("no_background_neuron", False)}
    for name in ("channels", "fc"):
        sizes = settings.pop(name, None)
        if sizes is not None:
            if min(sizes) < 1 or max(sizes) > MAX_WIDTH:  # bounded: the weights are allocated from these
                raise UserError(f"{label(name, labels)} sizes must be between 1 and {MAX_WIDTH} (the bound), "
                                f"got {' '.join(map(str, sizes))}")
            net[name] = tuple(sizes)
    return net


def configure(model: str, settings: dict, labels: Mapping[str, str] | None = None):
    """The config of `model` from its full settings (model_settings'); its network's from the layer settings."""
    entry = trainer(model, labels)
    settings = dict(settings)
    if entry.network is None:
        return resolve(entry.config)(**settings)
    net = _network(settings, labels)
    net.update({k: settings.pop(k) for k in entry.network_settings if k in settings})
    return resolve(entry.config)(**settings, network=resolve(entry.network)(**net))


# SCTN and its twin: a setting not given is TrainConfig's default (the recipe, sctn.training.snn), so no flags
# build TrainConfig() (with the twin's TwinConfig() network)
_SCTN_LIKE = ("loss", "channels", "fc", "squared_error", "background_term", "no_background_neuron", "bias",
              "error_time")

register_trainer("sctn", Trainer(
    train="sctn.training.snn:train", config="sctn.training.snn:TrainConfig", network="sctn.network:NetworkConfig",
    tracker="benchmarks.training.run:sctn_tracker",
    settings=_SCTN_LIKE + ("ops_penalty", "calibrate", "tail_steps", "init", "fluctuation_xi"),
    rescue=("init", "calibrate / fluctuation")))
register_trainer("sctn_ann", Trainer(
    train="sctn.ann:train_twin", config="sctn.training.snn:TrainConfig", network="sctn.ann:TwinConfig",
    tracker="benchmarks.training.run:sctn_tracker", settings=_SCTN_LIKE + ("input",), network_settings=("input",)))
register_trainer("siamfc", Trainer(
    train="benchmarks.trackers.siamfc.train:train_siamfc",
    config="benchmarks.trackers.siamfc.train:SiamFCTrainConfig",
    tracker="benchmarks.training.run:siamfc_tracker"))
for _name, _module, _cls in (("goturn", "goturn", "GOTURN"), ("siamrpn", "siamrpn", "SiamRPN"),
                             ("siammask", "siammask", "SiamMask")):
    register_trainer(_name, Trainer(
        train=f"benchmarks.trackers.{_module}.train:train_{_name}",
        config=f"benchmarks.trackers.{_module}.train:{_cls}TrainConfig",
        tracker=f"benchmarks.trackers.{_module}.tracker:validation_tracker"))
register_trainer("ocean", Trainer(
    train="benchmarks.trackers.ocean.train:train_ocean", config="benchmarks.trackers.ocean.train:OceanTrainConfig",
    tracker="benchmarks.trackers.ocean.tracker:trained_tracker"))
register_trainer("automatch", Trainer(
    train="benchmarks.trackers.automatch.train:train_automatch",
    config="benchmarks.trackers.automatch.train:AutoMatchTrainConfig",
    tracker="benchmarks.trackers.automatch.tracker:trained_tracker"))
