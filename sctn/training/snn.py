"""Training SCTN directly as an SNN (STCA-style surrogate gradients through time) on dataset files.

Per training segment (one with a ground-truth box of at least `min_box_px` a side): 20 positive
(IoU >= 0.7) and 40 negative (IoU <= 0.5) uniform samples (paper §2.4), encoded as the events inside
each box (sctn/encoding.py); the loss is the voltage loss of sctn/loss.py on each output neuron's
voltage at its error step (STCA's rule by default, `error_time`), optionally plus a penalty on the
synaptic operations the spikes drive (`ops_penalty`, the energy model of sctn/energy.py). Adam. The
weights start as `init` says (Kaiming-uniform by default). Every `val_every` steps a fixed set of
validation segments is scored: from validation files when given, else every 10th segment of each
training file, held out. Fine-tuning lives in sctn/finetune.py (`finetune`, re-exported here).
"""

from __future__ import annotations

import json
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, Literal

import numpy as np
import torch
from pydantic import Field, SerializeAsAny, model_validator

from dvsot.core.bounds import MAX_LEARNING_RATE
from dvsot.dataset import Dataset
from dvsot.events import EventBatch
from sctn.encoding import encode_boxes
from sctn.energy import layer_ops
from sctn.finetune import finetune  # noqa: F401  (re-exported: callers import it from here)
from sctn.loss import ErrorTime, LossKind, error_voltages, voltage_loss
from sctn.network import SCTN, NetworkConfig
from sctn.neurons import THETA
from sctn.samples import TRAIN, labelled_samples
from sctn.training.loop import TrainBudget, TrainConfigError, Validation, fit, held_out, score_note, spread  # noqa: F401  (TrainConfigError)

NEARLY_SILENT = 0.1  # mean target V_max on validation positives below this: a nearly silent network
MAX_BATCH_SEGMENTS = 64  # segments per step: 60 samples of T x 107 x 107 each, ~55 MB a segment
Init = Literal["kaiming", "calibrate", "fluctuation"]  # how the weights start (TrainConfig.init)
INIT_METHODS = {"calibrate": "calibrate", "fluctuation": "fluctuation_init"}  # init -> the network's method


# settings that shape nothing trained (which seed, when to validate, a time limit): the recipe leaves them out
RUN_SETTINGS = ("seed", "max_minutes", "val_every", "val_segments", "val_arscore_every")
# network fields whose difference from the preset's layout sctn.checkpoint.layout_note names already
LAYOUT_FIELDS = ("bias", "tail_steps", "steps", "step_us")


class TrainConfig(TrainBudget):
    """Training settings of SCTN (and its twin). The defaults are the recipe: what `dvsot train` runs with no flags
    and what the shipped checkpoints are trained with (epochs x segments_per_epoch / batch_segments Adam steps; the
    loss eq. 5-6, STCA's error rule, Kaiming-uniform weights); every named deviation is off (the paper preset)."""

    epochs: int = Field(1, ge=1)
    segments_per_epoch: int | None = Field(1000, ge=1)
    batch_segments: int = Field(2, ge=1, le=MAX_BATCH_SEGMENTS)  # every segment's 60 samples are built at once
    lr: float = Field(3e-3, gt=0, le=MAX_LEARNING_RATE)
    val_every: int = Field(100, ge=1)
    val_segments: int = Field(40, ge=0)
    loss: LossKind = "exp"
    error_time: ErrorTime = "stca"  # the step each sample's error sits at: STCA's rule, or "max" (an ablation row)
    ops_penalty: float = Field(0.0, ge=0)  # loss weight per million synaptic operations (ACs) per sample; 0 = off
    squared_error: bool = False  # deviation: square each sample's eq.-5 error (sctn/loss.py)
    background_term: bool = False  # deviation: add the mirrored background-neuron error (sctn/loss.py)
    # the weights' start: Kaiming-uniform (today's preset; the paper gives none), the data-driven scale of
    # SCTN.calibrate, or SCTN.fluctuation_init with fluctuation_xi; each an ablation row
    init: Init = "kaiming"
    fluctuation_xi: float = Field(2.0, gt=0, allow_inf_nan=False)  # theta over V's standard deviation at the start
    network: SerializeAsAny[NetworkConfig] = Field(default_factory=NetworkConfig)  # a TwinConfig keeps its fields

    @model_validator(mode="before")
    @classmethod
    def _calibrate_is_an_init(cls, data: Any) -> Any:
        """`calibrate: true` (configs written before `init`, and `dvsot train --calibrate`) is init "calibrate"."""
        if isinstance(data, dict) and "calibrate" in data:
            data = dict(data)
            if data.pop("calibrate"):
                if data.get("init", "calibrate") != "calibrate":
                    raise ValueError(f"calibrate contradicts init {data['init']!r}")
                data["init"] = "calibrate"
        return data

    def __init__(self, **data: Any) -> None:
        super().__init__(**data)
        if self.background_term and not self.network.background_neuron:  # the mirrored error would train nothing
            raise TrainConfigError("background_term", "needs the background neuron (not with --no-background-neuron)")

    @property
    def calibrate(self) -> bool:
        """Whether the weights start from the data-driven calibration (init "calibrate")."""
        return self.init == "calibrate"


