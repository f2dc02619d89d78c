"""Training SiamFC from scratch on ATSLTD frames (paper eq. 11) of the training split: logistic loss on the response.

Data: the segments with a ground-truth box of at least `min_box_px` a side (sctn.train.usable_segments),
every 10th held out for validation, as SCTN's training does. A training pair is an exemplar from one
segment and a search region from another of the same sequence at most `max_gap` segments away (SiamFC
draws frames up to 100 apart); the search crop is centred on the target, moved by up to `shift_px`
crop px and scaled by up to 1 +- `stretch` (augmentation, as in SiamFC's training), so the label's
centre moves with it. Labels: 1 within `radius_px` (crop px, 16 as in SiamFC) of the target centre,
0 elsewhere; the loss is the logistic loss on every response cell, positives and negatives weighted
half each (SiamFC). Adam. Frames are computed once per segment and kept sparse.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch
from torch.nn import functional as F

from benchmarks.atsltd import atsltd_frame
from benchmarks.siamfc.crops import balanced_weights, crop, exemplar_extent, response_labels
from benchmarks.siamfc.model import TOTAL_STRIDE, SiamFC, SiamFCConfig


@dataclass
class SiamFCTrainConfig:
    """SiamFC training settings: pairs (one search segment each), optimiser, augmentation, budget."""

    epochs: int = 20
    segments_per_epoch: int | None = 400  # search segments (training pairs) per epoch
    batch_segments: int = 8  # pairs per step
    lr: float = 1e-3
    seed: int = 0
    max_gap: int = 100  # segments between exemplar and search
    shift_px: float = 8.0
    stretch: float = 0.05
    radius_px: float = 16.0
    min_box_px: float = 8.0
    val_every: int = 50
    val_segments: int = 40
    max_minutes: float | None = None
    network: SiamFCConfig = field(default_factory=SiamFCConfig)

    def __post_init__(self) -> None:
        from sctn.train import TrainConfigError

        problem = config_problem(self)
        if problem:
            raise TrainConfigError(*problem)


def config_problem(cfg: SiamFCTrainConfig) -> tuple[str, str] | None:
    """The first out-of-range field of cfg and what is wrong with it, or None."""
    for name in ("epochs", "batch_segments", "val_every", "max_gap"):
        if getattr(cfg, name) < 1:
            return name, f"must be >= 1, got {getattr(cfg, name)}"
    if cfg.segments_per_epoch is not None and cfg.segments_per_epoch < 1:
        return "segments_per_epoch", f"must be >= 1, got {cfg.segments_per_epoch}"
    if cfg.val_segments < 0:
        return "val_segments", f"must be >= 0, got {cfg.val_segments}"
    if not (math.isfinite(cfg.lr) and cfg.lr > 0):
        return "lr", f"must be positive and finite, got {cfg.lr}"
    if not 0 <= cfg.seed < 2**63 - 1:
        return "seed", f"must be >= 0 (and below 2**63 - 1), got {cfg.seed}"
    if cfg.max_minutes is not None and not (math.isfinite(cfg.max_minutes) and cfg.max_minutes > 0):
        return "max_minutes", f"must be positive and finite, got {cfg.max_minutes}"
    for name in ("shift_px", "stretch", "radius_px", "min_box_px"):
        v = getattr(cfg, name)
        if not (math.isfinite(v) and v >= 0):
            return name, f"must be >= 0 and finite, got {v}"
    return None


@dataclass
class Frames:
    """The ATSLTD frames of one sequence's usable segments, sparse: flat pixel index and value per segment."""

    width: int
    height: int
    segments: np.ndarray  # segment indices
    boxes: np.ndarray  # (N, 4) ground truth xywh
    pixels: list[np.ndarray]
    values: list[np.ndarray]

    def dense(self, k: int) -> np.ndarray:
        """Frame k (height, width) float32 in [0, 1]."""
        f = np.zeros(self.height * self.width, np.float32)
        f[self.pixels[k]] = self.values[k]
        return f.reshape(self.height, self.width)


