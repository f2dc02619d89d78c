"""Training SCTN directly as an SNN (STCA-style surrogate gradients through time) on dataset files.

Per training segment (one with a ground-truth box of at least `min_box_px` a side): 20 positive
(IoU >= 0.7) and 40 negative (IoU <= 0.5) uniform samples (paper §2.4), encoded as the events inside
each box (sctn/encoding.py); the loss is the voltage loss of sctn/loss.py on each output neuron's
maximum voltage over the time window, optionally plus a penalty on the synaptic operations the spikes
drive (`ops_penalty`, the energy model of sctn/energy.py). Adam. Every `val_every` steps a fixed held-out
set of segments (every 10th segment of each file) is scored. Fine-tuning lives in sctn/finetune.py
(`finetune`, re-exported here).
"""

from __future__ import annotations

import math
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from dvsot.dataset import Dataset
from dvsot.events import EventBatch
from dvsot.lazy import callable_module
from sctn.encoding import encode_boxes
from sctn.energy import layer_ops
from sctn.finetune import finetune  # noqa: F401  (re-exported: callers import it from here)
from sctn.loss import voltage_loss
from sctn.network import SCTN, NetworkConfig
from sctn.neurons import THETA
from sctn.samples import TRAIN, labelled_samples


@dataclass
class TrainConfig:
    """Training settings (segments, samples, optimiser, budget)."""

    epochs: int = 3
    segments_per_epoch: int | None = 400
    batch_segments: int = 4
    lr: float = 2e-3
    loss: str = "exp"
    seed: int = 0
    min_box_px: float = 8.0
    val_every: int = 50
    val_segments: int = 40
    max_minutes: float | None = None
    ops_penalty: float = 0.0  # loss weight per million synaptic operations (ACs) per sample; 0 = off
    squared_error: bool = False  # deviation: square each sample's eq.-5 error (sctn/loss.py)
    background_term: bool = False  # deviation: add the mirrored background-neuron error (sctn/loss.py)
    calibrate: bool = False  # deviation: data-driven weight scale at initialisation (SCTN.calibrate), an ablation row
    network: NetworkConfig = field(default_factory=NetworkConfig)

    def __post_init__(self) -> None:
        problem = config_problem(self)
        if problem:
            raise TrainConfigError(*problem)


class TrainConfigError(ValueError):
    """A TrainConfig field out of range: `field` names it, `problem` says what is wrong with its value."""

    def __init__(self, field_name: str, problem: str) -> None:
        super().__init__(f"TrainConfig.{field_name} {problem}")
        self.field, self.problem = field_name, problem


def _finite(v: float) -> bool:
    """v is a finite real number."""
    return isinstance(v, (int, float)) and math.isfinite(v)


MAX_BATCH_SEGMENTS = 64  # segments per step: 60 samples of T x 107 x 107 each, ~55 MB a segment


def config_problem(cfg: TrainConfig) -> tuple[str, str] | None:
    """The first out-of-range field of cfg and what is wrong with it, or None; checked before any work."""
    for name in ("epochs", "batch_segments", "val_every"):
        if getattr(cfg, name) < 1:
            return name, f"must be >= 1, got {getattr(cfg, name)}"
    if cfg.segments_per_epoch is not None and cfg.segments_per_epoch < 1:
        return "segments_per_epoch", f"must be >= 1, got {cfg.segments_per_epoch}"
    if cfg.batch_segments > MAX_BATCH_SEGMENTS:  # every segment's 60 samples are built at once
        return "batch_segments", f"must be at most {MAX_BATCH_SEGMENTS} (the bound), got {cfg.batch_segments}"
    if cfg.val_segments < 0:
        return "val_segments", f"must be >= 0, got {cfg.val_segments}"
    if not (_finite(cfg.lr) and cfg.lr > 0):  # else Adam's ValueError on a NaN rate looks like a data problem
        return "lr", f"must be positive and finite, got {cfg.lr}"
    if not 0 <= cfg.seed < 2**63 - 1:  # numpy seeds are non-negative, torch's fit in int64 (seed + 1 is used too)
        return "seed", f"must be >= 0 (and below 2**63 - 1), got {cfg.seed}"
    if cfg.max_minutes is not None and not (_finite(cfg.max_minutes) and cfg.max_minutes > 0):
        return "max_minutes", f"must be positive and finite, got {cfg.max_minutes}"
    for name in ("ops_penalty", "min_box_px"):
        v = getattr(cfg, name)
        if not (_finite(v) and v >= 0):
            return name, f"must be >= 0 and finite, got {v}"
    return None


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