def recipe(network: NetworkConfig | None = None) -> dict:
    """The recipe as a checkpoint's metadata records it (JSON types): TrainConfig's defaults, less RUN_SETTINGS, with
    `network`'s fields (the preset SCTN's by default; the twin's TwinConfig for sctn_ann)."""
    cfg = TrainConfig() if network is None else TrainConfig(network=network)
    return cfg.model_dump(mode="json", exclude=set(RUN_SETTINGS))


def _plain(value: Any) -> Any:
    """A setting's value as JSON holds it (tuples as lists), so a recorded value compares with the recipe's."""
    return json.loads(json.dumps(value, default=str))


def _recorded(train_config: dict, name: str, preset: Any) -> Any:
    """A setting as a recorded train_config has it; one recorded before the setting existed ran as it says: the
    error rule was V's maximum, the initialisation the `calibrate` flag's, every other setting the recipe's."""
    if name in train_config:
        return _plain(train_config[name])
    if name == "error_time":
        return None
    if name == "init":
        return "calibrate" if train_config.get("calibrate") else "kaiming"
    return preset


def training_note(train_config: dict | None, network: NetworkConfig | None = None,
                  skip_network: tuple[str, ...] = LAYOUT_FIELDS) -> str | None:
    """What makes a checkpoint's training (its metadata's train_config) differ from the recipe (`recipe(network)`),
    one phrase per setting ("lr 0.002 (the recipe's 0.003)"), or None (also when nothing was recorded). A config
    without `error_time` was trained before the rule became a setting: with the maximum over all steps. Network
    fields in `skip_network` are left to the caller (sctn.checkpoint.layout_note names them)."""
    if not isinstance(train_config, dict):
        return None
    preset = recipe(network)
    ways = []
    for name, want in preset.items():
        if name == "network":
            continue
        got = _recorded(train_config, name, want)
        if name == "error_time" and got is None:
            ways.append("the old error-time rule (V's maximum over all steps; no error_time recorded)")
        elif got != want:
            ways.append(f"{name} {got!r} (the recipe's {want!r})")
    net = train_config.get("network")
    if isinstance(net, dict):
        for name, want in preset["network"].items():
            if name not in skip_network and name in net and _plain(net[name]) != want:
                ways.append(f"network {name} {net[name]!r} (the recipe's {want!r})")
    return ("trained with another recipe than `dvsot train`'s: " + ", ".join(ways)) if ways else None


def usable_segments(ds: Dataset, min_box_px: float) -> np.ndarray:
    """Indices of segments whose ground truth exists and is at least min_box_px on each side."""
    b = ds.segment_boxes()
    ok = np.isfinite(b).all(axis=1) & (b[:, 2] >= min_box_px) & (b[:, 3] >= min_box_px)
    return np.flatnonzero(ok)


