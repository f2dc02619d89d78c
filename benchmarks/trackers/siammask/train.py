"""Training SiamMask from scratch on ATSLTD frames (paper eq. 11) with the dataset files' instance masks.

Pairs, crops and the score and box targets as SiamRPN's training (benchmarks/trackers/siamrpn/train.py). The mask
target of a pair is the target's pixels (`Dataset.mask(i) == Dataset.target_id`) at the rendered sample nearest
the search segment's end, cropped with the search crop; a cell's mask target is its response window of it
(masks.mask_targets). As in SiamMask, the mask loss (per-pixel logistic loss, mean over the window) is taken at
the cells holding a positive anchor only, weighted by `mask_weight` (SiamMask's 32) beside the score and box
losses. A file without masks (`Dataset.has_masks` false, e.g. one made by `dvsot simulate`) trains with its box
filled as the mask: the history's `mask_sources` says which files did.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from pydantic import Field
from torch.nn import functional as F

from benchmarks.trackers.pair_training import load_pairs, train_pairs
from benchmarks.trackers.siamfc.train import Frames, load_frames, partner
from benchmarks.trackers.siammask.masks import mask_targets
from benchmarks.trackers.siammask.model import SiamMask, SiamMaskConfig
from benchmarks.trackers.siamrpn.anchors import make_anchors
from benchmarks.trackers.siamrpn.crops import search_crop, search_window, template_crop
from benchmarks.trackers.siamrpn.model import TOTAL_STRIDE
from benchmarks.trackers.siamrpn.train import SiamRPNTrainConfig, box_figures, rpn_loss, rpn_targets


class SiamMaskTrainConfig(SiamRPNTrainConfig):
    """SiamRPN's training settings, the mask loss's weight and the network."""

    mask_weight: float = Field(32.0, ge=0)
    network: SiamMaskConfig = Field(default_factory=SiamMaskConfig)


@dataclass
class MaskedFrames:
    """A sequence's frames (siamfc.train.Frames) and each frame's target pixels (flat indices); source: "file"
    (the instance masks) or "box" (the box filled, for a file without masks)."""

    frames: Frames
    target_pixels: list[np.ndarray]
    source: str

    @property
    def segments(self) -> np.ndarray:
        """The frames' segment indices."""
        return self.frames.segments

    def mask(self, k: int) -> np.ndarray:
        """The target mask (height, width) float32 of frame k."""
        m = np.zeros(self.frames.height * self.frames.width, np.float32)
        m[self.target_pixels[k]] = 1.0
        return m.reshape(self.frames.height, self.frames.width)


def load_masked(path: Path, min_box_px: float) -> MaskedFrames:
    """The frames and target masks of the usable segments of one dataset file."""
    from dvsot.dataset import Dataset

    frames = load_frames(path, min_box_px)
    w, h = frames.width, frames.height
    pixels = []
    with Dataset(path) as ds:
        source = "file" if ds.has_masks else "box"
        target = ds.target_id if ds.target_id is not None else 1
        for seg, box in zip(frames.segments, frames.boxes):
            if source == "file":
                ids = ds.mask(ds.sample_at((int(seg) + 1) * ds.segment_us))
                pixels.append(np.flatnonzero(ids.ravel() == target).astype(np.int32))
                continue
            x0, y0 = int(np.clip(np.floor(box[0]), 0, w)), int(np.clip(np.floor(box[1]), 0, h))
            x1, y1 = int(np.clip(np.ceil(box[0] + box[2]), 0, w)), int(np.clip(np.ceil(box[1] + box[3]), 0, h))
            yy, xx = np.mgrid[y0:y1, x0:x1]
            pixels.append((yy * w + xx).ravel().astype(np.int32))
    return MaskedFrames(frames, pixels, source)


def mask_loss(masks: torch.Tensor, labels: torch.Tensor, targets: torch.Tensor) -> torch.Tensor:
    """Mean per-pixel logistic loss of the mask logits (B, m, m, R, R) at the cells with a positive anchor (in
    labels (B, k, R, R)) against their targets (N, m, m), in the order of torch.nonzero."""
    cells = torch.nonzero((labels == 1).any(dim=1))
    if len(cells) == 0:
        return masks.sum() * 0.0
    picked = masks[cells[:, 0], :, :, cells[:, 1], cells[:, 2]]
    return F.binary_cross_entropy_with_logits(picked, targets)


def train_siammask(files: list[Path], cfg: SiamMaskTrainConfig, progress: bool = True,
                   val_files: list[Path] | None = None,
                   val_score: Callable[[torch.nn.Module], dict] | None = None) -> tuple[SiamMask, dict]:
    """Train a new SiamMask on the given dataset files; returns the model and a history of metrics (validation:
    loss, centre error px and IoU of the top-scoring anchor's box, mask loss)."""
    torch.manual_seed(cfg.seed)
    seqs, n_train, pools = load_pairs(load_masked, files, val_files, cfg.min_box_px)
    net = cfg.network
    r = net.score_size()
    anchors = make_anchors(r, TOTAL_STRIDE, net.ratios, net.anchor_scale)

    def batch(items: list, rng: np.random.Generator) -> tuple:
        zs, xs, boxes, mask_crops = [], [], [], []
        for s, k in items:
            seq = seqs[s]
            ez = partner(rng, seq.frames, k, cfg.max_gap, pools[s])
            zs.append(template_crop(seq.frames.dense(ez), seq.frames.boxes[ez], net.exemplar_size))
            window = search_window(seq.frames.boxes[k], rng, net.exemplar_size, net.search_size, cfg.shift_px,
                                   cfg.stretch)
            xs.append(search_crop(seq.frames.dense(k), window, net.search_size))
            mask_crops.append(search_crop(seq.mask(k), window, net.search_size))
            boxes.append(window[2])
        labels, offsets = rpn_targets(boxes, anchors, rng, cfg)
        cells = torch.nonzero((labels == 1).any(dim=1)).numpy()
        targets = np.concatenate([mask_targets(mask_crops[b], cells[cells[:, 0] == b, 1:], r, TOTAL_STRIDE,
                                               net.exemplar_size, net.mask_side) for b in range(len(items))])
        return (torch.from_numpy(np.stack(zs)[:, None]), torch.from_numpy(np.stack(xs)[:, None]), labels, offsets,
                torch.from_numpy(targets), np.stack(boxes))

    def losses(model: SiamMask, b: tuple) -> tuple[torch.Tensor, torch.Tensor, tuple]:
        out = model(b[0], b[1])
        return rpn_loss(out[0], out[1], b[2], b[3], cfg.reg_weight), mask_loss(out[2], b[2], b[4]), out

    def loss(model: SiamMask, b: tuple) -> torch.Tensor:
        rpn, mask, _ = losses(model, b)
        return rpn + cfg.mask_weight * mask

    def evaluate(model: SiamMask, b: tuple) -> dict:
        with torch.no_grad():
            rpn, mask, out = losses(model, b)
        return {"loss": float(rpn + cfg.mask_weight * mask), "mask_loss": float(mask),
                **box_figures(out[0], out[1], anchors, b[5])}

    model, history = train_pairs(
        "siammask", lambda: SiamMask(net), seqs, n_train, val_files, cfg, batch, loss, evaluate,
        lambda m: f"val loss {m['loss']:.4f} mask {m['mask_loss']:.4f} centre error {m['centre_error_px']:.1f} px",
        progress, val_score)
    history["mask_sources"] = {str(f): s.source for f, s in zip(list(files) + list(val_files or []), seqs)}
    return model, history