def batch_loss(vmax: torch.Tensor, iou: torch.Tensor, pos: torch.Tensor, cfg: TrainConfig) -> torch.Tensor:
    """The voltage loss of cfg (eq. 5-6 of the target neuron by default) on maximum voltages (N, 2)."""
    return voltage_loss(vmax, iou, pos, cfg.loss, squared=cfg.squared_error, background=cfg.background_term)


def evaluate(model: SCTN, x: torch.Tensor, iou: torch.Tensor, pos: torch.Tensor, cfg: TrainConfig) -> dict:
    """Loss, firing accuracy of the target neuron and mean V_max of positives / negatives on one batch."""
    with torch.no_grad():
        vmax = model(x).max(dim=1).values
        loss = float(batch_loss(vmax, iou, pos, cfg))
    fires = vmax[:, 1] >= THETA
    return {"loss": loss, "accuracy": float((fires == pos).float().mean()),
            "vmax_pos": float(vmax[pos, 1].mean()) if pos.any() else float("nan"),
            "vmax_neg": float(vmax[~pos, 1].mean()) if (~pos).any() else float("nan"),
            "vmax_max": float(vmax[:, 1].max())}


def training_loss(model: SCTN, x: torch.Tensor, iou: torch.Tensor, pos: torch.Tensor,
                  cfg: TrainConfig) -> tuple[torch.Tensor, float | None]:
    """The voltage loss of one batch, plus cfg.ops_penalty x the mean synaptic operations per sample in
    millions (the ACs the spikes of conv1..fc2 drive; input events are given, not learned), and those ACs."""
    if cfg.ops_penalty <= 0:
        return batch_loss(model(x).max(dim=1).values, iou, pos, cfg), None
    volts, spikes = model.forward_record(x)
    ops = torch.stack(layer_ops(model, spikes)[1:]).sum(dim=0).mean()
    loss = batch_loss(volts.max(dim=1).values, iou, pos, cfg) + cfg.ops_penalty * ops / 1e6
    return loss, float(ops.detach())


