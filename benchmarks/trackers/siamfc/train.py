"""Training SiamFC from scratch on ATSLTD frames (paper eq. 11) of the training split: logistic loss on the response.

Data: the segments with a ground-truth box of at least `min_box_px` a side (sctn.training.snn.usable_segments),
every 10th held out for validation, as SCTN's training does; with validation files (`val_files`) those are the
validation pairs' sequences instead and every usable training segment trains. A tracking score of the network
(`val_score`, e.g. the validation sequences' ARscore) joins the validation every `val_arscore_every` steps and at
the end, as in SCTN's training (sctn.training.loop.Validation). A training pair is an exemplar from one
segment and a search region from another of the same sequence at most `max_gap` segments away (SiamFC
draws frames up to 100 apart); the search crop is centred on the target, moved by up to `shift_px`
crop px and scaled by up to 1 +- `stretch` (augmentation, as in SiamFC's training), so the label's
centre moves with it. Labels: 1 within `radius_px` (crop px, 16 as in SiamFC) of the target centre,
0 elsewhere; the loss is the logistic loss on every response cell, positives and negatives weighted
half each (SiamFC). Adam. Frames are computed once per segment and kept sparse.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from pydantic import Field
from torch.nn import functional as F

from benchmarks.trackers.atsltd import atsltd_frame
from benchmarks.trackers.pair_training import PairTrainConfig, load_pairs, train_pairs
from benchmarks.trackers.siamfc.crops import balanced_weights, crop, exemplar_extent, response_labels
from benchmarks.trackers.siamfc.model import TOTAL_STRIDE, SiamFC, SiamFCConfig


class SiamFCTrainConfig(PairTrainConfig):
    """SiamFC training settings: PairTrainConfig's (pairs: one search segment each, optimiser, budget, gap and
    augmentation) with SiamFC's shift, the label radius and the network."""

    shift_px: float = Field(8.0, ge=0)
    radius_px: float = Field(16.0, ge=0)
    network: SiamFCConfig = Field(default_factory=SiamFCConfig)


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
    from sctn.training.snn import usable_segments

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


def train_siamfc(files: list[Path], cfg: SiamFCTrainConfig, progress: bool = True,
                 val_files: list[Path] | None = None,
                 val_score: Callable[[torch.nn.Module], dict] | None = None) -> tuple[SiamFC, dict]:
    """Train a new SiamFC on the given dataset files; returns the model and a history of metrics.

    Validation (every cfg.val_every steps and at the end): cfg.val_segments search segments spread over
    `val_files` when given (each paired with an exemplar of its own sequence; every usable training segment then
    trains), else over every 10th usable segment of the training files (held out). Each entry of history["val"]
    has the loss, the mean centre error (px) and the mean training loss since the previous entry; `val_score(model)`
    is added every cfg.val_arscore_every steps and at the end."""
    torch.manual_seed(cfg.seed)
    # exemplars come from training segments only
    seqs, n_train, pools = load_pairs(load_frames, files, val_files, cfg.min_box_px)

    def batch(picks: list, rng: np.random.Generator) -> tuple[torch.Tensor, ...]:
        items = [(s, partner(rng, seqs[s], k, cfg.max_gap, pools[s]), k) for s, k in picks]
        return make_batch(items, seqs, rng, cfg)

    def loss(model: SiamFC, b: tuple[torch.Tensor, ...]) -> torch.Tensor:
        z, x, labels, weights = b
        return logistic_loss(model(z, x), labels, weights)

    return train_pairs("siamfc", lambda: SiamFC(cfg.network), seqs, n_train, val_files, cfg, batch, loss, evaluate,
                       lambda m: f"val loss {m['loss']:.4f} centre error {m['centre_error_px']:.1f} px", progress,
                       val_score)
