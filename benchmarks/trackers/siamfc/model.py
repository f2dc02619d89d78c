"""SiamFC (Bertinetto et al. 2016) sized for a CPU: one backbone on exemplar and search crops, cross-correlation.

The backbone is fully convolutional without padding (so a shift of the search crop shifts the response
exactly), total stride 8, like SiamFC's AlexNet but narrower and with 3x3 kernels after the first layer:

| layer | kernel, stride | channels | exemplar 127 | search 255 |
|---|---|---|---|---|
| conv1 + BN + ReLU | 5, 2 | 1 -> 24 | 62 | 126 |
| max pool | 3, 2 | | 30 | 62 |
| conv2 + BN + ReLU | 3, 1 | 24 -> 32 | 28 | 60 |
| max pool | 3, 2 | | 13 | 29 |
| conv3 + BN + ReLU | 3, 1 | 32 -> 64 | 11 | 27 |
| conv4 + BN + ReLU | 3, 1 | 64 -> 64 | 9 | 25 |
| conv5 + BN | 3, 1 | 64 -> 32 | 7 | 23 |

The exemplar's 7x7x32 features slide over the search region's 23x23x32 (cross-correlation, one
group per pair) into a 17x17 response, scaled by a learned gain and offset (SiamFC's 0.001 "adjust"
layer). Input: one channel, the ATSLTD frame (paper eq. 11) divided by 255.
"""

from __future__ import annotations

import os
from pathlib import Path

import torch
from pydantic import BaseModel, ConfigDict, Field
from torch import nn
from torch.nn import functional as F

KIND = "siamfc"
CHECKPOINT_DIR = Path(__file__).resolve().parent / "checkpoints"
TOTAL_STRIDE = 8  # of the backbone: conv1 2 x pool 2 x pool 2


class SiamFCConfig(BaseModel):
    """Backbone widths (channels of conv1..conv5) and crop sizes (px) of the network."""

    model_config = ConfigDict(extra="forbid")

    channels: tuple[int, int, int, int, int] = (24, 32, 64, 64, 32)
    exemplar_size: int = Field(127, ge=39)
    search_size: int = Field(255, ge=39)

    def feature_size(self, size: int) -> int:
        """Side of the backbone's output for an input of `size` px."""
        s = (size - 5) // 2 + 1
        s = (s - 3) // 2 + 1 - 2
        s = (s - 3) // 2 + 1
        return s - 6

    def response_size(self) -> int:
        """Side of the response map (cells)."""
        return self.feature_size(self.search_size) - self.feature_size(self.exemplar_size) + 1


class SiamFC(nn.Module):
    """Shared backbone + cross-correlation; forward(z, x) -> response (B, 1, R, R) for crops (B, 1, S, S)."""

    def __init__(self, cfg: SiamFCConfig | None = None) -> None:
        super().__init__()
        self.cfg = cfg = cfg or SiamFCConfig()
        c = (1,) + tuple(cfg.channels)

        def block(i: int, k: int, stride: int = 1, relu: bool = True) -> list[nn.Module]:
            layers = [nn.Conv2d(c[i], c[i + 1], k, stride), nn.BatchNorm2d(c[i + 1])]
            return layers + [nn.ReLU(inplace=True)] if relu else layers

        self.backbone = nn.Sequential(*block(0, 5, 2), nn.MaxPool2d(3, 2), *block(1, 3), nn.MaxPool2d(3, 2),
                                      *block(2, 3), *block(3, 3), *block(4, 3, relu=False))
        self.gain = nn.Parameter(torch.tensor(1e-3))
        self.offset = nn.Parameter(torch.tensor(0.0))
        if cfg.feature_size(cfg.exemplar_size) < 1 or cfg.response_size() < 1:
            raise ValueError(f"exemplar {cfg.exemplar_size} px and search {cfg.search_size} px give no response")

    def features(self, x: torch.Tensor) -> torch.Tensor:
        """Backbone features (B, C, F, F) of crops (B, 1, S, S)."""
        return self.backbone(x)

    def correlate(self, z_feat: torch.Tensor, x_feat: torch.Tensor) -> torch.Tensor:
        """Response (B, 1, R, R): each exemplar's features (1 or B of them) correlated with its search features."""
        b, c, h, w = x_feat.shape
        if z_feat.shape[0] == 1 and b > 1:
            out = F.conv2d(x_feat, z_feat)  # one exemplar over every search crop (the scale pyramid)
        else:
            out = F.conv2d(x_feat.reshape(1, b * c, h, w), z_feat, groups=b).view(b, 1, h - z_feat.shape[2] + 1, -1)
        return out * self.gain + self.offset

    def forward(self, z: torch.Tensor, x: torch.Tensor) -> torch.Tensor:
        """Response maps (B, 1, R, R) of exemplar crops z (B or 1, 1, Sz, Sz) on search crops x (B, 1, Sx, Sx)."""
        return self.correlate(self.features(z), self.features(x))


def default_siamfc_path() -> Path:
    """The SiamFC weights shipped with the benchmarks (trained by `dvsot train --model siamfc`)."""
    return CHECKPOINT_DIR / "siamfc_dvsot21.pt"


def load_siamfc(path: str | os.PathLike | None = None) -> tuple[SiamFC, dict]:
    """The network and metadata of a siamfc checkpoint (the shipped one if path is None); UserError if unusable."""
    from sctn.checkpoint import load_model

    return load_model(path, default_siamfc_path(), KIND, "siamfc", lambda blob: SiamFC(SiamFCConfig(**blob["config"])))