def segment_batch(items: list[tuple[EventBatch, int, np.ndarray]], image_wh: list[tuple[int, int]],
                  rng: np.random.Generator, net_cfg: NetworkConfig, specs=TRAIN):
    """Encoded samples of several segments: inputs (N, T, 2, S, S), IoUs (N,), positive flags (N,)."""
    xs, ious, pos = [], [], []
    for (events, t0, box), wh in zip(items, image_wh):
        boxes, iou, p = labelled_samples(rng, box, specs, wh)
        xs.append(encode_boxes(events, t0, boxes, net_cfg))
        ious.append(iou)
        pos.append(p)
    return torch.cat(xs), torch.from_numpy(np.concatenate(ious)), torch.from_numpy(np.concatenate(pos))


def batch_loss(volts: torch.Tensor, iou: torch.Tensor, pos: torch.Tensor, cfg: TrainConfig,
               rng: np.random.Generator) -> torch.Tensor:
    """The voltage loss of cfg (eq. 5-6 of the target neuron by default) on output voltages (N, T, 2), each
    sample's error at the step cfg.error_time picks (sctn.loss.error_steps; `rng` draws STCA's random steps)."""
    v = error_voltages(volts, pos, cfg.error_time, rng)
    return voltage_loss(v, iou, pos, cfg.loss, squared=cfg.squared_error, background=cfg.background_term)


def evaluate(model: SCTN, x: torch.Tensor, iou: torch.Tensor, pos: torch.Tensor, cfg: TrainConfig) -> dict:
    """Loss, firing accuracy of the target neuron and mean V_max of positives / negatives on one batch (the
    loss's random error steps from a generator seeded by cfg.seed, so a fixed batch gives a fixed loss)."""
    with torch.no_grad():
        volts = model(x)
        vmax = volts.max(dim=1).values
        loss = float(batch_loss(volts, iou, pos, cfg, np.random.default_rng(cfg.seed)))
    fires = vmax[:, 1] >= THETA
    return {"loss": loss, "accuracy": float((fires == pos).float().mean()),
            "vmax_pos": float(vmax[pos, 1].mean()) if pos.any() else float("nan"),
            "vmax_neg": float(vmax[~pos, 1].mean()) if (~pos).any() else float("nan"),
            "vmax_max": float(vmax[:, 1].max())}


def training_loss(model: SCTN, x: torch.Tensor, iou: torch.Tensor, pos: torch.Tensor,
                  cfg: TrainConfig, rng: np.random.Generator) -> tuple[torch.Tensor, float | None]:
    """The voltage loss of one batch, plus cfg.ops_penalty x the mean synaptic operations per sample in
    millions (the ACs the spikes of conv1..fc2 drive; input events are given, not learned), and those ACs."""
    if cfg.ops_penalty <= 0:
        return batch_loss(model(x), iou, pos, cfg, rng), None
    volts, spikes = model.forward_record(x)
    ops = torch.stack(layer_ops(model, spikes)[1:]).sum(dim=0).mean()
    loss = batch_loss(volts, iou, pos, cfg, rng) + cfg.ops_penalty * ops / 1e6
    return loss, float(ops.detach())


