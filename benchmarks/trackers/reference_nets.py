"""The published trackers' networks at their papers' sizes, untrained, for counting multiply-accumulates.

Built here from the papers' descriptions (no released code or weights), three input channels (RGB)
as published:
- SiamRPN (Li et al. 2018): AlexNet trunk with conv2/conv4 groups removed (96-256-384-384-256), RPN
  with k = 5 anchors, "up-channel" correlation: the template's features become 2k and 4k kernels of
  256 channels (3x3 convs to 256 x 2k and 256 x 4k channels), correlated with the search features
  after a 3x3 conv each; template 127, search 271 (the tracking size, score map 19x19) or 255.
- SiamMask (Wang et al. 2019, its appendix's architecture tables, three-branch variant): ResNet-50's conv1 to
  conv4_x with output stride 8 (conv4_x stride 1, dilation 2), conv1 unpadded (61x61 / 125x125
  maps), conv3_x's stride-2 3x3 unpadded (15x15 / 31x31), adjust 1x1 to 256; depth-wise correlation
  (17x17x256); heads 1x1 256 then 1x1 to 2k scores, 4k box offsets and 63x63 = 3969 mask logits per
  position (RoW). The mask refinement module is not built (optional in the paper, run on one RoW).
  conv3_x's first projection shortcut is ResNet's 1x1 stride 2, taken on the centre-aligned grid so its
  15x15 / 31x31 output meets the main path's.
- GOTURN (Held et al. 2016): CaffeNet conv1-conv5 (grouped conv2/4/5, pool5 6x6x256) on two 227x227
  crops, three fully connected layers of 4096, then 4 box outputs.
- Ocean (Zhang et al. 2020), offline model, as read from its paper with widths it leaves open assumed:
  SiamMask's trunk (ResNet-50 to conv4_x, output stride 8, adjust to 256) with the template map centre-
  cropped to 7x7; per branch (classification, regression) a feature combination of three parallel
  3x3 convolutions of dilation (1,1), (1,2), (2,1) on template and search features, depth-wise correlated
  and summed (25x25x256); towers of four 3x3 convolutions of 256; regression 3x3 to 4 distances,
  classification 3x3 to 1; the object-aware branch's feature alignment counted as the 3x3 convolution
  it computes after sampling (256 channels, then 1x1 to 1): bilinear sampling is not a MAC.
- AutoMatch (Zhang et al. 2021), as read from its paper with what it leaves open assumed: Ocean's trunk here
  (ResNet-50 to conv4_x, output stride 8, adjust to 256) on its 128 / 256 px crops (template map 15x15, its centre
  7x7 as the target's region; search map 31x31); per branch the operators of benchmarks/trackers/automatch (the
  combination recalled as its searched one, operators.py's 1x1 maps at 256 channels, all template cells in the
  target mask); Ocean's towers and heads above on the 31x31 matched maps.
"""

from __future__ import annotations

from collections import OrderedDict

import torch
from torch import nn
from torch.nn import functional as F


def conv_bn(cin: int, cout: int, k: int, stride: int = 1, padding: int = 0, dilation: int = 1,
            relu: bool = True) -> nn.Sequential:
    """Convolution (no bias), batch norm, optional ReLU."""
    layers = [nn.Conv2d(cin, cout, k, stride, padding, dilation, bias=False), nn.BatchNorm2d(cout)]
    return nn.Sequential(*layers, *([nn.ReLU(inplace=True)] if relu else []))


def up_channel_xcorr(x: torch.Tensor, kernels: torch.Tensor, outputs: int) -> torch.Tensor:
    """SiamRPN's correlation: search features (B, C, H, W) with per-sample kernels (B, outputs * C, h, w) ->
    (B, outputs, H - h + 1, W - w + 1), as one grouped convolution over the batch."""
    b, c, h, w = x.shape
    k = kernels.reshape(b * outputs, c, kernels.shape[-2], kernels.shape[-1])
    out = F.conv2d(x.reshape(1, b * c, h, w), k, groups=b)
    return out.reshape(b, outputs, out.shape[-2], out.shape[-1])


