"""Ocean (Zhang et al. 2020), offline model, sized for a CPU: anchor-free box regression and the object-aware
classification branch on a narrow Siamese trunk.

Trunk: SiamFC's here (benchmarks/trackers/siamfc/model.py: unpadded, total stride 8, channels 24-32-64-64-64
instead of Ocean's ResNet-50 to conv4_x with 256 adjusted channels): template 127 px -> 7x7 (Ocean crops its
15x15 template map to the centre 7x7), search 255 px -> 23x23. Group norm throughout, where Ocean has batch
norm (see norm).

Per branch (regression, classification) Ocean's feature combination: three parallel 3x3 convolutions of
dilation (1,1), (1,2), (2,1) on the template and on the search features, each pair depth-wise correlated, the
three summed (17x17xC). Then a tower of `tower` 3x3 convolutions (Ocean: 4 of 256 channels) and
- regression: 3x3 conv to 4, distances exp(a x + b) crop px to the box's sides (Ocean's exp with a learned
  gain a and offset b);
- classification: 3x3 conv to 1 (the regular-region score);
- object-aware classification: at each location, the classification tower's features sampled (bilinearly) at a
  3x3 grid spanning the location's predicted box (Ocean's feature alignment, a deformable 3x3 convolution whose
  offsets come from the box), a 1x1 convolution of the 9 samples to C channels (the 3x3 kernel), ReLU, 1x1 to 1.
  The predicted box is detached here: the alignment learns from classification, the box from the IoU loss.
Input: one channel, the ATSLTD frame (paper eq. 11) divided by 255.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import torch
from pydantic import BaseModel, ConfigDict, Field
from torch import nn
from torch.nn import functional as F

from benchmarks.trackers.ocean.boxes import decode, locations

KIND = "ocean"
TOTAL_STRIDE = 8
DILATIONS = ((1, 1), (1, 2), (2, 1))


class TrunkConfig(BaseModel):
    """Trunk widths (channels of conv1..conv5), head tower depth and crop sizes (px) of an anchor-free network."""

    model_config = ConfigDict(extra="forbid")

    channels: tuple[int, int, int, int, int] = (24, 32, 64, 64, 64)
    tower: int = Field(2, ge=0, le=8)
    exemplar_size: int = Field(127, ge=39, le=511)
    search_size: int = Field(255, ge=39, le=1023)

    def feature_size(self, size: int) -> int:
        """Side of the trunk's output for an input of `size` px (SiamFC's trunk: conv 5/2, pool 3/2, conv 3, pool 3/2,
        three convs 3)."""
        s = (size - 5) // 2 + 1
        s = (s - 3) // 2 + 1 - 2
        s = (s - 3) // 2 + 1
        return s - 6


class OceanConfig(TrunkConfig):
    """Ocean's network: the trunk and head sizes (see the module doc)."""

    def response_size(self) -> int:
        """Side of the response maps (cells): the depth-wise correlation's output."""
        return self.feature_size(self.search_size) - self.feature_size(self.exemplar_size) + 1


def norm(c: int) -> nn.GroupNorm:
    """Group normalisation of c channels in gcd(c, 8) groups.

    Not batch norm: template and search crops differ in event density, so batch statistics of either differ from
    the running ones a tracker uses (with batch norm, a network trained 150 steps had 2.5x its training loss on the
    same pairs in eval mode); group norm computes the same in training and tracking."""
    return nn.GroupNorm(math.gcd(c, 8), c)


def trunk(channels: tuple[int, ...]) -> nn.Sequential:
    """SiamFC's unpadded trunk (total stride 8) on one input channel, group norm for batch norm (see norm)."""
    c = (1,) + tuple(channels)

    def block(i: int, k: int, stride: int = 1, relu: bool = True) -> list[nn.Module]:
        layers = [nn.Conv2d(c[i], c[i + 1], k, stride), norm(c[i + 1])]
        return layers + [nn.ReLU(inplace=True)] if relu else layers

    return nn.Sequential(*block(0, 5, 2), nn.MaxPool2d(3, 2), *block(1, 3), nn.MaxPool2d(3, 2),
                         *block(2, 3), *block(3, 3), *block(4, 3, relu=False))


