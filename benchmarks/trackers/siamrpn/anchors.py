"""SiamRPN's anchors on the score map, its box parametrisation and its training targets.

Boxes are (cx, cy, w, h) in search-crop pixels relative to the crop's centre. Score cell (i, j) (column i, row
j) of an R x R map sits at ((i - (R - 1) / 2) stride, (j - (R - 1) / 2) stride): the trunk has no padding, so
the map's centre is the crop's centre. Each cell holds k anchors of one area (scale x stride)^2 and the
aspect ratios h / w of `ratios`, sized as SiamRPN's code sizes them (w = int(sqrt(area / r)), h = int(w r)).
Offsets (SiamRPN, after Faster R-CNN): dx = (x - xa) / wa, dy = (y - ya) / ha, dw = log(w / wa),
dh = log(h / ha). Targets: an anchor is positive above `pos_iou` IoU with the target, negative below `neg_iou`,
at most `max_pos` positives and `total` samples in all (the rest ignored), as in SiamRPN's training.
"""

from __future__ import annotations

import numpy as np

RATIOS = (0.33, 0.5, 1.0, 2.0, 3.0)
SCALE = 8.0


def anchor_shapes(stride: int, ratios: tuple[float, ...] = RATIOS, scale: float = SCALE) -> np.ndarray:
    """(k, 2) anchor widths and heights (px) of one cell."""
    area = (stride * scale) ** 2
    out = []
    for r in ratios:
        w = int(np.sqrt(area / r))
        out.append((w, int(w * r)))
    return np.asarray(out, np.float64)


def make_anchors(size: int, stride: int, ratios: tuple[float, ...] = RATIOS, scale: float = SCALE) -> np.ndarray:
    """Anchors (4, k, size, size) as (cx, cy, w, h) crop px from the crop's centre; axis 2 rows, axis 3 columns."""
    wh = anchor_shapes(stride, ratios, scale)
    k = len(wh)
    pos = (np.arange(size) - (size - 1) / 2) * stride
    cx = np.broadcast_to(pos[None, None, :], (k, size, size))
    cy = np.broadcast_to(pos[None, :, None], (k, size, size))
    w = np.broadcast_to(wh[:, 0, None, None], (k, size, size))
    h = np.broadcast_to(wh[:, 1, None, None], (k, size, size))
    return np.stack([cx, cy, w, h]).astype(np.float64)


def encode(boxes: np.ndarray, anchors: np.ndarray) -> np.ndarray:
    """Offsets (4, ...) of boxes (4, ...) (cx, cy, w, h; broadcast against the anchors) from the anchors."""
    b, a = np.asarray(boxes, np.float64), np.asarray(anchors, np.float64)
    return np.stack([(b[0] - a[0]) / a[2], (b[1] - a[1]) / a[3], np.log(b[2] / a[2]), np.log(b[3] / a[3])])


def decode(offsets: np.ndarray, anchors: np.ndarray) -> np.ndarray:
    """Boxes (4, ...) (cx, cy, w, h) from offsets (4, ...) on the anchors: encode's inverse."""
    d, a = np.asarray(offsets, np.float64), np.asarray(anchors, np.float64)
    return np.stack([d[0] * a[2] + a[0], d[1] * a[3] + a[1], np.exp(d[2]) * a[2], np.exp(d[3]) * a[3]])


def iou(anchors: np.ndarray, box: np.ndarray) -> np.ndarray:
    """IoU (...) of every anchor (4, ...) with one box (4,), both (cx, cy, w, h)."""
    a, b = np.asarray(anchors, np.float64), np.asarray(box, np.float64)
    ix = np.minimum(a[0] + a[2] / 2, b[0] + b[2] / 2) - np.maximum(a[0] - a[2] / 2, b[0] - b[2] / 2)
    iy = np.minimum(a[1] + a[3] / 2, b[1] + b[3] / 2) - np.maximum(a[1] - a[3] / 2, b[1] - b[3] / 2)
    inter = np.clip(ix, 0, None) * np.clip(iy, 0, None)
    return inter / (a[2] * a[3] + b[2] * b[3] - inter)


def targets(anchors: np.ndarray, box: np.ndarray, rng: np.random.Generator, pos_iou: float = 0.6,
            neg_iou: float = 0.3, max_pos: int = 16, total: int = 64) -> tuple[np.ndarray, np.ndarray]:
    """Labels (k, R, R) (1 positive, 0 negative, -1 ignored) and regression targets (4, k, R, R) of one target box
    (cx, cy, w, h crop px from the centre). With no anchor above pos_iou the best one is positive (the target
    always teaches the regression)."""
    overlap = iou(anchors, box)
    labels = np.full(overlap.shape, -1, np.int64)
    pos = np.flatnonzero(overlap.ravel() > pos_iou)
    if len(pos) == 0:
        pos = np.array([int(np.argmax(overlap))])
    if len(pos) > max_pos:
        pos = rng.choice(pos, max_pos, replace=False)
    neg = np.flatnonzero(overlap.ravel() < neg_iou)
    if len(neg) > total - len(pos):
        neg = rng.choice(neg, total - len(pos), replace=False)
    flat = labels.reshape(-1)
    flat[neg] = 0
    flat[pos] = 1
    return labels, encode(np.asarray(box, np.float64).reshape(4, 1, 1, 1), anchors).astype(np.float32)