def depthwise_xcorr(x: torch.Tensor, kernels: torch.Tensor) -> torch.Tensor:
    """Depth-wise correlation: search (B, C, H, W) with template (B, C, h, w), channel by channel -> (B, C, H', W')."""
    b, c, h, w = x.shape
    out = F.conv2d(x.reshape(1, b * c, h, w), kernels.reshape(b * c, 1, kernels.shape[-2], kernels.shape[-1]),
                   groups=b * c)
    return out.reshape(b, c, out.shape[-2], out.shape[-1])


class SiameseNet(nn.Module):
    """A Siamese tracker's network split as it runs: `template` once per initialisation (its features or kernels
    are cached), `track` once per frame on the search crop; `forward(z, x)` runs both (one training pass)."""

    template_size: int
    search_size: int

    def template(self, z: torch.Tensor):
        """What the tracker caches from the template crop z (B, 3, template_size, template_size)."""
        raise NotImplementedError

    def track(self, cached, x: torch.Tensor):
        """The per-frame outputs from the search crop x (B, 3, search_size, search_size)."""
        raise NotImplementedError

    def forward(self, z: torch.Tensor, x: torch.Tensor):
        """Template and search branch together."""
        return self.track(self.template(z), x)


def alexnet_trunk() -> nn.Sequential:
    """SiamRPN's AlexNet: conv1 11x11/2 96, pool, conv2 5x5 256, pool, conv3-5 3x3 384, 384, 256; no padding."""
    return nn.Sequential(OrderedDict([
        ("conv1", conv_bn(3, 96, 11, 2)), ("pool1", nn.MaxPool2d(3, 2)),
        ("conv2", conv_bn(96, 256, 5)), ("pool2", nn.MaxPool2d(3, 2)),
        ("conv3", conv_bn(256, 384, 3)), ("conv4", conv_bn(384, 384, 3)), ("conv5", conv_bn(384, 256, 3, relu=False)),
    ]))


