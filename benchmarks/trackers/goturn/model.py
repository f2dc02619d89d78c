"""GOTURN (Held et al. 2016) sized for a CPU: one CaffeNet trunk on both crops, fully connected box regression.

Narrowing (named in the benchmark's row, measured by `narrowing()` against reference_nets.GOTURN): every
convolution has a quarter of CaffeNet's channels (96-256-384-384-256 -> 24-64-96-96-64) without its groups and
with batch normalisation in place of local response normalisation (trained from scratch); the three fully
connected layers have 128 units instead of 4096, so that the shipped checkpoint stays a few MB (fc6 alone,
2 x 64 x 6 x 6 inputs, is 0.6 M weights at 128 units and 2.4 M at 512); one input channel (the ATSLTD frame,
paper eq. 11, divided by 255) instead of RGB. Crops 227 px, kernels, strides and pooling are CaffeNet's:

| layer | kernel, stride, pad | channels | 227 px crop |
|---|---|---|---|
| conv1 + BN + ReLU, max pool 3/2 | 11, 4, 0 | 1 -> 24 | 55 -> 27 |
| conv2 + BN + ReLU, max pool 3/2 | 5, 1, 2 | 24 -> 64 | 27 -> 13 |
| conv3, conv4 + BN + ReLU | 3, 1, 1 | 64 -> 96 -> 96 | 13 |
| conv5 + BN + ReLU, max pool 3/2 | 3, 1, 1 | 96 -> 64 | 13 -> 6 |
| fc6, fc7, fc7b + ReLU | | 2 x 64 x 6 x 6 -> 128 -> 128 -> 128 | |
| fc8 | | 128 -> 4 | |

The previous frame's crop and the current frame's pass the same trunk; their pool5 features are concatenated.
fc8's bias starts at the output for "no motion" (the previous box, the middle half of the search crop), so that
an untrained network starts by holding the box still (trained from scratch; GOTURN starts from CaffeNet).
"""

from __future__ import annotations

import os
from collections import OrderedDict

import torch
from pydantic import BaseModel, ConfigDict, Field
from torch import nn

from benchmarks.trackers.reference_nets import BoxRegressor, conv_bn

KIND = "goturn"
NO_MOTION = (2.5, 2.5, 7.5, 7.5)  # crops.encode of the previous box in its own region (context 2)
NARROWING = "conv channels /4 (24-64-96-96-64), fc 128 (4096), BN for LRN, 1 input channel"


class GOTURNConfig(BaseModel):
    """Trunk widths (conv1..conv5), fully connected width and the crops' side (px)."""

    model_config = ConfigDict(extra="forbid")

    channels: tuple[int, int, int, int, int] = (24, 64, 96, 96, 64)
    hidden: int = Field(128, ge=1)
    size: int = Field(227, ge=1)

    def feature_size(self) -> int:
        """Side of pool5's output for a crop of `size` px."""
        s = (self.size - 11) // 4 + 1
        s = (s - 3) // 2 + 1
        s = (s - 3) // 2 + 1
        return (s - 3) // 2 + 1


class GOTURN(BoxRegressor):
    """forward(previous crops, current crops) (B, 1, S, S) each -> (B, 4) box outputs (crops.encode's form);
    template and track as reference_nets.BoxRegressor."""

    def __init__(self, cfg: GOTURNConfig | None = None) -> None:
        super().__init__()
        self.cfg = cfg = cfg or GOTURNConfig()
        if cfg.feature_size() < 1:
            raise ValueError(f"a {cfg.size} px crop gives no pool5 features (at least 67 px)")
        self.template_size = self.search_size = cfg.size
        c = (1,) + tuple(cfg.channels)
        self.backbone = nn.Sequential(OrderedDict([
            ("conv1", conv_bn(c[0], c[1], 11, 4)), ("pool1", nn.MaxPool2d(3, 2)),
            ("conv2", conv_bn(c[1], c[2], 5, padding=2)), ("pool2", nn.MaxPool2d(3, 2)),
            ("conv3", conv_bn(c[2], c[3], 3, padding=1)), ("conv4", conv_bn(c[3], c[4], 3, padding=1)),
            ("conv5", conv_bn(c[4], c[5], 3, padding=1)), ("pool5", nn.MaxPool2d(3, 2))]))
        h = cfg.hidden
        self.regressor = nn.Sequential(OrderedDict([
            ("fc6", nn.Linear(2 * c[5] * cfg.feature_size() ** 2, h)), ("relu6", nn.ReLU(inplace=True)),
            ("fc7", nn.Linear(h, h)), ("relu7", nn.ReLU(inplace=True)),
            ("fc7b", nn.Linear(h, h)), ("relu7b", nn.ReLU(inplace=True)),
            ("fc8", nn.Linear(h, 4))]))
        with torch.no_grad():  # start at "no motion": the previous box in the middle of the search crop
            self.regressor.fc8.bias.copy_(torch.tensor(NO_MOTION))


def load_goturn(path: str | os.PathLike | None = None) -> tuple[GOTURN, dict]:
    """The network and metadata of a goturn checkpoint; UserError in one line if there is none or it is unusable."""
    from benchmarks.trackers.trained_here import load_trained

    return load_trained(path, KIND, "goturn", lambda blob: GOTURN(GOTURNConfig(**blob["config"])))


def narrowing(cfg: GOTURNConfig | None = None) -> dict:
    """The narrowing's name and its measure: parameters and MACs per frame against the paper's GOTURN."""
    from benchmarks.trackers.reference_nets import GOTURN as Reference
    from benchmarks.trackers.trained_here import narrowing as measure

    cfg = cfg or GOTURNConfig()
    return {"narrowing": NARROWING, **measure(GOTURN(cfg), Reference(size=cfg.size))}
