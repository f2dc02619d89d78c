"""Training GOTURN from scratch on ATSLTD frames (paper eq. 11) of the training split: consecutive segment pairs.

Data as SiamFC's training (benchmarks/trackers/pair_training.py); a training item is a search segment k and its
pair is the previous usable segment (k - 1; k itself when that one is not usable). Each pair gives one example of
the real motion (both crops around the previous box, crops.region) and `augmented_per_pair` examples of
GOTURN's motion augmentation (the search crop around the current box moved and scaled by crops.shifted_box: GOTURN
draws 10 per frame). The target is the current box in the search crop (crops.encode); the loss is L1 (GOTURN).
Adam.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import torch
from pydantic import Field
from torch.nn import functional as F

from benchmarks.trackers.goturn.crops import crop_region, encode, region, shifted_box
from benchmarks.trackers.goturn.model import GOTURN, GOTURNConfig
from benchmarks.trackers.pair_training import load_pairs, train_pairs
from benchmarks.trackers.siamfc.train import Frames, load_frames
from dvsot.core.bounds import MAX_LEARNING_RATE
from sctn.training.loop import TrainBudget


class GOTURNTrainConfig(TrainBudget):
    """GOTURN training settings: TrainBudget's with these defaults, the motion augmentation and the network."""

    epochs: int = Field(20, ge=1)
    segments_per_epoch: int | None = Field(400, ge=1)
    batch_segments: int = Field(8, ge=1)  # pairs per step, each giving 1 + augmented_per_pair examples
    lr: float = Field(1e-3, gt=0, le=MAX_LEARNING_RATE)
    augmented_per_pair: int = Field(3, ge=0)
    lambda_shift: float = Field(5.0, gt=0)
    lambda_scale: float = Field(15.0, gt=0)
    max_scale: float = Field(0.4, ge=0, lt=1)
    network: GOTURNConfig = Field(default_factory=GOTURNConfig)

def previous(frames: Frames, k: int) -> int:
    """The usable frame of the segment just before frame k's, or k itself if that segment is not usable."""
    return k - 1 if k > 0 and frames.segments[k - 1] == frames.segments[k] - 1 else k

def examples(frames: Frames, k: int, rng: np.random.Generator, cfg: GOTURNTrainConfig) -> tuple[list, list, list]:
    """(previous crops, search crops, targets) of search frame k: the real motion, then the augmented ones."""
    p = previous(frames, k)
    size = cfg.network.size
    prev_frame, frame = frames.dense(p), frames.dense(k)
    z = crop_region(prev_frame, region(frames.boxes[p]), size)
    places = [frames.boxes[p]] + [shifted_box(frames.boxes[k], rng, cfg.lambda_shift, cfg.lambda_scale,
                                              cfg.max_scale) for _ in range(cfg.augmented_per_pair)]
    zs, xs, ys = [], [], []
    for place in places:
        rect = region(place)
        zs.append(z)
        xs.append(crop_region(frame, rect, size))
        ys.append(encode(frames.boxes[k], rect))
    return zs, xs, ys

def iou_xyxy(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """IoU (B,) of corner boxes a and b (B, 4) (x1, y1, x2, y2)."""
    lo, hi = np.maximum(a[:, :2], b[:, :2]), np.minimum(a[:, 2:], b[:, 2:])
    inter = np.prod(np.clip(hi - lo, 0, None), axis=1)
    areas = [np.prod(np.clip(c[:, 2:] - c[:, :2], 0, None), axis=1) for c in (a, b)]
    return inter / np.maximum(areas[0] + areas[1] - inter, 1e-9)

def train_goturn(files: list[Path], cfg: GOTURNTrainConfig, progress: bool = True,
                 val_files: list[Path] | None = None,
                 val_score: Callable[[torch.nn.Module], dict] | None = None) -> tuple[GOTURN, dict]:
    """Train a new GOTURN on the given dataset files; returns the model and a history of metrics (validation: L1
    loss, IoU of the predicted box in the search crop, and the centre error in crop px)."""
    torch.manual_seed(cfg.seed)
    seqs, n_train, _ = load_pairs(load_frames, files, val_files, cfg.min_box_px)

    def batch(items: list, rng: np.random.Generator) -> tuple:
        zs, xs, ys = [], [], []
        for s, k in items:
            z, x, y = examples(seqs[s], k, rng, cfg)
            zs += z
            xs += x
            ys += y
        return (torch.from_numpy(np.stack(zs)[:, None]), torch.from_numpy(np.stack(xs)[:, None]),
                torch.from_numpy(np.stack(ys).astype(np.float32)))

    def loss(model: GOTURN, b: tuple) -> torch.Tensor:
        return F.l1_loss(model(b[0], b[1]), b[2])

    def evaluate(model: GOTURN, b: tuple) -> dict:
        with torch.no_grad():
            out = model(b[0], b[1])
            value = float(F.l1_loss(out, b[2]))
        o, y = out.numpy().astype(np.float64), b[2].numpy().astype(np.float64)
        px = cfg.network.size / 10.0
        err = np.hypot((o[:, 0] + o[:, 2] - y[:, 0] - y[:, 2]) / 2, (o[:, 1] + o[:, 3] - y[:, 1] - y[:, 3]) / 2) * px
        return {"loss": value, "iou": float(iou_xyxy(o, y).mean()), "centre_error_px": float(err.mean())}

    return train_pairs("goturn", lambda: GOTURN(cfg.network), seqs, n_train, val_files, cfg, batch, loss, evaluate,
                       lambda m: f"val loss {m['loss']:.4f} iou {m['iou']:.2f} centre error "
                                 f"{m['centre_error_px']:.1f} px", progress, val_score)
