"""GOTURN's crops and box parametrisation.

Both crops cover `context` (GOTURN's 2) times the previous box's width and height around its centre, resized to
size x size (so a crop is anisotropic when the box is not square), 0 outside the sensor (ATSLTD's "no event").
The network's four outputs are the box's corners in the search crop, (x1, y1, x2, y2) / size x SCALE (GOTURN's
scale factor 10): 0..10 spans the crop. Coordinates: pixels, (x, y), pixel i covering [i, i + 1).

Motion augmentation (GOTURN's "learning from motion smoothness"): the search crop of a training pair is centred on
the current box moved by (w dx, h dy) and sized by (gw, gh) before the context, dx, dy ~ Laplace(0, 1 /
`lambda_shift`) and g = 1 + Laplace(0, 1 / `lambda_scale`) clipped to 1 +- `max_scale` (GOTURN: 5, 15, 0.4).
"""

from __future__ import annotations

import cv2
import numpy as np

CONTEXT = 2.0
SCALE = 10.0


def region(box_xywh: np.ndarray, context: float = CONTEXT) -> np.ndarray:
    """The crop region (x, y, w, h) px of a box: context times its size around its centre (at least 1 px)."""
    b = np.asarray(box_xywh, np.float64)
    size = np.maximum(b[2:] * context, 1.0)
    return np.concatenate([b[:2] + b[2:] / 2 - size / 2, size])


def crop_region(frame: np.ndarray, rect: np.ndarray, size: int) -> np.ndarray:
    """The region rect (x, y, w, h px) of a frame resized to size x size (float32, bilinear, 0 outside)."""
    sx, sy = rect[2] / size, rect[3] / size
    # crop px u maps to sensor coordinate x + (u + 0.5) sx in our convention, minus 0.5 in cv2's
    m = np.array([[sx, 0.0, rect[0] + 0.5 * sx - 0.5], [0.0, sy, rect[1] + 0.5 * sy - 0.5]])
    return cv2.warpAffine(np.ascontiguousarray(frame, np.float32), m, (size, size),
                          flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP, borderMode=cv2.BORDER_CONSTANT,
                          borderValue=0.0)


def encode(box_xywh: np.ndarray, rect: np.ndarray) -> np.ndarray:
    """The network's target (4,) for a box (x, y, w, h px) in the crop region rect: corners / rect size x SCALE."""
    b, r = np.asarray(box_xywh, np.float64), np.asarray(rect, np.float64)
    x1, y1 = (b[0] - r[0]) / r[2], (b[1] - r[1]) / r[3]
    return np.array([x1, y1, x1 + b[2] / r[2], y1 + b[3] / r[3]]) * SCALE


def decode(out: np.ndarray, rect: np.ndarray) -> np.ndarray:
    """The box (x, y, w, h px) of the network's output (4,) in the crop region rect: encode's inverse."""
    o, r = np.asarray(out, np.float64) / SCALE, np.asarray(rect, np.float64)
    x1, y1 = r[0] + o[0] * r[2], r[1] + o[1] * r[3]
    return np.array([x1, y1, (o[2] - o[0]) * r[2], (o[3] - o[1]) * r[3]])


def shifted_box(box_xywh: np.ndarray, rng: np.random.Generator, lambda_shift: float = 5.0,
                lambda_scale: float = 15.0, max_scale: float = 0.4) -> np.ndarray:
    """A box moved and scaled by GOTURN's Laplace motion model (the search crop's centre and size in training)."""
    b = np.asarray(box_xywh, np.float64)
    g = np.clip(1.0 + rng.laplace(0.0, 1.0 / lambda_scale, 2), 1.0 - max_scale, 1.0 + max_scale)
    d = rng.laplace(0.0, 1.0 / lambda_shift, 2)
    size = b[2:] * g
    centre = b[:2] + b[2:] / 2 + b[2:] * d
    return np.concatenate([centre - size / 2, size])