def train(files: list[Path], cfg: TrainConfig, progress: bool = True, log=print,
          build=SCTN, val_files: list[Path] | None = None,
          val_score: Callable[[torch.nn.Module], dict] | None = None) -> tuple[SCTN, dict]:
    """Train a new SCTN on the given dataset files; returns the model and a history of metrics. `build(cfg.network)`
    makes the network (another with SCTN's interface: sctn.ann's twin); cfg.init's method, if any, runs first.

    Validation (every cfg.val_every steps and at the end): on cfg.val_segments segments spread over `val_files`
    when given (then every usable training segment trains), else over every 10th segment of the training files
    (held out). Each entry of history["val"] has the loss, accuracy, mean target V_max on positives and
    negatives, and the mean training loss since the previous entry; `val_score(model)` (a tracking score, e.g.
    {"arscore": ...}) is added every cfg.val_arscore_every steps and at the end.
    """
    rng = np.random.default_rng(cfg.seed)
    torch.manual_seed(cfg.seed)
    datasets = [Dataset(f) for f in files]
    n_train = len(datasets)
    try:
        datasets += [Dataset(f) for f in (val_files or [])]
        train_items, val_items = [], []
        for d, ds in enumerate(datasets):
            usable = usable_segments(ds, cfg.min_box_px)
            if d >= n_train:
                val_items += [(d, int(i)) for i in usable]
                continue
            fit_idx, val_idx = (usable, usable[:0]) if val_files else held_out(usable)
            val_items += [(d, int(i)) for i in val_idx]
            train_items += [(d, int(i)) for i in fit_idx]
        if not train_items:
            raise ValueError("no training segments with a ground-truth box")
        cfg.check_steps(len(train_items))  # before the model is built or calibrated
        if val_files and not val_items:
            raise ValueError(f"{', '.join(map(str, val_files))}: no validation segments with a ground-truth box")

        def load(items):
            segs = [datasets[d].segment(i) for d, i in items]
            return ([(s.events, s.t0_us, s.box) for s in segs],
                    [(datasets[d].width, datasets[d].height) for d, _ in items])

        model = build(cfg.network)
        calib_items = [train_items[k] for k in rng.choice(len(train_items), min(8, len(train_items)), replace=False)]
        calib_batch = segment_batch(*load(calib_items), rng, cfg.network)[0]  # drawn either way: same rng stream
        history_calibration = None
        if cfg.init != "kaiming":
            method = getattr(model, INIT_METHODS[cfg.init], None)
            if method is None:
                raise ValueError(f"init {cfg.init!r} is not available for {type(model).__name__} (only kaiming)")
            history_calibration = (method(calib_batch) if cfg.init == "calibrate"
                                   else method(calib_batch, xi=cfg.fluctuation_xi))
        opt = torch.optim.Adam(model.parameters(), lr=cfg.lr)

        val_pick = spread(val_items, cfg.val_segments)
        val_rng = np.random.default_rng(cfg.seed + 1)
        val_batch = segment_batch(*load(val_pick), val_rng, cfg.network) if val_pick else None

        def step_loss(items: list) -> tuple[torch.Tensor, dict]:
            loss, ops = training_loss(model, *segment_batch(*load(items), rng, cfg.network), cfg, rng)
            return loss, ({} if ops is None else {"train_ops_per_sample": ops})

        history: dict = {"train_loss": [], "val": [], "calibration": history_calibration, "init": cfg.init,
                         "validation": "files" if val_files else "held_out"}
        validate = Validation(model, cfg, history, lambda: evaluate(model, *val_batch, cfg), val_score)
        history = fit(model, opt, train_items, cfg, rng, step_loss, validate if val_batch is not None else None,
                      lambda m: (f"val loss {m['loss']:.4f} acc {m['accuracy']:.3f} "
                                 f"vmax pos {m['vmax_pos']:.3f} neg {m['vmax_neg']:.3f}" + score_note(m)),
                      history, progress, "train")
        if val_batch is not None:
            validate.score_last()
            final = history["val"][-1]
            # a network whose target output never rises above 0 cannot track; with eq. 5 and no bias nothing
            # revives it (no spike, no surrogate gradient), so say so rather than hand it on as trained
            history["silent"] = final["vmax_max"] <= 0.0
            # a target neuron whose mean V_max on positives stays below NEARLY_SILENT barely responds: said, not refused
            history["target_vmax_pos"] = final["vmax_pos"]
            history["nearly_silent"] = not final["vmax_pos"] >= NEARLY_SILENT
        history.update(train_segments=len(train_items), val_segments=len(val_pick))
        return model, history
    finally:
        for ds in datasets:
            ds.close()


def provenance(files: list[Path], cfg: TrainConfig, history: dict) -> dict:
    """What made a checkpoint: data files (size, name, split), config, command, git commit, metrics."""
    try:
        commit = subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True,
                                cwd=Path(__file__).resolve().parent, timeout=5).stdout.strip() or None
    except (OSError, subprocess.SubprocessError):
        commit = None
    data = []
    for f in files:
        with Dataset(f) as ds:
            data.append({"file": str(f), "name": ds.name, "split": ds.split, "bytes": Path(f).stat().st_size,
                         "events": ds.num_events, "segments": ds.num_segments})
    return {
        "train_config": cfg.model_dump(),
        "data": data,
        "command": " ".join(sys.argv),
        "git_commit": commit,
        "history": {k: v for k, v in history.items() if k != "train_loss"},
        "train_loss_first_last": [history["train_loss"][0], history["train_loss"][-1]]
        if history["train_loss"]
        else None,
        "created": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
    }
