"""Ocean's crops (SiamFC's geometry, benchmarks/trackers/siamfc/crops.py) and where the target lies in them.

The template covers exemplar_extent(wh) px around the target (context 0.5) resized to exemplar_size; the search
region covers that extent x search_size / exemplar_size. A box in a crop is (x0, y0, x1, y1) crop px.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from benchmarks.trackers.siamfc.crops import crop, exemplar_extent

if TYPE_CHECKING:  # the training's frames: the tracker, which imports this module, needs no training code
    from benchmarks.trackers.siamfc.train import Frames


def box_in_crop(box_xywh: np.ndarray, centre_xy: np.ndarray, extent_px: float, out_px: int) -> np.ndarray:
    """The sensor box (x, y, w, h px) in the crop of side extent_px centred at centre_xy, resized to out_px: its
    x0 y0 x1 y1 in crop px."""
    s = out_px / extent_px
    x0 = (box_xywh[0] - centre_xy[0]) * s + out_px / 2
    y0 = (box_xywh[1] - centre_xy[1]) * s + out_px / 2
    return np.array([x0, y0, x0 + box_xywh[2] * s, y0 + box_xywh[3] * s])


def pair_crops(frames: Frames, ez: int, ex: int, rng: np.random.Generator, exemplar_size: int, search_size: int,
               shift_px: float, stretch: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Template crop of frame ez, search crop of frame ex (its centre off the target by up to shift_px crop px a
    side, its extent scaled by up to 1 +- stretch), the target's box in the search crop and in the template crop."""
    bz, bx = frames.boxes[ez], frames.boxes[ex]
    cz = bz[:2] + bz[2:] / 2
    z_ext = exemplar_extent(bz[2:])
    z = crop(frames.dense(ez), tuple(cz), z_ext, exemplar_size)
    x_ext = exemplar_extent(bx[2:]) * search_size / exemplar_size * (1.0 + rng.uniform(-stretch, stretch))
    shift = rng.uniform(-shift_px, shift_px, 2)
    centre = bx[:2] + bx[2:] / 2 - shift * x_ext / search_size
    x = crop(frames.dense(ex), tuple(centre), x_ext, search_size)
    return z, x, box_in_crop(bx, centre, x_ext, search_size), box_in_crop(bz, cz, z_ext, exemplar_size)
