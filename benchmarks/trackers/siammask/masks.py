"""SiamMask's mask targets on the search crop and the box taken from a predicted mask.

Response window (RoW) of score cell (column i, row j) of an R x R map: the exemplar_size-px square of the search
crop centred at the cell's position S / 2 + (i - (R - 1) / 2) stride (x) and likewise (y), S the search crop's side
(the trunk has no padding). Its mask target is that square of the target's mask in the search crop, resized to
m x m (bilinear, a float in 0..1).

Box from a mask (SiamMask's tracking output): the mask probabilities are resized to the window's side in
search-crop px and thresholded (`threshold`, SiamMask's 0.35); the box is either the axis-aligned rectangle of the
pixels above it ("axis", SiamMask's "min-max"), or the axis-aligned hull of their minimum-area rotated rectangle
("minarea", SiamMask's MBR, made upright for xywh boxes). Pixel u covers [u, u + 1).
"""

from __future__ import annotations

from typing import Literal

import cv2
import numpy as np

from benchmarks.trackers.siamfc.crops import crop


def window_centre(row: int, col: int, score_size: int, stride: int, search_size: int) -> tuple[float, float]:
    """Centre (x, y) in search-crop px of the response window of cell (row, col)."""
    half = (score_size - 1) / 2
    return search_size / 2 + (col - half) * stride, search_size / 2 + (row - half) * stride


def mask_targets(mask_crop: np.ndarray, cells: np.ndarray, score_size: int, stride: int, window: int,
                 side: int) -> np.ndarray:
    """Mask targets (N, side, side) float32 of cells (N, 2) (row, col) from the target mask of a search crop."""
    s = mask_crop.shape[0]
    return np.stack([crop(mask_crop, window_centre(int(r), int(c), score_size, stride, s), window, side)
                     for r, c in np.asarray(cells).reshape(-1, 2)]) if len(cells) else np.zeros((0, side, side),
                                                                                            np.float32)


def mask_box(prob: np.ndarray, threshold: float, mode: Literal["axis", "minarea"] = "axis") -> np.ndarray:
    """The box (x, y, w, h) in prob's pixels of the pixels above threshold; NaN if none is."""
    ys, xs = np.nonzero(prob > threshold)
    if len(xs) == 0:
        return np.full(4, np.nan)
    if mode == "axis":
        x0, y0 = xs.min(), ys.min()
        return np.array([x0, y0, xs.max() + 1 - x0, ys.max() + 1 - y0], np.float64)
    # every pixel's four corners, so that the rectangle covers whole pixels as "axis" does
    corners = np.concatenate([np.stack([xs + dx, ys + dy], 1) for dx in (0, 1) for dy in (0, 1)]).astype(np.float32)
    pts = cv2.boxPoints(cv2.minAreaRect(corners))
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    return np.array([lo[0], lo[1], hi[0] - lo[0], hi[1] - lo[1]], np.float64)


def window_probabilities(logits: np.ndarray, window: int) -> np.ndarray:
    """Mask probabilities (window, window) of one cell's m x m logits, resized to the window's side in crop px."""
    prob = 1.0 / (1.0 + np.exp(-logits.astype(np.float32)))
    return cv2.resize(prob, (window, window), interpolation=cv2.INTER_LINEAR)
