"""SiamMask (Wang et al. 2019) sized for a CPU: three branches on depth-wise correlations of a narrowed trunk.

Narrowing (named in the benchmark's row, measured by `narrowing()` against reference_nets.SiamMask): the trunk is
SiamRPN's AlexNet at a quarter of its channels (benchmarks/trackers/siamrpn/model.py: 24-64-96-96-64, one input
channel) instead of ResNet-50 to conv4 (1024 channels, adjusted to 256); the branches have 64 channels instead of
256; the mask is 31 x 31 per response window instead of 63 x 63; no refinement module (optional in the paper).
Crops: template 127, search 255 px, as in the paper.

Each branch (scores, boxes, mask), as SiamMask's three-branch variant: the template and the search features
pass a 3x3 conv + BN + ReLU each (6 -> 4, 22 -> 20), are correlated channel by channel (depth-wise, 17 x 17,
scaled by 1 / sqrt(kernel taps) for training from scratch), then a 1x1 conv + BN + ReLU and a 1x1 conv to 2k
scores, 4k anchor offsets (k = 5 anchors of SiamRPN, benchmarks/trackers/siamrpn/anchors.py) or m x m mask
logits of the response window (RoW) of each cell: the exemplar_size x exemplar_size square of the search crop
centred on the cell.
"""

from __future__ import annotations

import os

import torch
from pydantic import Field
from torch import nn

from benchmarks.trackers.reference_nets import conv_bn, depthwise_xcorr
from benchmarks.trackers.siamrpn.model import AnchoredNet, SiamRPNConfig, anchored_narrowing

KIND = "siammask"
NARROWING = ("trunk AlexNet/4 (24-64-96-96-64) for ResNet-50, branches 64 channels, mask 31x31, "
             "1 input channel")


class SiamMaskConfig(SiamRPNConfig):
    """SiamRPN's trunk and anchor settings (head_channels: the branches' width) and the mask's side (cells)."""

    mask_side: int = Field(31, ge=2)


class DepthCorr(nn.Module):
    """One branch: 3x3 conv + BN + ReLU on template and search features, depth-wise correlation, 1x1 head."""

    def __init__(self, channels: int, hidden: int, outputs: int) -> None:
        super().__init__()
        self.conv_kernel = conv_bn(channels, hidden, 3)
        self.conv_search = conv_bn(channels, hidden, 3)
        self.head = nn.Sequential(conv_bn(hidden, hidden, 1), nn.Conv2d(hidden, outputs, 1))

    def forward(self, kernel: torch.Tensor, x_feat: torch.Tensor) -> torch.Tensor:
        """Outputs (B, outputs, R, R) of the branch's template kernel (B or 1, H, f, f) on search features."""
        b = x_feat.shape[0]
        kernel = kernel.expand(b, -1, -1, -1) if kernel.shape[0] == 1 else kernel
        corr = depthwise_xcorr(self.conv_search(x_feat), kernel) * (kernel.shape[-1] * kernel.shape[-2]) ** -0.5
        return self.head(corr)


class SiamMask(AnchoredNet):
    """Trunk + three depth-wise branches; template(z) -> kernels, track(kernels, x) -> (scores, offsets, masks)."""

    def __init__(self, cfg: SiamMaskConfig | None = None) -> None:
        super().__init__(cfg or SiamMaskConfig())
        cfg = self.cfg
        c, h = cfg.channels[-1], cfg.head_channels
        self.score = DepthCorr(c, h, 2 * self.k)
        self.box = DepthCorr(c, h, 4 * self.k)
        self.mask = DepthCorr(c, h, cfg.mask_side ** 2)

    def template(self, z: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Each branch's template kernel (B, H, f, f) of template crops (B, 1, S, S)."""
        f = self.backbone(z)
        return self.score.conv_kernel(f), self.box.conv_kernel(f), self.mask.conv_kernel(f)

    def track(self, cached: tuple, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Scores (B, 2, k, R, R), offsets (B, 4, k, R, R) and mask logits (B, m, m, R, R) of search crops."""
        f = self.backbone(x)
        b = x.shape[0]
        scores, offsets, masks = (branch(k, f) for branch, k in zip((self.score, self.box, self.mask), cached))
        r, m = scores.shape[-1], self.cfg.mask_side
        return scores.view(b, 2, self.k, r, r), offsets.view(b, 4, self.k, r, r), masks.view(b, m, m, r, r)


def load_siammask(path: str | os.PathLike | None = None) -> tuple[SiamMask, dict]:
    """The network and metadata of a siammask checkpoint; UserError in one line if there is none or it is unusable."""
    from benchmarks.trackers.trained_here import load_trained

    return load_trained(path, KIND, "siammask", lambda blob: SiamMask(SiamMaskConfig(**blob["config"])))


def narrowing(cfg: SiamMaskConfig | None = None) -> dict:
    """The narrowing's name and its measure: parameters and MACs per frame against the paper's SiamMask (three
    branches, ResNet-50) at the same crop sizes."""
    from benchmarks.trackers.reference_nets import SiamMask as Reference

    return anchored_narrowing(SiamMask(cfg), Reference, NARROWING)