def conv_bn_relu(cin: int, cout: int, k: int = 3, dilation: tuple[int, int] = (1, 1)) -> nn.Sequential:
    """A size-keeping convolution, group norm, ReLU."""
    pad = (dilation[0] * (k // 2), dilation[1] * (k // 2))
    return nn.Sequential(nn.Conv2d(cin, cout, k, padding=pad, dilation=dilation, bias=False), norm(cout),
                         nn.ReLU(inplace=True))


def depthwise_xcorr(x: torch.Tensor, z: torch.Tensor) -> torch.Tensor:
    """Channel-by-channel correlation of search features (B, C, H, W) with template features (B or 1, C, h, w)."""
    b, c, h, w = x.shape
    z = z.expand(b, -1, -1, -1) if z.shape[0] == 1 else z
    out = F.conv2d(x.reshape(1, b * c, h, w), z.reshape(b * c, 1, z.shape[2], z.shape[3]), groups=b * c)
    return out.reshape(b, c, out.shape[-2], out.shape[-1])


class Combination(nn.Module):
    """Ocean's feature combination: three dilated 3x3 convs on template and search, depth-wise correlated, summed."""

    def __init__(self, channels: int) -> None:
        super().__init__()
        self.template = nn.ModuleList([conv_bn_relu(channels, channels, 3, d) for d in DILATIONS])
        self.search = nn.ModuleList([conv_bn_relu(channels, channels, 3, d) for d in DILATIONS])

    def kernels(self, z: torch.Tensor) -> list[torch.Tensor]:
        """The three dilated template maps (cached per initialisation)."""
        return [conv(z) for conv in self.template]

    def forward(self, kernels: list[torch.Tensor], x: torch.Tensor) -> torch.Tensor:
        """The summed correlations (B, C, R, R)."""
        return sum(depthwise_xcorr(conv(x), k) for conv, k in zip(self.search, kernels))


class AnchorFreeHead(nn.Module):
    """Ocean's heads on matched features of both branches: towers, distances, regular and object-aware scores."""

    def __init__(self, channels: int, tower: int, search_size: int) -> None:
        super().__init__()
        self.search_size = search_size
        self.reg_tower = nn.Sequential(*[conv_bn_relu(channels, channels) for _ in range(tower)])
        self.cls_tower = nn.Sequential(*[conv_bn_relu(channels, channels) for _ in range(tower)])
        self.reg_pred = nn.Conv2d(channels, 4, 3, padding=1)
        self.reg_gain = nn.Parameter(torch.tensor(0.1))
        self.reg_offset = nn.Parameter(torch.tensor(math.log(search_size / 8)))
        self.cls_pred = nn.Conv2d(channels, 1, 3, padding=1)
        self.align = nn.Sequential(nn.Conv2d(9 * channels, channels, 1), nn.ReLU(inplace=True))
        self.align_pred = nn.Conv2d(channels, 1, 1)

    def aligned(self, feat: torch.Tensor, boxes: torch.Tensor) -> torch.Tensor:
        """Features (B, 9 C, R, R): `feat` sampled at the 3x3 grid spanning each location's box (B, 4, R, R) in
        crop px."""
        b, c, r, _ = feat.shape
        pos = locations(r, self.search_size, TOTAL_STRIDE).to(feat.device)
        frac = torch.tensor([0.0, 0.5, 1.0], device=feat.device)  # the box's sides and middle
        # sample points (B, R, R, 3, 3) in crop px, then in the map's normalised coordinates (align_corners=True)
        xs = boxes[:, 0, :, :, None] + frac * (boxes[:, 2] - boxes[:, 0])[..., None]
        ys = boxes[:, 1, :, :, None] + frac * (boxes[:, 3] - boxes[:, 1])[..., None]
        to_norm = 2.0 / ((r - 1) * TOTAL_STRIDE) if r > 1 else 0.0
        gx = ((xs - pos[0]) * to_norm - 1.0)[..., None, :].expand(-1, -1, -1, 3, 3)
        gy = ((ys - pos[0]) * to_norm - 1.0)[..., :, None].expand(-1, -1, -1, 3, 3)
        grid = torch.stack([gx, gy], dim=-1).reshape(b, r, r * 9, 2)
        s = F.grid_sample(feat, grid, mode="bilinear", padding_mode="zeros", align_corners=True)  # (B, C, R, 9R)
        return s.reshape(b, c, r, r, 9).permute(0, 1, 4, 2, 3).reshape(b, c * 9, r, r)

    def forward(self, reg_feat: torch.Tensor, cls_feat: torch.Tensor) -> tuple[torch.Tensor, ...]:
        """Distances (B, 4, R, R) crop px, regular-region logits (B, 1, R, R), object-aware logits (B, 1, R, R)."""
        raw = self.reg_pred(self.reg_tower(reg_feat))
        dist = torch.exp((self.reg_gain * raw + self.reg_offset).clamp(max=math.log(4.0 * self.search_size)))
        t = self.cls_tower(cls_feat)
        pos = locations(t.shape[-1], self.search_size, TOTAL_STRIDE).to(t.device)
        aware = self.align_pred(self.align(self.aligned(t, decode(dist.detach(), pos))))
        return dist, self.cls_pred(t), aware


class Ocean(nn.Module):
    """Ocean: shared trunk, per-branch feature combination, anchor-free heads (module doc)."""

    def __init__(self, cfg: OceanConfig | None = None) -> None:
        super().__init__()
        self.cfg = cfg = cfg or OceanConfig()
        if cfg.feature_size(cfg.exemplar_size) < 1 or cfg.response_size() < 1:
            raise ValueError(f"exemplar {cfg.exemplar_size} px and search {cfg.search_size} px give no response")
        c = cfg.channels[-1]
        self.backbone = trunk(cfg.channels)
        self.reg_combine, self.cls_combine = Combination(c), Combination(c)
        self.head = AnchorFreeHead(c, cfg.tower, cfg.search_size)

    def response_size(self) -> int:
        """Side of the output maps (cells)."""
        return self.cfg.response_size()

    def template(self, z: torch.Tensor, z_box: torch.Tensor | None = None) -> tuple[list, list]:
        """Per branch, the dilated template kernels of crops z (B, 1, Sz, Sz) (z_box, the target's box in the
        template crop, is not used by Ocean)."""
        f = self.backbone(z)
        return self.reg_combine.kernels(f), self.cls_combine.kernels(f)

    def track(self, cached: tuple[list, list], x: torch.Tensor) -> tuple[torch.Tensor, ...]:
        """Distances, regular and object-aware logits (AnchorFreeHead) of search crops x (B, 1, Sx, Sx)."""
        f = self.backbone(x)
        return self.head(self.reg_combine(cached[0], f), self.cls_combine(cached[1], f))

    def forward(self, z: torch.Tensor, x: torch.Tensor, z_box: torch.Tensor | None = None) -> tuple[torch.Tensor, ...]:
        """Template and search branch together (one training pass)."""
        return self.track(self.template(z, z_box), x)


def default_ocean_path() -> Path:
    """The shipped Ocean checkpoint (benchmarks.trackers.trained_here.default_path), if it is there."""
    from benchmarks.trackers.trained_here import default_path

    return default_path(KIND)


def load_ocean(path: str | os.PathLike | None = None) -> tuple[Ocean, dict]:
    """The network and metadata of an ocean checkpoint (the shipped one if path is None); UserError in one line if
    there is none or it is unusable."""
    from benchmarks.trackers.trained_here import load_trained

    return load_trained(path, KIND, "ocean", lambda blob: Ocean(OceanConfig(**blob["config"])), article="an")
