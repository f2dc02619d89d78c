"""The anchor-free box geometry of Ocean (and AutoMatch): locations, targets, decoding and the IoU loss.

A response map of R x R cells over a search crop of S px: cell j lies at crop coordinate S / 2 + (j - (R - 1) / 2)
x stride (the networks here are unpadded and centred, so this is exact). At each location (px, py) the network
predicts its distances (l, t, r, b) in crop px to the box's left, top, right and bottom sides; the box is
(px - l, py - t, px + r, py + b). Boxes are (x0, y0, x1, y1) crop px throughout.
"""

from __future__ import annotations

import torch


def locations(size: int, search_px: int, stride: int) -> torch.Tensor:
    """Crop coordinates (px) of the R = `size` cells of one axis."""
    return search_px / 2 + (torch.arange(size, dtype=torch.float32) - (size - 1) / 2) * stride


def decode(dist: torch.Tensor, pos: torch.Tensor) -> torch.Tensor:
    """Boxes (B, 4, R, R) x0 y0 x1 y1 from distances (B, 4, R, R) l t r b at locations `pos` (R,) on both axes."""
    px, py = pos[None, None, :], pos[None, :, None]
    left, top, right, bottom = dist.unbind(1)
    return torch.stack([px - left, py - top, px + right, py + bottom], dim=1)


def assign(boxes: torch.Tensor, pos: torch.Tensor, stride: int) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Targets of target boxes (B, 4) at locations `pos` (R,): distances (B, 4, R, R) l t r b; the regression mask
    (B, 1, R, R), 1 at the locations inside the box; the classification labels (B, 1, R, R), 1 inside the ellipse
    of semi-axes max(w / 4, stride), max(h / 4, stride) around the box centre (always holds the nearest location)."""
    px, py = pos[None, None, :], pos[None, :, None]
    x0, y0, x1, y1 = (boxes[:, k, None, None] for k in range(4))
    dist = torch.stack([(px - x0).expand(-1, len(pos), -1), (py - y0).expand(-1, -1, len(pos)),
                        (x1 - px).expand(-1, len(pos), -1), (y1 - py).expand(-1, -1, len(pos))], dim=1)
    inside = (dist.min(dim=1, keepdim=True).values > 0).float()
    a = ((x1 - x0) / 4).clamp(min=stride)
    b = ((y1 - y0) / 4).clamp(min=stride)
    ell = ((px - (x0 + x1) / 2) / a) ** 2 + ((py - (y0 + y1) / 2) / b) ** 2
    return dist, inside, (ell <= 1).float()[:, None]


def iou_loss(pred: torch.Tensor, target: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """Ocean's IoU loss: mean over the masked locations of -log((I + 1) / (U + 1)) of the boxes given as distances
    (B, 4, R, R) l t r b from the same location (0 when no location is masked)."""
    pl, pt, pr, pb = pred.unbind(1)
    tl, tt, tr, tb = target.clamp(min=0.0).unbind(1)  # outside the box (masked out) a distance is negative
    inter = (torch.minimum(pl, tl) + torch.minimum(pr, tr)) * (torch.minimum(pt, tt) + torch.minimum(pb, tb))
    union = (pl + pr) * (pt + pb) + (tl + tr) * (tt + tb) - inter
    loss = -torch.log((inter + 1.0) / (union + 1.0))
    m = mask[:, 0]
    return (loss * m).sum() / m.sum().clamp(min=1.0)
