"""Template and search crops of a training pair for the RPN trackers (SiamRPN, SiamMask), and the target's box in
the search crop.

The template covers SiamFC's context square z = sqrt((w + p)(h + p)), p = (w + h) / 2, resized to exemplar_size;
the search crop covers z x search_size / exemplar_size around the target, scaled by up to 1 +- `stretch` and
moved so that the target lands up to `shift_px` crop px off its centre (the augmentation of SiamRPN's training:
the target is not always at the centre, so the head must locate it). Crops are 0 outside the sensor
(benchmarks.trackers.siamfc.crops.crop).
"""

from __future__ import annotations

import numpy as np

from benchmarks.trackers.siamfc.crops import crop, exemplar_extent


def centre(box_xywh: np.ndarray) -> tuple[float, float]:
    """Centre (x, y) px of an xywh box."""
    return float(box_xywh[0] + box_xywh[2] / 2), float(box_xywh[1] + box_xywh[3] / 2)


def template_crop(frame: np.ndarray, box_xywh: np.ndarray, exemplar_size: int) -> np.ndarray:
    """The template crop (exemplar_size^2, float32) of a frame around a box."""
    return crop(frame, centre(box_xywh), exemplar_extent(box_xywh[2:]), exemplar_size)


def search_window(box_xywh: np.ndarray, rng: np.random.Generator, exemplar_size: int, search_size: int,
                  shift_px: float, stretch: float) -> tuple[tuple[float, float], float, np.ndarray]:
    """(centre px, extent px) of a training search crop around a box, and the box in it as (cx, cy, w, h) crop px
    from the crop's centre."""
    ext = exemplar_extent(box_xywh[2:]) * search_size / exemplar_size * (1.0 + rng.uniform(-stretch, stretch))
    shift = rng.uniform(-shift_px, shift_px, 2)
    px = search_size / ext  # crop px per sensor px
    c = np.asarray(centre(box_xywh)) - shift / px
    return (float(c[0]), float(c[1])), float(ext), np.array([shift[0], shift[1], box_xywh[2] * px, box_xywh[3] * px])


def search_crop(image: np.ndarray, window: tuple[tuple[float, float], float], search_size: int) -> np.ndarray:
    """The search crop of an image (a frame or a mask) in a window of search_window."""
    return crop(image, window[0], window[1], search_size)
