"""SiamRPN (Li et al. 2018) sized for a CPU: AlexNet trunk with a quarter of its channels, up-channel RPN head.

Narrowing (named in the benchmark's row, measured by `narrowing()` against reference_nets.SiamRPN): every
layer has a quarter of the published channels (trunk 96-256-384-384-256 -> 24-64-96-96-64, RPN head 256 -> 64),
one input channel (the ATSLTD frame, paper eq. 11, divided by 255) instead of RGB, and the search crop is 255 px
(SiamRPN trains at 255 and tracks at 271). Kernels, strides and the anchors (k = 5) are the paper's:

| layer | kernel, stride | channels | template 127 | search 255 |
|---|---|---|---|---|
| conv1 + BN + ReLU, max pool 3/2 | 11, 2 | 1 -> 24 | 59 -> 29 | 123 -> 61 |
| conv2 + BN + ReLU, max pool 3/2 | 5, 1 | 24 -> 64 | 25 -> 12 | 57 -> 28 |
| conv3, conv4 + BN + ReLU | 3, 1 | 64 -> 96 -> 96 | 8 | 24 |
| conv5 + BN | 3, 1 | 96 -> 64 | 6 | 22 |
| cls / reg template conv | 3 | 64 -> 64 x 2k / 64 x 4k | 4 | |
| cls / reg search conv | 3 | 64 -> 64 | | 20 |
| up-channel correlation | | 2k, 4k maps | | 17 x 17 |

The regression map passes a 1x1 "adjust" convolution (4k -> 4k), as in SiamRPN's code. Both correlations are
scaled by 1 / sqrt(fan-in) (head channels x kernel taps): trained from scratch, unscaled correlations of
untrained kernels start with logits in the hundreds (SiamRPN starts from ImageNet weights). Output: scores (B, 2, k,
R, R) (background, target) and offsets (B, 4, k, R, R) on the anchors of anchors.make_anchors.
"""

from __future__ import annotations

import os
from collections import OrderedDict

import torch
from pydantic import BaseModel, ConfigDict, Field
from torch import nn

from benchmarks.trackers.reference_nets import SiameseNet, conv_bn, up_channel_xcorr
from benchmarks.trackers.siamrpn.anchors import RATIOS, SCALE

KIND = "siamrpn"
TOTAL_STRIDE = 8  # conv1 2 x pool 2 x pool 2
NARROWING = "channels /4 (trunk 24-64-96-96-64, head 64), 1 input channel, search 255 px"


class TrunkConfig(BaseModel):
    """The AlexNet trunk's widths (channels of conv1..conv5) and crop sizes (px)."""

    model_config = ConfigDict(extra="forbid")

    channels: tuple[int, int, int, int, int] = (24, 64, 96, 96, 64)
    exemplar_size: int = Field(127, ge=1)
    search_size: int = Field(255, ge=1)

    def feature_size(self, size: int) -> int:
        """Side of the trunk's output for an input of `size` px (no padding)."""
        s = (size - 11) // 2 + 1
        s = (s - 3) // 2 + 1
        s = (s - 5 + 1 - 3) // 2 + 1
        return s - 6


def alexnet_trunk(channels: tuple[int, ...], in_channels: int = 1) -> nn.Sequential:
    """SiamRPN's AlexNet without padding at the given widths: conv1 11/2, pool, conv2 5, pool, conv3-5 3."""
    c = (in_channels,) + tuple(channels)
    return nn.Sequential(OrderedDict([
        ("conv1", conv_bn(c[0], c[1], 11, 2)), ("pool1", nn.MaxPool2d(3, 2)),
        ("conv2", conv_bn(c[1], c[2], 5)), ("pool2", nn.MaxPool2d(3, 2)),
        ("conv3", conv_bn(c[2], c[3], 3)), ("conv4", conv_bn(c[3], c[4], 3)),
        ("conv5", conv_bn(c[4], c[5], 3, relu=False))]))


