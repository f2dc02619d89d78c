"""Training Ocean (and AutoMatch, through `train_anchor_free`) from scratch on ATSLTD frames of the training split.

Data and validation as SiamFC's training (benchmarks/trackers/siamfc/train.py): the usable segments (a box of at
least `min_box_px` a side), every 10th held out unless validation files are given; a pair is a template from one
segment and a search region from another of the same sequence at most `max_gap` segments away, the search centre
moved by up to `shift_px` crop px (Ocean's training shifts the target in the search region, so the regression
sees every offset) and its extent scaled by up to 1 +- `stretch`. Loss, per pair (Ocean's): the IoU loss of the
distances at the locations inside the target box, plus the classification and object-aware losses, each a
binary cross-entropy over every location with positives (boxes.assign's ellipse) and negatives weighted half each.
Adam.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import torch
from pydantic import Field
from torch import nn
from torch.nn import functional as F

from benchmarks.trackers.ocean.boxes import assign, decode, iou_loss, locations
from benchmarks.trackers.ocean.crops import pair_crops
from benchmarks.trackers.ocean.model import TOTAL_STRIDE, Ocean, OceanConfig
from benchmarks.trackers.pair_training import PairTrainConfig, load_pairs, train_pairs
from benchmarks.trackers.siamfc.crops import balanced_weights
from benchmarks.trackers.siamfc.train import Frames, load_frames, partner


class OceanTrainConfig(PairTrainConfig):
    """Ocean's training settings and network."""

    network: OceanConfig = Field(default_factory=OceanConfig)


def make_batch(items: list[tuple[int, int, int]], seqs: list[Frames], rng: np.random.Generator,
               net, shift_px: float, stretch: float) -> tuple[torch.Tensor, ...]:
    """Templates (B, 1, Sz, Sz), search crops (B, 1, Sx, Sx), search boxes and template boxes (B, 4) crop px of
    (seq, template frame, search frame) items; `net` has exemplar_size, search_size (the network's config)."""
    out = [pair_crops(seqs[s], ez, ex, rng, net.exemplar_size, net.search_size, shift_px, stretch)
           for s, ez, ex in items]
    z, x, bx, bz = (np.stack(v) for v in zip(*out))
    return (torch.from_numpy(z[:, None].astype(np.float32)), torch.from_numpy(x[:, None].astype(np.float32)),
            torch.from_numpy(bx.astype(np.float32)), torch.from_numpy(bz.astype(np.float32)))


def anchor_free_loss(outputs: tuple[torch.Tensor, ...], boxes: torch.Tensor,
                     search_size: int) -> tuple[torch.Tensor, dict]:
    """Ocean's loss of (distances, logits, object-aware logits) on search crops of search_size px for target boxes
    (B, 4) crop px; the sum and its three terms."""
    dist, cls, aware = outputs
    target, inside, labels = assign(boxes, locations(dist.shape[-1], search_size, TOTAL_STRIDE), TOTAL_STRIDE)
    w = torch.from_numpy(balanced_weights(labels.numpy()))
    reg = iou_loss(dist, target, inside)
    c = F.binary_cross_entropy_with_logits(cls, labels, weight=w)
    a = F.binary_cross_entropy_with_logits(aware, labels, weight=w)
    return reg + c + a, {"reg_loss": reg.item(), "cls_loss": c.item(), "aware_loss": a.item()}


def evaluate(model: nn.Module, batch: tuple[torch.Tensor, ...]) -> dict:
    """Validation loss and the mean distance (search-crop px) of the best-scoring location's box centre from the
    target's centre."""
    z, x, bx, bz = batch
    with torch.no_grad():
        out = model(z, x, bz)
        loss, parts = anchor_free_loss(out, bx, model.cfg.search_size)
    dist, cls, aware = out
    r = dist.shape[-1]
    boxes = decode(dist, locations(r, model.cfg.search_size, TOTAL_STRIDE)).flatten(2)
    best = (torch.sigmoid(cls) + torch.sigmoid(aware)).flatten(1).argmax(dim=1)
    pick = boxes[torch.arange(len(best)), :, best]
    centre = (pick[:, :2] + pick[:, 2:]) / 2
    err = torch.linalg.norm(centre - (bx[:, :2] + bx[:, 2:]) / 2, dim=1)
    return {"loss": float(loss), **parts, "centre_error_px": float(err.mean())}


def train_anchor_free(build: Callable[[], nn.Module], name: str, files: list[Path], cfg: PairTrainConfig,
                      progress: bool = True, val_files: list[Path] | None = None,
                      val_score: Callable[[nn.Module], dict] | None = None) -> tuple[nn.Module, dict]:
    """Train a new network `build()` (Ocean's interface: forward(z, x, z_box) -> distances, logits, object-aware
    logits) on the dataset files; the model and its history (validation as in SiamFC's training)."""
    torch.manual_seed(cfg.seed)
    seqs, n_train, pools = load_pairs(load_frames, files, val_files, cfg.min_box_px)
    model: nn.Module | None = None  # the network build() makes (after the data's checks): its config sizes the crops

    def built() -> nn.Module:
        nonlocal model
        model = build()
        return model

    def batch(picks: list, rng: np.random.Generator) -> tuple[torch.Tensor, ...]:
        items = [(s, partner(rng, seqs[s], k, cfg.max_gap, pools[s]), k) for s, k in picks]
        return make_batch(items, seqs, rng, model.cfg, cfg.shift_px, cfg.stretch)

    def loss(net: nn.Module, b: tuple[torch.Tensor, ...]) -> tuple[torch.Tensor, dict]:
        z, x, bx, bz = b
        return anchor_free_loss(net(z, x, bz), bx, net.cfg.search_size)

    return train_pairs(name, built, seqs, n_train, val_files, cfg, batch, loss, evaluate,
                       lambda m: f"val loss {m['loss']:.4f} centre error {m['centre_error_px']:.1f} px", progress,
                       val_score)


def train_ocean(files: list[Path], cfg: OceanTrainConfig, progress: bool = True, val_files: list[Path] | None = None,
                val_score: Callable[[nn.Module], dict] | None = None) -> tuple[Ocean, dict]:
    """Train a new Ocean on the given dataset files; the model and a history of metrics (train_anchor_free)."""
    return train_anchor_free(lambda: Ocean(cfg.network), "ocean", files, cfg, progress, val_files, val_score)
