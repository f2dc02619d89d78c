"""SCTN's ANN twin (paper Fig. 8B): SCTN's layers with ReLU on one frame per candidate, trained and tracked as SCTN.

Layers: SCTN's own (sctn/network.py NetworkConfig: the same widths, kernels and strides, and SCTN's
bias setting: none in the paper preset), each a convolution or fully connected layer followed by ReLU
instead of C-LIF neurons; the two output units (0 = background, 1 = target) have no activation. Input: a candidate's
canvas from sctn/encoding.py (the events inside the box, 107 x 107), in one of two forms (`TwinConfig.input`):

- "bins" (default): the ten 1-ms steps x 2 polarities as 20 input channels (channel = 2 step + polarity).
  The twin then sees exactly what SCTN sees, timing included, so the comparison is between the neuron
  models (C-LIF over time against ReLU on one frame), not between inputs. It costs conv1 10x the MACs
  of a 2-channel input (the energy table counts them).
- "sum": the bins summed over time (2 channels, event counts per pixel, 0..10): SCTN's layer sizes
  exactly, but the 1 ms timing is gone. A named option, off by default.

The output is returned as a one-step "voltage" trace (B, 1, 2): the code written for SCTN, which takes
each output's maximum over time (the eq. 5-6 loss of sctn/loss.py, training and fine-tuning of
sctn/training/snn.py, candidate scoring of sctn/tracker.py), runs the twin unchanged, with the target unit's
output standing for V_max. So its loss mirrors eq. 5-6 on its output: it should reach theta + R_s on
positives and stay below theta - 0.3 on negatives.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Literal

import numpy as np
import torch
from pydantic import ConfigDict
from torch import nn
from torch.nn import functional as F

from dvsot.events import EventBatch
from sctn.encoding import PRESET, encode_boxes
from sctn.energy import count_macs
from sctn.network import NetworkConfig, drop_background

KIND = "sctn_ann"
TWIN_INPUTS = ("bins", "sum")


class TwinConfig(NetworkConfig):
    """SCTN's layer sizes (NetworkConfig; its neuron fields are unused) and the twin's input form."""

    model_config = ConfigDict(extra="forbid")

    input: Literal["bins", "sum"] = "bins"

    def in_channels(self) -> int:
        """Input channels of conv1: 2 polarities x steps ("bins") or 2 ("sum")."""
        return 2 * self.steps if self.input == "bins" else 2


class SCTNTwin(nn.Module):
    """SCTN's convolutions and fully connected layers with ReLU: a conventional ANN of the same structure."""

    def __init__(self, cfg: TwinConfig | None = None) -> None:
        super().__init__()
        self.cfg = cfg = cfg or TwinConfig()
        chans = (cfg.in_channels(),) + tuple(cfg.channels)
        self.convs = nn.ModuleList(nn.Conv2d(chans[i], chans[i + 1], cfg.kernels[i], cfg.strides[i], bias=cfg.bias)
                                   for i in range(3))
        widths = (cfg.channels[-1] * cfg.conv_sizes()[-1] ** 2,) + tuple(cfg.fc) + (2,)
        self.fcs = nn.ModuleList(nn.Linear(widths[i], widths[i + 1], bias=cfg.bias) for i in range(3))
        for layer in list(self.convs) + list(self.fcs):  # He init for ReLU
            nn.init.kaiming_uniform_(layer.weight, a=0.0)
            if layer.bias is not None:
                nn.init.zeros_(layer.bias)
        if not cfg.background_neuron:  # as SCTN leaves it out (sctn.network)
            drop_background(self.fcs[2])

    def frame(self, x: torch.Tensor) -> torch.Tensor:
        """SCTN's input spikes (B, T, 2, H, W) as the twin's frame (B, C, H, W)."""
        if self.cfg.input == "sum":
            return x.sum(dim=1)
        return x.reshape(x.shape[0], -1, *x.shape[3:])  # (step, polarity) -> channel 2 step + polarity

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """Outputs (B, 1, 2) for input spikes x (B, T, 2, H, W): one step of SCTN's (B, T, 2) voltages."""
        h = self.frame(x)
        for conv in self.convs:
            h = F.relu(conv(h))
        h = h.flatten(1)
        for k, fc in enumerate(self.fcs):
            h = fc(h)
            if k < 2:
                h = F.relu(h)
        return self.with_background(h)[:, None]

    def with_background(self, h: torch.Tensor) -> torch.Tensor:
        """Output units (..., outputs) in the (..., 2) layout, a constant 0 for a background unit left out."""
        return h if self.cfg.background_neuron else torch.cat([torch.zeros_like(h), h], dim=-1)

    def score(self, x: torch.Tensor) -> torch.Tensor:
        """The target unit's output per candidate (B,), SCTN's maximum target voltage."""
        return self(x)[:, 0, 1]

    def candidate_scores(self, events: EventBatch, t0_us: int, boxes_xywh: np.ndarray) -> np.ndarray:
        """score() of each candidate box's encoded canvas (N,), computed from the events: conv1's kernel equals its
        stride, so each canvas pixel feeds one conv1 cell and conv1 is a sum of the weight columns of the pixels
        that hold an event (the dense canvas is ~99% zeros); the same outputs as encode_boxes + score to float
        rounding (test), in less time. MACs are still counted as a conventional ANN runs it: dense."""
        cfg = self.cfg
        k, cells = cfg.kernels[0], cfg.conv_sizes()[0]
        if k != cfg.strides[0]:
            boxes = np.asarray(boxes_xywh, np.float32).reshape(-1, 4)
            with torch.no_grad():
                return torch.cat([self.score(encode_boxes(events, t0_us, boxes[i:i + 64], cfg))
                                  for i in range(0, len(boxes), 64)]).numpy()
        n = len(np.asarray(boxes_xywh).reshape(-1, 4))
        b, step, pol, v, u = canvas_pixels(events, t0_us, boxes_xywh, cfg)
        ok = (v < cells * k) & (u < cells * k)  # beyond the last window: read by no conv1 cell
        b, step, pol, v, u = b[ok], step[ok], pol[ok], v[ok], u[ok]
        ch = 2 * step + pol if cfg.input == "bins" else pol  # "sum": each event-step adds its column once
        conv1 = self.convs[0]
        with torch.no_grad():
            columns = conv1.weight.permute(1, 2, 3, 0).reshape(-1, conv1.out_channels)  # (channel, row, col) rows
            cell = torch.from_numpy((b * cells + v // k) * cells + u // k)
            col = torch.from_numpy((ch * k + v % k) * k + u % k)
            h = torch.zeros(n * cells * cells, conv1.out_channels).index_add_(0, cell, columns[col])
            h = F.relu(h if conv1.bias is None else h + conv1.bias).view(n, cells, cells, -1).permute(0, 3, 1, 2)
            for conv in self.convs[1:]:
                h = F.relu(conv(h))
            h = h.flatten(1)
            for j, fc in enumerate(self.fcs):
                h = fc(h) if j == 2 else F.relu(fc(h))
        return h[:, -1].numpy()  # the target unit: the last one, with or without the background unit


def canvas_pixels(events: EventBatch, t0_us: int, boxes_xywh: np.ndarray,
                  cfg: NetworkConfig = PRESET) -> tuple[np.ndarray, ...]:
    """The nonzero entries of encode_boxes' tensor, each once: box index, step, polarity, canvas row, column
    (int64 arrays; the same mapping as sctn.encoding.encode_boxes, held equal by a test)."""
    size, steps, step_us = cfg.input_size, cfg.steps, cfg.step_us
    boxes = np.asarray(boxes_xywh, np.float32).reshape(-1, 4)
    empty = (np.zeros(0, np.int64),) * 5
    step = (np.asarray(events.t, np.int64) - int(t0_us)) // step_us
    keep = (step >= 0) & (step < steps)
    ex = events.x[keep].astype(np.float32) + 0.5  # pixel centres
    ey = events.y[keep].astype(np.float32) + 0.5
    ep, es = events.p[keep].astype(np.int64), step[keep]
    if len(boxes) == 0 or ex.size == 0:
        return empty
    x0, y0, w, h = (boxes[:, i:i + 1] for i in range(4))
    bi, ei = np.nonzero((ex >= x0) & (ex < x0 + w) & (ey >= y0) & (ey < y0 + h))
    scale = np.minimum(1.0, size / np.maximum(boxes[:, 2], boxes[:, 3]))
    cx, cy = boxes[:, 0] + boxes[:, 2] / 2, boxes[:, 1] + boxes[:, 3] / 2
    u = np.floor((ex[ei] - cx[bi]) * scale[bi] + size / 2).astype(np.int64)
    v = np.floor((ey[ei] - cy[bi]) * scale[bi] + size / 2).astype(np.int64)
    ok = (u >= 0) & (u < size) & (v >= 0) & (v < size)
    flat = np.unique((((bi[ok] * steps + es[ei][ok]) * 2 + ep[ei][ok]) * size + v[ok]) * size + u[ok])
    flat, u = np.divmod(flat, size)
    flat, v = np.divmod(flat, size)
    flat, p = np.divmod(flat, 2)
    b, s = np.divmod(flat, steps)
    return b, s, p, v, u


def twin_macs(model: SCTNTwin) -> dict:
    """MACs of one candidate evaluation of the twin, in total and per layer (counted on a 1-candidate batch)."""
    cfg = model.cfg
    return count_macs(model, torch.zeros(1, cfg.steps, 2, cfg.input_size, cfg.input_size))


def train_twin(files: list[Path], cfg, progress: bool = True, **validation) -> tuple[SCTNTwin, dict]:
    """Train a new twin exactly as sctn.training.snn.train trains SCTN (same segments, samples, loss, optimiser,
    budget); cfg is a sctn.training.snn.TrainConfig whose network is a TwinConfig (a NetworkConfig is taken as input
    "bins"); `validation` (val_files, val_score) as sctn.training.snn.train takes them."""
    from sctn.training.snn import train

    if cfg.ops_penalty > 0:
        raise ValueError("the ANN twin has no spikes to penalise: ops_penalty must be 0")
    if not isinstance(cfg.network, TwinConfig):
        cfg = cfg.model_copy(update={"network": TwinConfig(**cfg.network.model_dump())})
    return train(files, cfg, progress=progress, build=SCTNTwin, **validation)


def default_twin_path() -> Path:
    """The twin checkpoint shipped beside SCTN's (trained by `dvsot train --model sctn_ann`)."""
    from sctn.checkpoint import CHECKPOINT_DIR

    return CHECKPOINT_DIR / "sctn_ann_dvsot21.pt"


def load_twin(path: str | os.PathLike | None = None) -> tuple[SCTNTwin, dict]:
    """The twin and metadata of a sctn_ann checkpoint (the shipped one if path is None); UserError if unusable; a
    TrainingRuleWarning naming what differs when it was trained with another recipe than `dvsot train`'s."""
    import warnings

    from sctn.checkpoint import TrainingRuleWarning, load_model
    from sctn.training.snn import training_note

    model, meta = load_model(path, default_twin_path(), KIND, "sctn_ann",
                             lambda blob: SCTNTwin(TwinConfig(**blob["config"])), article="an")
    note = training_note(meta.get("train_config"), TwinConfig(), skip_network=())
    if note:
        warnings.warn(f"{path or default_twin_path()}: {note}", TrainingRuleWarning, stacklevel=2)
    return model, meta
