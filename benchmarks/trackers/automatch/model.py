"""AutoMatch (Zhang et al. 2021, "Learn to Match"), sized for a CPU: a shared trunk, per-branch matching by a
fixed combination of the paper's operators (operators.py), Ocean's anchor-free heads.

Trunk: SiamFC's here (unpadded, total stride 8, channels 24-32-64-64-64; AutoMatch uses ResNet-50 to conv4_x
with 256 adjusted channels on 128 / 256 px crops): template 127 px -> 7x7 features (AutoMatch's template is
its target's region of interest, 7x7 too), search 255 px -> 23x23. Each branch (regression, classification)
matches with its operators (`reg_ops`, `cls_ops`), and Ocean's heads (benchmarks/trackers/ocean/model.py
AnchorFreeHead: towers, exp distances, regular and object-aware classification) give 23x23 maps.

The combination: the paper searches, per branch, over its six operators and reports the one it keeps; the
defaults here (regression: pairwise relation and FiLM; classification: simple transformer and transductive
guidance) are that choice as recalled without the paper at hand, not checked against it; both tuples are
config fields (AutoMatchConfig), so another combination trains without a code change (docs/baselines.md).
"""

from __future__ import annotations

import os
from pathlib import Path

import torch
from pydantic import field_validator
from torch import nn

from benchmarks.trackers.automatch.crops import template_mask
from benchmarks.trackers.automatch.operators import OPERATORS, Matching
from benchmarks.trackers.ocean.model import AnchorFreeHead, TrunkConfig, trunk

KIND = "automatch"


class AutoMatchConfig(TrunkConfig):
    """AutoMatch's network: the trunk, head sizes and each branch's operators (see the module doc)."""

    reg_ops: tuple[str, ...] = ("pairwise_relation", "film")
    cls_ops: tuple[str, ...] = ("simple_transformer", "transductive_guidance")

    @field_validator("reg_ops", "cls_ops")
    @classmethod
    def _known(cls, v: tuple[str, ...]) -> tuple[str, ...]:
        bad = [n for n in v if n not in OPERATORS]
        if bad or not v or len(set(v)) != len(v):
            raise ValueError(f"operators {', '.join(v) or '(none)'}: give distinct ones of {', '.join(OPERATORS)}")
        return v

    def response_size(self) -> int:
        """Side of the output maps (cells): the search features' (the operators keep the search grid)."""
        return self.feature_size(self.search_size)


class AutoMatch(nn.Module):
    """AutoMatch: shared trunk, per-branch operator matching, anchor-free heads (module doc)."""

    def __init__(self, cfg: AutoMatchConfig | None = None) -> None:
        super().__init__()
        self.cfg = cfg = cfg or AutoMatchConfig()
        if cfg.feature_size(cfg.exemplar_size) < 1 or cfg.response_size() < 1:
            raise ValueError(f"exemplar {cfg.exemplar_size} px and search {cfg.search_size} px give no features")
        c, cells = cfg.channels[-1], cfg.feature_size(cfg.exemplar_size) ** 2
        self.backbone = trunk(cfg.channels)
        self.reg_match, self.cls_match = Matching(cfg.reg_ops, c, cells), Matching(cfg.cls_ops, c, cells)
        self.head = AnchorFreeHead(c, cfg.tower, cfg.search_size)

    def response_size(self) -> int:
        """Side of the output maps (cells)."""
        return self.cfg.response_size()

    def template(self, z: torch.Tensor, z_box: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """The template features (B, C, h, w) of crops z (B, 1, Sz, Sz) and the target mask of boxes z_box (B, 4)."""
        f = self.backbone(z)
        return f, template_mask(z_box, f.shape[-1], self.cfg.exemplar_size)

    def track(self, cached: tuple[torch.Tensor, torch.Tensor], x: torch.Tensor) -> tuple[torch.Tensor, ...]:
        """Distances, regular and object-aware logits (AnchorFreeHead) of search crops x (B, 1, Sx, Sx)."""
        f = self.backbone(x)
        z, mask = cached
        return self.head(self.reg_match(z, f, mask), self.cls_match(z, f, mask))

    def forward(self, z: torch.Tensor, x: torch.Tensor, z_box: torch.Tensor) -> tuple[torch.Tensor, ...]:
        """Template and search branch together (one training pass)."""
        return self.track(self.template(z, z_box), x)


def default_automatch_path() -> Path:
    """The shipped AutoMatch checkpoint (benchmarks.trackers.trained_here.default_path), if it is there."""
    from benchmarks.trackers.trained_here import default_path

    return default_path(KIND)


def load_automatch(path: str | os.PathLike | None = None) -> tuple[AutoMatch, dict]:
    """The network and metadata of an automatch checkpoint (the shipped one if path is None); UserError in one line if
    there is none or it is unusable."""
    from benchmarks.trackers.trained_here import load_trained

    return load_trained(path, KIND, "automatch", lambda blob: AutoMatch(AutoMatchConfig(**blob["config"])),
                        article="an")