class SiamRPNConfig(TrunkConfig):
    """The trunk's settings, the RPN head's width and the anchors (aspect ratios h / w, scale in strides)."""

    head_channels: int = Field(64, ge=1)
    ratios: tuple[float, ...] = RATIOS
    anchor_scale: float = Field(SCALE, gt=0)

    def score_size(self) -> int:
        """Side of the score map (cells)."""
        return self.feature_size(self.search_size) - self.feature_size(self.exemplar_size) + 1


class AnchoredNet(SiameseNet):
    """The AlexNet trunk and k anchors per score cell that SiamRPN and SiamMask share; subclasses add the heads
    after it (the trunk's weights are drawn first)."""

    def __init__(self, cfg: SiamRPNConfig) -> None:
        super().__init__()
        self.cfg = cfg
        if cfg.feature_size(cfg.exemplar_size) < 3 or cfg.score_size() < 1:
            raise ValueError(f"exemplar {cfg.exemplar_size} px and search {cfg.search_size} px give no score map")
        self.template_size, self.search_size, self.k = cfg.exemplar_size, cfg.search_size, len(cfg.ratios)
        self.backbone = alexnet_trunk(cfg.channels)


def anchored_narrowing(net: AnchoredNet, reference: type[SiameseNet], name: str) -> dict:
    """The narrowing's name and its measure (trained_here.narrowing) of `net` against the paper's network
    `reference` built at the same crop sizes and number of anchors."""
    from benchmarks.trackers.trained_here import narrowing as measure

    cfg = net.cfg
    ref = reference(search_size=cfg.search_size, template_size=cfg.exemplar_size, anchors=len(cfg.ratios))
    return {"narrowing": name, **measure(net, ref)}


class SiamRPN(AnchoredNet):
    """Trunk + up-channel RPN head; template(z) -> kernels, track(kernels, x) -> (scores, offsets)."""

    def __init__(self, cfg: SiamRPNConfig | None = None) -> None:
        super().__init__(cfg or SiamRPNConfig())
        cfg = self.cfg
        c, h = cfg.channels[-1], cfg.head_channels
        self.cls_z = nn.Conv2d(c, h * 2 * self.k, 3)
        self.reg_z = nn.Conv2d(c, h * 4 * self.k, 3)
        self.cls_x = nn.Conv2d(c, h, 3)
        self.reg_x = nn.Conv2d(c, h, 3)
        self.adjust = nn.Conv2d(4 * self.k, 4 * self.k, 1)

    def template(self, z: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Classification and regression kernels (B, 2k H, f, f), (B, 4k H, f, f) of template crops (B, 1, S, S)."""
        f = self.backbone(z)
        return self.cls_z(f), self.reg_z(f)

    def track(self, cached: tuple[torch.Tensor, torch.Tensor], x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Scores (B, 2, k, R, R) and offsets (B, 4, k, R, R) of search crops (B, 1, S, S) on the cached kernels."""
        f = self.backbone(x)
        b = x.shape[0]
        cls_k, reg_k = (t.expand(b, -1, -1, -1) if t.shape[0] == 1 else t for t in cached)
        gain = (self.cfg.head_channels * cls_k.shape[-1] * cls_k.shape[-2]) ** -0.5
        cls = up_channel_xcorr(self.cls_x(f), cls_k, 2 * self.k) * gain
        reg = self.adjust(up_channel_xcorr(self.reg_x(f), reg_k, 4 * self.k) * gain)
        r = cls.shape[-1]
        return cls.view(b, 2, self.k, r, r), reg.view(b, 4, self.k, r, r)


def load_siamrpn(path: str | os.PathLike | None = None) -> tuple[SiamRPN, dict]:
    """The network and metadata of a siamrpn checkpoint; UserError in one line if there is none or it is unusable."""
    from benchmarks.trackers.trained_here import load_trained

    return load_trained(path, KIND, "siamrpn", lambda blob: SiamRPN(SiamRPNConfig(**blob["config"])))


def narrowing(cfg: SiamRPNConfig | None = None) -> dict:
    """The narrowing's name and its measure: parameters and MACs per frame against the paper's SiamRPN at the
    same crop sizes."""
    from benchmarks.trackers.reference_nets import SiamRPN as Reference

    return anchored_narrowing(SiamRPN(cfg), Reference, NARROWING)