def train(files: list[Path], cfg: TrainConfig, progress: bool = True, log=print,
          build=SCTN) -> tuple[SCTN, dict]:
    """Train a new SCTN on the given dataset files; returns the model and a history of metrics. `build(cfg.network)`
    makes the network (another with SCTN's interface: sctn.ann's twin); its `calibrate`, if any, runs first."""
    from tqdm import tqdm

    rng = np.random.default_rng(cfg.seed)
    torch.manual_seed(cfg.seed)
    datasets = [Dataset(f) for f in files]
    try:
        train_items, val_items = [], []
        for d, ds in enumerate(datasets):
            idx = usable_segments(ds, cfg.min_box_px)
            val_items += [(d, int(i)) for i in idx[::10]]
            train_items += [(d, int(i)) for k, i in enumerate(idx) if k % 10 != 0]
        if not train_items:
            raise ValueError("no training segments with a ground-truth box")

        def load(items):
            segs = [datasets[d].segment(i) for d, i in items]
            return ([(s.events, s.t0_us, s.box) for s in segs],
                    [(datasets[d].width, datasets[d].height) for d, _ in items])

        model = build(cfg.network)
        calib_items = [train_items[k] for k in rng.choice(len(train_items), min(8, len(train_items)), replace=False)]
        calib_batch = segment_batch(*load(calib_items), rng, cfg.network)[0]  # drawn either way: same rng stream
        calibrate = cfg.calibrate and hasattr(model, "calibrate")  # the ANN twin has no calibration
        history_calibration = model.calibrate(calib_batch) if calibrate else None
        opt = torch.optim.Adam(model.parameters(), lr=cfg.lr)

        val_pick = [val_items[i] for i in np.linspace(0, len(val_items) - 1, min(cfg.val_segments, len(val_items))).astype(int)] if val_items else []
        val_rng = np.random.default_rng(cfg.seed + 1)
        val_batch = segment_batch(*load(val_pick), val_rng, cfg.network) if val_pick else None
        history: dict = {"train_loss": [], "val": [], "calibration": history_calibration}
        start = time.monotonic()
        step = 0
        per_epoch = min(len(train_items), cfg.segments_per_epoch or len(train_items))
        total = cfg.epochs * (per_epoch // cfg.batch_segments)
        bar = tqdm(total=total, unit="batch", disable=not progress, desc="train")
        stop = False
        for epoch in range(cfg.epochs):
            order = rng.permutation(len(train_items))[:per_epoch]
            for b in range(0, len(order) - cfg.batch_segments + 1, cfg.batch_segments):
                items = [train_items[k] for k in order[b:b + cfg.batch_segments]]
                x, iou, pos = segment_batch(*load(items), rng, cfg.network)
                model.train()
                loss, ops = training_loss(model, x, iou, pos, cfg)
                opt.zero_grad()
                loss.backward()
                opt.step()
                history["train_loss"].append(float(loss.detach()))
                if ops is not None:
                    history.setdefault("train_ops_per_sample", []).append(ops)
                step += 1
                bar.update(1)
                bar.set_postfix(epoch=epoch, loss=f"{history['train_loss'][-1]:.4f}", refresh=False)
                if val_batch is not None and step % cfg.val_every == 0:
                    model.eval()
                    m = evaluate(model, *val_batch, cfg)
                    m["step"] = step
                    history["val"].append(m)
                    bar.write(f"step {step}: val loss {m['loss']:.4f} acc {m['accuracy']:.3f} "
                              f"vmax pos {m['vmax_pos']:.3f} neg {m['vmax_neg']:.3f}")
                if cfg.max_minutes is not None and time.monotonic() - start > 60 * cfg.max_minutes:
                    stop = True
                    break
            if stop:
                break
        bar.close()
        model.eval()
        if val_batch is not None:
            final = evaluate(model, *val_batch, cfg)
            final["step"] = step
            history["val"].append(final)
            # a network whose target output never rises above 0 cannot track; with eq. 5 and no bias nothing
            # revives it (no spike, no surrogate gradient), so say so rather than hand it on as trained
            history["silent"] = final["vmax_max"] <= 0.0
        history.update(steps=step, minutes=(time.monotonic() - start) / 60, train_segments=len(train_items),
                       val_segments=len(val_pick))
        return model, history
    finally:
        for ds in datasets:
            ds.close()


def provenance(files: list[Path], cfg: TrainConfig, history: dict) -> dict:
    """What made a checkpoint: data files (size, name, split), config, command, git commit, metrics."""
    from dataclasses import asdict

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
    c = asdict(cfg)
    c["network"] = cfg.network.model_dump()
    return {"train_config": c, "data": data, "command": " ".join(sys.argv), "git_commit": commit,
            "history": {k: v for k, v in history.items() if k != "train_loss"},
            "train_loss_first_last": [history["train_loss"][0], history["train_loss"][-1]] if history["train_loss"] else None,
            "created": time.strftime("%Y-%m-%dT%H:%M:%S%z")}


callable_module(__name__, "train")  # sctn.train(...) is this module's train (dvsot.lazy says why)