class SiamRPN(SiameseNet):
    """SiamRPN (Li et al. 2018): AlexNet trunk and the up-channel region proposal head, k anchors."""

    def __init__(self, search_size: int = 271, template_size: int = 127, anchors: int = 5, channels: int = 256):
        super().__init__()
        self.template_size, self.search_size, self.k = template_size, search_size, anchors
        self.backbone = alexnet_trunk()
        self.cls_z = nn.Conv2d(channels, channels * 2 * anchors, 3)
        self.reg_z = nn.Conv2d(channels, channels * 4 * anchors, 3)
        self.cls_x = nn.Conv2d(channels, channels, 3)
        self.reg_x = nn.Conv2d(channels, channels, 3)

    def template(self, z: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """The classification and regression kernels (B, 2k C, 4, 4), (B, 4k C, 4, 4)."""
        f = self.backbone(z)
        return self.cls_z(f), self.reg_z(f)

    def track(self, cached, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Scores (B, 2k, S, S) and box offsets (B, 4k, S, S); S = 19 at search 271, 17 at 255."""
        f = self.backbone(x)
        return (up_channel_xcorr(self.cls_x(f), cached[0], 2 * self.k),
                up_channel_xcorr(self.reg_x(f), cached[1], 4 * self.k))


class Bottleneck(nn.Module):
    """ResNet-50's bottleneck: 1x1, 3x3 (stride, dilation), 1x1 to 4x width, with a projection shortcut when the
    shape changes; `padding` of the 3x3 (SiamMask leaves conv3_x's stride-2 3x3 unpadded)."""

    def __init__(self, cin: int, width: int, stride: int = 1, dilation: int = 1, padding: int | None = None):
        super().__init__()
        pad = dilation if padding is None else padding
        self.conv1 = conv_bn(cin, width, 1)
        self.conv2 = conv_bn(width, width, 3, stride, pad, dilation)
        self.conv3 = conv_bn(width, width * 4, 1, relu=False)
        self.shift = (3 - 1) // 2 * dilation - pad  # where the 3x3's first output centre falls in the input
        self.downsample = conv_bn(cin, width * 4, 1, stride, relu=False) if stride != 1 or cin != width * 4 else None

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """Residual block output."""
        out = self.conv3(self.conv2(self.conv1(x)))
        if self.downsample is None:
            return F.relu(out + x)
        s = self.shift  # the shortcut samples the grid the 3x3's output centres lie on
        short = self.downsample(x[:, :, s:, s:])[:, :, :out.shape[2], :out.shape[3]]
        return F.relu(out + short)


def resnet50_stage(cin: int, width: int, blocks: int, stride: int = 1, dilation: int = 1,
                   first_padding: int | None = None) -> nn.Sequential:
    """One ResNet-50 stage: `blocks` bottlenecks, the first one changing stride and width."""
    layers = [Bottleneck(cin, width, stride, dilation, first_padding)]
    layers += [Bottleneck(width * 4, width, 1, dilation) for _ in range(blocks - 1)]
    return nn.Sequential(*layers)


def resnet50_os8() -> nn.Sequential:
    """SiamMask's trunk: ResNet-50 conv1 to conv4_x at output stride 8, then the adjust layer (1x1 to 256)."""
    return nn.Sequential(OrderedDict([
        ("conv1", conv_bn(3, 64, 7, 2)), ("pool", nn.MaxPool2d(3, 2, 1)),
        ("conv2_x", resnet50_stage(64, 64, 3)),
        ("conv3_x", resnet50_stage(256, 128, 4, stride=2, first_padding=0)),
        ("conv4_x", resnet50_stage(512, 256, 6, dilation=2)),
        ("adjust", conv_bn(1024, 256, 1, relu=False)),
    ]))


def head(outputs: int, channels: int = 256) -> nn.Sequential:
    """SiamMask's per-branch head on the correlation: conv5 1x1 to 256 (BN, ReLU), conv6 1x1 to `outputs`."""
    return nn.Sequential(OrderedDict([("conv5", conv_bn(channels, channels, 1)),
                                      ("conv6", nn.Conv2d(channels, outputs, 1))]))


class SiamMask(SiameseNet):
    """SiamMask (Wang et al. 2019), three-branch variant without the refinement module."""

    def __init__(self, search_size: int = 255, template_size: int = 127, anchors: int = 5, mask_side: int = 63):
        super().__init__()
        self.template_size, self.search_size = template_size, search_size
        self.backbone = resnet50_os8()
        self.score, self.box, self.mask = head(2 * anchors), head(4 * anchors), head(mask_side * mask_side)

    def template(self, z: torch.Tensor) -> torch.Tensor:
        """The template's adjusted features (B, 256, 15, 15)."""
        return self.backbone(z)

    def track(self, cached: torch.Tensor, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Scores (B, 2k, 17, 17), box offsets (B, 4k, 17, 17), mask logits (B, 3969, 17, 17)."""
        corr = depthwise_xcorr(self.backbone(x), cached)
        return self.score(corr), self.box(corr), self.mask(corr)


class BoxRegressor(SiameseNet):
    """GOTURN's split: both crops through one trunk (`backbone`) every frame, their features side by side through
    fully connected layers (`regressor`) to a box; nothing of the template is computed ahead."""

    backbone: nn.Module
    regressor: nn.Module

    def template(self, z: torch.Tensor) -> torch.Tensor:
        """The previous frame's crop, kept as pixels: it changes every frame, so nothing is computed ahead."""
        return z

    def track(self, cached: torch.Tensor, x: torch.Tensor) -> torch.Tensor:
        """Box outputs (B, 4) of previous crops (B, C, S, S) and current crops (B, C, S, S): one trunk pass."""
        both = self.backbone(torch.cat([cached, x]))
        b = x.shape[0]
        return self.regressor(torch.cat([both[:b].flatten(1), both[b:].flatten(1)], dim=1))


def caffenet_trunk() -> nn.Sequential:
    """CaffeNet conv1-conv5 with pool5: 227x227 -> 6x6x256 (conv2, conv4, conv5 in two groups)."""
    def conv(cin, cout, k, s=1, p=0, g=1):
        return nn.Sequential(nn.Conv2d(cin, cout, k, s, p, groups=g), nn.ReLU(inplace=True))
    return nn.Sequential(OrderedDict([
        ("conv1", conv(3, 96, 11, 4)), ("pool1", nn.MaxPool2d(3, 2)), ("norm1", nn.LocalResponseNorm(5)),
        ("conv2", conv(96, 256, 5, p=2, g=2)), ("pool2", nn.MaxPool2d(3, 2)), ("norm2", nn.LocalResponseNorm(5)),
        ("conv3", conv(256, 384, 3, p=1)), ("conv4", conv(384, 384, 3, p=1, g=2)),
        ("conv5", conv(384, 256, 3, p=1, g=2)),
        ("pool5", nn.MaxPool2d(3, 2)),
    ]))


class GOTURN(BoxRegressor):
    """GOTURN (Held et al. 2016): both crops through CaffeNet every frame, fc 4096 x 3, 4 box outputs."""

    def __init__(self, size: int = 227, hidden: int = 4096):
        super().__init__()
        self.template_size = self.search_size = size
        self.backbone = caffenet_trunk()
        self.regressor = nn.Sequential(OrderedDict([
            ("fc6", nn.Linear(2 * 256 * 6 * 6, hidden)), ("relu6", nn.ReLU(inplace=True)),
            ("fc7", nn.Linear(hidden, hidden)), ("relu7", nn.ReLU(inplace=True)),
            ("fc7b", nn.Linear(hidden, hidden)), ("relu7b", nn.ReLU(inplace=True)),
            ("fc8", nn.Linear(hidden, 4)),
        ]))


class Ocean(SiameseNet):
    """Ocean (Zhang et al. 2020), offline: anchor-free regression and object-aware classification (module doc)."""

    DILATIONS = ((1, 1), (1, 2), (2, 1))

    def __init__(self, search_size: int = 255, template_size: int = 127, channels: int = 256, tower: int = 4,
                 crop: int = 7):
        super().__init__()
        self.template_size, self.search_size, self.crop = template_size, search_size, crop
        self.backbone = resnet50_os8()

        def combination() -> nn.ModuleDict:
            def convs() -> nn.ModuleList:
                return nn.ModuleList([conv_bn(channels, channels, 3, dilation=d) for d in self.DILATIONS])
            return nn.ModuleDict({"template": convs(), "search": convs()})

        def towers() -> nn.Sequential:
            return nn.Sequential(*[conv_bn(channels, channels, 3, padding=1) for _ in range(tower)])

        self.cls_combine, self.reg_combine = combination(), combination()
        self.cls_tower, self.reg_tower = towers(), towers()
        self.reg_pred = nn.Conv2d(channels, 4, 3, padding=1)
        self.cls_pred = nn.Conv2d(channels, 1, 3, padding=1)
        self.align = conv_bn(channels, channels, 3, padding=1)  # the alignment's convolution after sampling
        self.align_pred = nn.Conv2d(channels, 1, 1)

    def template(self, z: torch.Tensor) -> tuple[list[torch.Tensor], list[torch.Tensor]]:
        """Per branch, the three dilated template kernels from the centre 7x7 of the template map."""
        f = self.backbone(z)
        lo = (f.shape[-1] - self.crop) // 2
        f = f[:, :, lo:lo + self.crop, lo:lo + self.crop]
        return [c(f) for c in self.cls_combine["template"]], [c(f) for c in self.reg_combine["template"]]

    @staticmethod
    def combine(combination: nn.ModuleDict, kernels: list[torch.Tensor], f: torch.Tensor) -> torch.Tensor:
        """Sum over the dilations of the depth-wise correlation of the dilated search and template features."""
        return sum(depthwise_xcorr(conv(f), k) for conv, k in zip(combination["search"], kernels))

    def track(self, cached, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Distances (B, 4, 25, 25), classification (B, 1, 25, 25) and object-aware score (B, 1, 25, 25)."""
        f = self.backbone(x)
        reg = self.reg_pred(self.reg_tower(self.combine(self.reg_combine, cached[1], f)))
        cls_feat = self.cls_tower(self.combine(self.cls_combine, cached[0], f))
        return reg, self.cls_pred(cls_feat), self.align_pred(self.align(cls_feat))


class AutoMatch(SiameseNet):
    """AutoMatch (Zhang et al. 2021): operator matching per branch and Ocean's heads (module doc)."""

    def __init__(self, search_size: int = 256, template_size: int = 128, channels: int = 256, tower: int = 4,
                 crop: int = 7, reg_ops: tuple[str, ...] = ("pairwise_relation", "film"),
                 cls_ops: tuple[str, ...] = ("simple_transformer", "transductive_guidance")):
        super().__init__()
        from benchmarks.trackers.automatch.operators import Matching

        self.template_size, self.search_size, self.crop = template_size, search_size, crop
        self.backbone = resnet50_os8()
        self.reg_match = Matching(reg_ops, channels, crop * crop)
        self.cls_match = Matching(cls_ops, channels, crop * crop)

        def towers() -> nn.Sequential:
            return nn.Sequential(*[conv_bn(channels, channels, 3, padding=1) for _ in range(tower)])

        self.cls_tower, self.reg_tower = towers(), towers()
        self.reg_pred = nn.Conv2d(channels, 4, 3, padding=1)
        self.cls_pred = nn.Conv2d(channels, 1, 3, padding=1)
        self.align = conv_bn(channels, channels, 3, padding=1)
        self.align_pred = nn.Conv2d(channels, 1, 1)

    def template(self, z: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """The centre 7x7 of the template map and its target mask (all ones: the mask costs no MAC)."""
        f = self.backbone(z)
        lo = (f.shape[-1] - self.crop) // 2
        f = f[:, :, lo:lo + self.crop, lo:lo + self.crop]
        return f, f.new_ones(f.shape[0], 1, self.crop, self.crop)

    def track(self, cached, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Distances (B, 4, 31, 31), classification (B, 1, 31, 31) and object-aware score (B, 1, 31, 31)."""
        f = self.backbone(x)
        reg = self.reg_pred(self.reg_tower(self.reg_match(cached[0], f, cached[1])))
        cls_feat = self.cls_tower(self.cls_match(cached[0], f, cached[1]))
        return reg, self.cls_pred(cls_feat), self.align_pred(self.align(cls_feat))


def count_siamese(net: SiameseNet, device: str = "meta") -> dict:
    """MACs of one frame (search branch and head on the cached template), one initialisation (the template branch)
    and one pass of both, for a batch of one; on the meta device nothing is computed."""
    from sctn.macs import count_macs

    net = net.to(device).eval()
    z = torch.zeros(1, 3, net.template_size, net.template_size, device=device)
    x = torch.zeros(1, 3, net.search_size, net.search_size, device=device)
    with torch.no_grad():
        cached = net.template(z)
    frame = count_macs(lambda xs: net.track(cached, xs), x, root=net)
    init = count_macs(net.template, z, root=net)
    both = count_macs(net, z, x)
    return {"per_frame": frame, "init": init, "template_and_search": both}
