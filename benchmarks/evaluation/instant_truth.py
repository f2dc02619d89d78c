"""Ground truth at any instant: the target's boxes (amodal and visible) interpolated between the rendered samples.

A rendered file's box track (`/boxes/t`, `Dataset.boxes()`) is sampled where the image motion is bounded
(dvsot.render.sample_times): between two consecutive samples no tracked scene point moves more than
`max_displacement_px` (d, default 0.75 px; the file's resolved scene, `sampling.max_displacement_px`), unless
the maximum render rate capped the step.

The error bound, per box edge. A box edge (x0 = min x, x1 = max x, and the same in y) is an extreme of the
projected silhouette; a minimum or maximum of points that each move at most d moves at most d. So on a
sample interval [t_a, t_b] the true edge e(t) is within d of e(t_a) and of e(t_b), and the linear blend
L(t) = (1 - w) e(t_a) + w e(t_b) is within (1 - w) d + w d = d of e(t). Hence x and y of the interpolated
box are within d of the truth and w and h within 2 d. The rendered boxes themselves are read from pixel
masks (whole pixels), so a box rendered at the query time differs from the interpolated one by at most
d + 1 px per edge (`interpolation_bound_px`). The bound assumes the tracked points bound the silhouette's
motion (they are sampled on the objects' surfaces) and holds for the visible box too where the occluders
are tracked objects. An annotated recording is not interpolated: its ground truth exists only at its
annotations, and a streaming evaluation queries it only there (`query_times`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dvsot.dataset.boxes import interpolate_boxes
from dvsot.dataset.format import BoxTrack

PIXEL_QUANTISATION_PX = 1.0  # a rendered box's edges lie on whole pixels of its mask
MIN_QUERY_HZ, MAX_QUERY_HZ = 1.0, 1e6  # the query rates a streaming evaluation accepts


def interpolation_bound_px(max_displacement_px: float) -> tuple[float, float]:
    """(edge, side) error bounds in pixels of an interpolated box against one rendered at the same instant:
    each edge (so x and y) within d + 1 px, width and height within 2 (d + 1) px."""
    edge = float(max_displacement_px) + PIXEL_QUANTISATION_PX
    return edge, 2.0 * edge


@dataclass(frozen=True)
class InstantTruth:
    """Boxes at query times: t (us, the queries), xywh and xywh_visible (Q, 4) float64 pixels, NaN = absent."""

    t: np.ndarray
    xywh: np.ndarray
    xywh_visible: np.ndarray


def truth_at(track: BoxTrack, t_us: np.ndarray) -> InstantTruth:
    """The track's amodal and visible boxes at the query times (microseconds), linear between samples; NaN outside
    the track or next to an absent sample."""
    t = np.asarray(t_us, dtype=np.int64).ravel()
    return InstantTruth(t, interpolate_boxes(track.t, track.xywh, t), interpolate_boxes(track.t, track.xywh_visible, t))


def query_times(track: BoxTrack, start_us: int, stop_us: int, rate_hz: float, annotated: bool = False) -> np.ndarray:
    """Query instants (us, int64) after start_us and up to stop_us: every 1/rate_hz from start_us for a rendered
    track (whole microseconds, rounded), the annotations' own times for an annotated recording."""
    if not MIN_QUERY_HZ <= rate_hz <= MAX_QUERY_HZ:
        raise ValueError(f"query rate must be within {MIN_QUERY_HZ:g}..{MAX_QUERY_HZ:g} Hz, got {rate_hz:g}")
    if annotated:
        t = np.asarray(track.t, np.int64)
        return t[(t > start_us) & (t <= stop_us)]
    n = int(np.floor((stop_us - start_us) * rate_hz / 1e6 + 1e-9))
    return start_us + np.round(np.arange(1, n + 1) * (1e6 / rate_hz)).astype(np.int64)
