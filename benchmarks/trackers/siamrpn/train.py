"""Training SiamRPN from scratch on ATSLTD frames (paper eq. 11) of the training split.

Pairs as SiamFC's training (benchmarks/trackers/pair_training.py): a template segment and a search segment at
most `max_gap` segments apart in one sequence, the search crop moved and scaled around the target
(siamrpn/crops.py). Targets (anchors.targets): anchors above `pos_iou` IoU with the target positive, below
`neg_iou` negative, 16 positives and 64 samples at most. Loss (SiamRPN): cross-entropy of the labelled anchors'
scores plus `reg_weight` x smooth L1 of the positive anchors' offsets. Adam.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import torch
from pydantic import Field
from torch.nn import functional as F

from benchmarks.trackers.pair_training import PairTrainConfig, load_pairs, train_pairs
from benchmarks.trackers.siamfc.train import Frames, load_frames, partner
from benchmarks.trackers.siamrpn.anchors import decode, make_anchors, targets
from benchmarks.trackers.siamrpn.crops import search_crop, search_window, template_crop
from benchmarks.trackers.siamrpn.model import TOTAL_STRIDE, SiamRPN, SiamRPNConfig


class SiamRPNTrainConfig(PairTrainConfig):
    """SiamRPN training settings: PairTrainConfig's with SiamRPN's stretch, the anchors' IoU thresholds, the
    regression's weight and the network."""

    stretch: float = Field(0.1, ge=0, lt=1)
    pos_iou: float = Field(0.6, gt=0, le=1)
    neg_iou: float = Field(0.3, ge=0, le=1)
    reg_weight: float = Field(1.0, ge=0)
    network: SiamRPNConfig = Field(default_factory=SiamRPNConfig)


def rpn_sample(seq: Frames, ez: int, ex: int, rng: np.random.Generator, net: SiamRPNConfig, cfg) -> tuple:
    """Template crop, search crop, search window and the target box in the search crop of frames (ez, ex)."""
    z = template_crop(seq.dense(ez), seq.boxes[ez], net.exemplar_size)
    window = search_window(seq.boxes[ex], rng, net.exemplar_size, net.search_size, cfg.shift_px, cfg.stretch)
    return z, search_crop(seq.dense(ex), window, net.search_size), window


def rpn_targets(boxes: list[np.ndarray], anchors: np.ndarray, rng: np.random.Generator, cfg) -> tuple:
    """Labels (B, k, R, R) int64 and offsets (B, 4, k, R, R) float32 of the target boxes in their search crops."""
    out = [targets(anchors, b, rng, cfg.pos_iou, cfg.neg_iou) for b in boxes]
    return (torch.from_numpy(np.stack([o[0] for o in out])), torch.from_numpy(np.stack([o[1] for o in out])))


def rpn_loss(scores: torch.Tensor, offsets: torch.Tensor, labels: torch.Tensor, reg_targets: torch.Tensor,
             reg_weight: float) -> torch.Tensor:
    """SiamRPN's loss: cross-entropy over labelled anchors + reg_weight x smooth L1 over positive anchors."""
    cls = F.cross_entropy(scores, labels, ignore_index=-1)
    pos = (labels == 1).unsqueeze(1).expand_as(offsets)
    reg = F.smooth_l1_loss(offsets[pos], reg_targets[pos], reduction="sum") / max(1, int((labels == 1).sum()))
    return cls + reg_weight * reg


def best_boxes(scores: torch.Tensor, offsets: torch.Tensor, anchors: np.ndarray) -> np.ndarray:
    """The box (B, 4) (cx, cy, w, h crop px from the centre) of each map's highest target score."""
    p = torch.softmax(scores, dim=1)[:, 1].flatten(1).numpy()
    best = p.argmax(axis=1)
    d = offsets.flatten(2).numpy()[np.arange(len(best)), :, best].T
    return decode(d, anchors.reshape(4, -1)[:, best]).T


def box_figures(scores: torch.Tensor, offsets: torch.Tensor, anchors: np.ndarray, boxes: np.ndarray) -> dict:
    """Mean centre error (crop px) and IoU of each map's top-scoring anchor's refined box against the target boxes
    (B, 4) (cx, cy, w, h crop px from the centre)."""
    found = best_boxes(scores, offsets, anchors)
    err = np.hypot(*(found[:, :2] - boxes[:, :2]).T)
    return {"centre_error_px": float(err.mean()), "iou": float(box_iou_cxcywh(found, boxes).mean())}


def box_iou_cxcywh(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """IoU (B,) of boxes a and b (B, 4), both (cx, cy, w, h)."""
    lo = np.maximum(a[:, :2] - a[:, 2:] / 2, b[:, :2] - b[:, 2:] / 2)
    hi = np.minimum(a[:, :2] + a[:, 2:] / 2, b[:, :2] + b[:, 2:] / 2)
    inter = np.prod(np.clip(hi - lo, 0, None), axis=1)
    return inter / (np.prod(a[:, 2:], axis=1) + np.prod(b[:, 2:], axis=1) - inter)


def train_siamrpn(files: list[Path], cfg: SiamRPNTrainConfig, progress: bool = True,
                  val_files: list[Path] | None = None,
                  val_score: Callable[[torch.nn.Module], dict] | None = None) -> tuple[SiamRPN, dict]:
    """Train a new SiamRPN on the given dataset files; returns the model and a history of metrics (validation:
    loss, centre error px and IoU of the top-scoring anchor's refined box in the search crop)."""
    torch.manual_seed(cfg.seed)
    seqs, n_train, pools = load_pairs(load_frames, files, val_files, cfg.min_box_px)
    net = cfg.network
    anchors = make_anchors(net.score_size(), TOTAL_STRIDE, net.ratios, net.anchor_scale)

    def batch(items: list, rng: np.random.Generator) -> tuple:
        zs, xs, boxes = [], [], []
        for s, k in items:
            z, x, window = rpn_sample(seqs[s], partner(rng, seqs[s], k, cfg.max_gap, pools[s]), k, rng, net, cfg)
            zs.append(z)
            xs.append(x)
            boxes.append(window[2])
        labels, offsets = rpn_targets(boxes, anchors, rng, cfg)
        return (torch.from_numpy(np.stack(zs)[:, None]), torch.from_numpy(np.stack(xs)[:, None]), labels, offsets,
                np.stack(boxes))

    def loss(model: SiamRPN, b: tuple) -> torch.Tensor:
        scores, offsets = model(b[0], b[1])
        return rpn_loss(scores, offsets, b[2], b[3], cfg.reg_weight)

    def evaluate(model: SiamRPN, b: tuple) -> dict:
        with torch.no_grad():
            scores, offsets = model(b[0], b[1])
            value = float(rpn_loss(scores, offsets, b[2], b[3], cfg.reg_weight))
        return {"loss": value, **box_figures(scores, offsets, anchors, b[4])}

    model, history = train_pairs(
        "siamrpn", lambda: SiamRPN(net), seqs, n_train, val_files, cfg, batch, loss, evaluate,
        lambda m: f"val loss {m['loss']:.4f} centre error {m['centre_error_px']:.1f} px iou {m['iou']:.2f}",
        progress, val_score)
    return model, history
