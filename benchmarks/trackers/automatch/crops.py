"""AutoMatch's crops are Ocean's (benchmarks/trackers/ocean/crops.py); this adds the template's target mask on the
template feature grid, which transductive guidance carries to the search region."""

from __future__ import annotations

import torch

from benchmarks.trackers.ocean.boxes import locations
from benchmarks.trackers.ocean.model import TOTAL_STRIDE


def template_mask(z_box: torch.Tensor, cells: int, exemplar_size: int) -> torch.Tensor:
    """(B, 1, cells, cells): 1 at the template feature locations inside the target's box z_box (B, 4) x0 y0 x1 y1
    (template-crop px), else 0; the location nearest the box centre is always 1 (a box smaller than a cell)."""
    pos = locations(cells, exemplar_size, TOTAL_STRIDE).to(z_box.device)
    x0, y0, x1, y1 = (z_box[:, k, None] for k in range(4))
    inx = (pos >= x0) & (pos <= x1)
    iny = (pos >= y0) & (pos <= y1)
    mask = (iny[:, :, None] & inx[:, None, :]).float()
    cx = ((x0 + x1) / 2 - pos).abs().argmin(dim=1)
    cy = ((y0 + y1) / 2 - pos).abs().argmin(dim=1)
    mask[torch.arange(len(z_box)), cy, cx] = 1.0
    return mask[:, None]