def load_frames(path: Path, min_box_px: float) -> Frames:
    """ATSLTD frames (eq. 11, divisor = the segment's length) of the usable segments of one dataset file."""
    from dvsot.dataset import Dataset
    from sctn.train import usable_segments

    with Dataset(path) as ds:
        idx = usable_segments(ds, min_box_px)
        pixels, values, boxes = [], [], []
        for i in idx:
            seg = ds.segment(int(i))
            frame = atsltd_frame(seg.events, ds.width, ds.height, max(1, int(seg.t1_us) - int(seg.t0_us))).ravel()
            nz = np.flatnonzero(frame)
            pixels.append(nz.astype(np.int32))
            values.append((frame[nz] / 255.0).astype(np.float32))
            boxes.append(seg.box)
        return Frames(ds.width, ds.height, idx, np.asarray(boxes, np.float64).reshape(-1, 4), pixels, values)


def pair_crops(frames: Frames, ez: int, ex: int, rng: np.random.Generator, net: SiamFCConfig, shift_px: float,
               stretch: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Exemplar crop of frame ez, search crop of frame ex and the target centre in response cells (x, y)."""
    bz, bx = frames.boxes[ez], frames.boxes[ex]
    z_ext = exemplar_extent(bz[2:])
    z = crop(frames.dense(ez), (bz[0] + bz[2] / 2, bz[1] + bz[3] / 2), z_ext, net.exemplar_size)
    x_ext = exemplar_extent(bx[2:]) * net.search_size / net.exemplar_size
    x_ext *= 1.0 + rng.uniform(-stretch, stretch)
    shift = rng.uniform(-shift_px, shift_px, 2)  # crop px the target lands off the centre
    centre = np.array([bx[0] + bx[2] / 2, bx[1] + bx[3] / 2]) - shift * x_ext / net.search_size
    x = crop(frames.dense(ex), tuple(centre), x_ext, net.search_size)
    r = net.response_size()
    return z, x, (r - 1) / 2 + shift / TOTAL_STRIDE


def make_batch(items: list[tuple[int, int, int]], seqs: list[Frames], rng: np.random.Generator,
               cfg: SiamFCTrainConfig) -> tuple[torch.Tensor, ...]:
    """Exemplars (B, 1, Sz, Sz), search crops (B, 1, Sx, Sx), labels and weights (B, 1, R, R) of (seq, ez, ex)."""
    zs, xs, centres = [], [], []
    for s, ez, ex in items:
        z, x, c = pair_crops(seqs[s], ez, ex, rng, cfg.network, cfg.shift_px, cfg.stretch)
        zs.append(z)
        xs.append(x)
        centres.append(c)
    labels = response_labels(cfg.network.response_size(), np.array(centres), cfg.radius_px / TOTAL_STRIDE)
    return (torch.from_numpy(np.stack(zs)[:, None]), torch.from_numpy(np.stack(xs)[:, None]),
            torch.from_numpy(labels), torch.from_numpy(balanced_weights(labels)))


def logistic_loss(response: torch.Tensor, labels: torch.Tensor, weights: torch.Tensor) -> torch.Tensor:
    """SiamFC's loss: mean over cells of weight x log(1 + exp(-y v)), y = +-1 (labels 1 / 0)."""
    return F.binary_cross_entropy_with_logits(response, labels, weight=weights)


def partner(rng: np.random.Generator, frames: Frames, k: int, max_gap: int, pool: np.ndarray) -> int:
    """An exemplar frame for search frame k: a frame of `pool` within max_gap segments of it (k itself if none)."""
    near = pool[np.abs(frames.segments[pool] - frames.segments[k]) <= max_gap]
    return int(rng.choice(near)) if len(near) else k


def evaluate(model: SiamFC, batch: tuple[torch.Tensor, ...]) -> dict:
    """Validation loss and the mean distance (search-crop px) of each response's peak from the target centre."""
    z, x, labels, weights = batch
    with torch.no_grad():
        resp = model(z, x)
        loss = float(logistic_loss(resp, labels, weights))
    r = resp.shape[-1]
    peak = resp.flatten(1).argmax(dim=1)
    # the target centre is the labels' centre of mass
    ys, xs = torch.meshgrid(torch.arange(r, dtype=torch.float32), torch.arange(r, dtype=torch.float32), indexing="ij")
    mass = labels[:, 0].sum(dim=(1, 2)).clamp(min=1)
    cx, cy = (labels[:, 0] * xs).sum(dim=(1, 2)) / mass, (labels[:, 0] * ys).sum(dim=(1, 2)) / mass
    err = torch.hypot((peak % r).float() - cx, (peak // r).float() - cy) * TOTAL_STRIDE
    return {"loss": loss, "centre_error_px": float(err.mean())}


def train(files: list[Path], cfg: SiamFCTrainConfig, progress: bool = True) -> tuple[SiamFC, dict]:
    """Train a new SiamFC on the given dataset files; returns the model and a history of metrics."""
    from tqdm import tqdm

    rng = np.random.default_rng(cfg.seed)
    torch.manual_seed(cfg.seed)
    seqs = [load_frames(f, cfg.min_box_px) for f in files]
    train_items, val_items, pools = [], [], []
    for s, fr in enumerate(seqs):
        ks = np.arange(len(fr.segments))
        pools.append(ks[ks % 10 != 0])  # exemplars come from training segments only
        val_items += [(s, int(k)) for k in ks[::10]]
        train_items += [(s, int(k)) for k in ks if k % 10 != 0]
    if not train_items:
        raise ValueError("no training segments with a ground-truth box")
    model = SiamFC(cfg.network)
    opt = torch.optim.Adam(model.parameters(), lr=cfg.lr)
    val_rng = np.random.default_rng(cfg.seed + 1)
    val_pick = []
    if val_items:
        spread = np.linspace(0, len(val_items) - 1, min(cfg.val_segments, len(val_items))).astype(int)
        val_pick = [val_items[i] for i in spread]
    val_batch = None
    if val_pick:
        items = [(s, partner(val_rng, seqs[s], k, cfg.max_gap, pools[s]), k) for s, k in val_pick]
        val_batch = make_batch(items, seqs, val_rng, cfg)
    history: dict = {"train_loss": [], "val": []}
    start = time.monotonic()
    step = 0
    per_epoch = min(len(train_items), cfg.segments_per_epoch or len(train_items))
    bar = tqdm(total=cfg.epochs * (per_epoch // cfg.batch_segments), unit="batch", disable=not progress,
               desc="train siamfc")
    stop = False
    for epoch in range(cfg.epochs):
        order = rng.permutation(len(train_items))[:per_epoch]
        for b in range(0, len(order) - cfg.batch_segments + 1, cfg.batch_segments):
            picks = [train_items[k] for k in order[b:b + cfg.batch_segments]]
            items = [(s, partner(rng, seqs[s], k, cfg.max_gap, pools[s]), k) for s, k in picks]
            z, x, labels, weights = make_batch(items, seqs, rng, cfg)
            model.train()
            loss = logistic_loss(model(z, x), labels, weights)
            opt.zero_grad()
            loss.backward()
            opt.step()
            history["train_loss"].append(float(loss.detach()))
            step += 1
            bar.update(1)
            bar.set_postfix(epoch=epoch, loss=f"{history['train_loss'][-1]:.4f}", refresh=False)
            if val_batch is not None and step % cfg.val_every == 0:
                model.eval()
                m = evaluate(model, val_batch)
                m["step"] = step
                history["val"].append(m)
                bar.write(f"step {step}: val loss {m['loss']:.4f} centre error {m['centre_error_px']:.1f} px")
            if cfg.max_minutes is not None and time.monotonic() - start > 60 * cfg.max_minutes:
                stop = True
                break
        if stop:
            break
    bar.close()
    model.eval()
    if val_batch is not None:
        final = evaluate(model, val_batch)
        final["step"] = step
        history["val"].append(final)
    history.update(steps=step, minutes=(time.monotonic() - start) / 60, train_segments=len(train_items),
                   val_segments=len(val_pick))
    return model, history
