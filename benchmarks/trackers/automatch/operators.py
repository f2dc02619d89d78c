"""AutoMatch's matching operators: template features z (B, C, h, w) and search features x (B, C, H, W) -> matched
search features (B, C, H, W).

The paper replaces the Siamese correlation by operators that fuse the template into the search features, then
searches (Binary Channel Manipulation) which ones each branch keeps. Here, each operator's learned maps are 1x1
convolutions with biases (no normalisation, so a small case computes by hand); the branch sums the operators it
keeps, then group norm and ReLU (`Matching`). g(z) is the template's global average (B, C, 1, 1).
- concatenation: W [x ; g(z)] (1x1 conv of 2C channels);
- pointwise_addition: W (x + g(z));
- pairwise_relation: each search location's dot products with the h w template locations (B, h w, H, W), then W
  (h w -> C);
- film: gamma(g(z)) x + beta(g(z)), gamma and beta 1x1 convs (feature-wise linear modulation);
- simple_transformer: x + W_o (softmax_j(q_i . k_j / sqrt(C)) v_j), q = W_q x, k = W_k z, v = W_v z (one head,
  search locations attending to template locations);
- transductive_guidance: the template's target mask m (B, 1, h, w) carried to each search location by its
  attention over the template locations (softmax of scaled dot products), g_i = sum_j a_ij m_j, then W (x (1 + g)).
"""

from __future__ import annotations

import math

import torch
from torch import nn

from benchmarks.trackers.ocean.model import norm


def pooled(z: torch.Tensor) -> torch.Tensor:
    """The template's global average (B, C, 1, 1)."""
    return z.mean(dim=(2, 3), keepdim=True)


def attention(x: torch.Tensor, z: torch.Tensor) -> torch.Tensor:
    """Softmax over template locations of the scaled dot products: (B, H W, h w)."""
    c = x.shape[1]
    logits = torch.einsum("bci,bcj->bij", x.flatten(2), z.flatten(2)) / math.sqrt(c)
    return torch.softmax(logits, dim=-1)


class Concatenation(nn.Module):
    """W [x ; g(z)]."""

    def __init__(self, c: int, template_cells: int) -> None:
        super().__init__()
        self.w = nn.Conv2d(2 * c, c, 1)

    def forward(self, z: torch.Tensor, x: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        """Matched features (B, C, H, W)."""
        return self.w(torch.cat([x, pooled(z).expand_as(x)], dim=1))


class PointwiseAddition(nn.Module):
    """W (x + g(z))."""

    def __init__(self, c: int, template_cells: int) -> None:
        super().__init__()
        self.w = nn.Conv2d(c, c, 1)

    def forward(self, z: torch.Tensor, x: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        """Matched features (B, C, H, W)."""
        return self.w(x + pooled(z))


class PairwiseRelation(nn.Module):
    """W (x_i . z_j for every template location j)."""

    def __init__(self, c: int, template_cells: int) -> None:
        super().__init__()
        self.w = nn.Conv2d(template_cells, c, 1)

    def forward(self, z: torch.Tensor, x: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        """Matched features (B, C, H, W)."""
        b, _, h, w = x.shape
        rel = torch.einsum("bcj,bci->bji", z.flatten(2), x.flatten(2)).reshape(b, -1, h, w)
        return self.w(rel)


class FiLM(nn.Module):
    """gamma(g(z)) x + beta(g(z))."""

    def __init__(self, c: int, template_cells: int) -> None:
        super().__init__()
        self.gamma, self.beta = nn.Conv2d(c, c, 1), nn.Conv2d(c, c, 1)

    def forward(self, z: torch.Tensor, x: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        """Matched features (B, C, H, W)."""
        g = pooled(z)
        return self.gamma(g) * x + self.beta(g)


class SimpleTransformer(nn.Module):
    """x + W_o (attention of search locations over template locations)."""

    def __init__(self, c: int, template_cells: int) -> None:
        super().__init__()
        self.q, self.k, self.v, self.o = (nn.Conv2d(c, c, 1) for _ in range(4))

    def forward(self, z: torch.Tensor, x: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        """Matched features (B, C, H, W)."""
        b, c, h, w = x.shape
        a = attention(self.q(x), self.k(z))
        out = torch.einsum("bij,bcj->bci", a, self.v(z).flatten(2)).reshape(b, c, h, w)
        return x + self.o(out)


class TransductiveGuidance(nn.Module):
    """W (x (1 + g)), g the template's target mask carried over by the attention."""

    def __init__(self, c: int, template_cells: int) -> None:
        super().__init__()
        self.w = nn.Conv2d(c, c, 1)

    def forward(self, z: torch.Tensor, x: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        """Matched features (B, C, H, W)."""
        b, _, h, w = x.shape
        g = torch.einsum("bij,bj->bi", attention(x, z), mask.flatten(1)).reshape(b, 1, h, w)
        return self.w(x * (1 + g))


OPERATORS: dict[str, type[nn.Module]] = {
    "concatenation": Concatenation, "pointwise_addition": PointwiseAddition, "pairwise_relation": PairwiseRelation,
    "film": FiLM, "simple_transformer": SimpleTransformer, "transductive_guidance": TransductiveGuidance}


class Matching(nn.Module):
    """One branch's matching: the sum of its operators' outputs, group norm (ocean.model.norm), ReLU."""

    def __init__(self, names: tuple[str, ...], c: int, template_cells: int) -> None:
        super().__init__()
        self.names = names
        self.ops = nn.ModuleList([OPERATORS[n](c, template_cells) for n in names])
        self.norm = nn.Sequential(norm(c), nn.ReLU(inplace=True))

    def forward(self, z: torch.Tensor, x: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        """Matched features (B, C, H, W) of template z (B or 1, C, h, w), search x, template mask (B or 1, 1, h, w)."""
        if z.shape[0] == 1 and x.shape[0] > 1:
            z, mask = z.expand(x.shape[0], -1, -1, -1), mask.expand(x.shape[0], -1, -1, -1)
        return self.norm(sum(op(z, x, mask) for op in self.ops))
