"""SiamFC's crops of an ATSLTD frame: a square around the target with context, resized, zero outside the frame.

Sizes as in SiamFC: the exemplar covers z = sqrt((w + p)(h + p)) px with p = context (w + h) (context
0.5), resized to exemplar_size; the search region covers z x search_size / exemplar_size px around the
same centre, resized to search_size, so the target has the same scale in both. Outside the sensor
the crop is 0, which in an ATSLTD frame means "no event" (SiamFC pads with the mean colour).
Coordinates: pixels, (x, y), pixel i covering [i, i + 1).
"""

from __future__ import annotations

import cv2
import numpy as np

CONTEXT = 0.5


def exemplar_extent(wh: np.ndarray, context: float = CONTEXT) -> float:
    """Side (px) of the square the exemplar covers for a target of size wh (px)."""
    w, h = float(wh[0]), float(wh[1])
    p = context * (w + h)
    return float(np.sqrt((w + p) * (h + p)))


def crop(frame: np.ndarray, centre_xy: tuple[float, float], extent_px: float, out_px: int) -> np.ndarray:
    """The square of side extent_px (sensor px) centred at centre_xy, resized to out_px x out_px (float32,
    bilinear, 0 outside the frame)."""
    s = extent_px / out_px  # sensor px per crop px
    # cv2 samples pixel u at coordinate u (pixel centres at integers): crop px u maps to sensor coordinate
    # (centre - extent / 2 + (u + 0.5) s) in our convention, minus 0.5 in cv2's
    tx = centre_xy[0] - extent_px / 2 + 0.5 * s - 0.5
    ty = centre_xy[1] - extent_px / 2 + 0.5 * s - 0.5
    m = np.array([[s, 0.0, tx], [0.0, s, ty]])
    return cv2.warpAffine(np.ascontiguousarray(frame, np.float32), m, (out_px, out_px),
                          flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP, borderMode=cv2.BORDER_CONSTANT,
                          borderValue=0.0)


def response_labels(size: int, centre_cells: np.ndarray, radius_cells: float) -> np.ndarray:
    """SiamFC's labels (B, 1, size, size): 1 within radius_cells of each (x, y) centre (response cells), else 0."""
    idx = np.arange(size, dtype=np.float32)
    c = np.asarray(centre_cells, np.float32).reshape(-1, 2)
    dx = idx[None, None, :] - c[:, 0, None, None]
    dy = idx[None, :, None] - c[:, 1, None, None]
    return (np.hypot(dx, dy) <= radius_cells).astype(np.float32)[:, None]


def balanced_weights(labels: np.ndarray) -> np.ndarray:
    """Per-cell loss weights giving positives and negatives half the weight each, per map (SiamFC)."""
    pos = labels.sum(axis=(1, 2, 3), keepdims=True)
    neg = labels[0].size - pos
    w_pos = np.where(pos > 0, 0.5 / np.maximum(pos, 1), 0.0)
    w_neg = np.where(neg > 0, 0.5 / np.maximum(neg, 1), 0.0)
    w = labels * w_pos + (1 - labels) * w_neg
    return w / w.sum(axis=(1, 2, 3), keepdims=True) * labels[0].size  # mean weight 1 per map
