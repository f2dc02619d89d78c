"""Adaptive Time-Surface with Linear Time Decay (ATSLTD): one 8-bit frame per segment of events.

The SCTN paper (eq. 11, after Chen et al. 2019) turns the events of a 10 ms segment into a frame for
conventional (frame-based) trackers:

    t*_i   = t_i - t_earliest                 (t_earliest: the earliest event of the segment)
    F(x,y) = round(255 * t*_latest(x,y) / 10 ms)   at pixels that fired, 0 elsewhere

where t*_latest(x,y) is t* of the latest event at that pixel. We divide by the segment's length in
milliseconds instead of a literal 10, so the frame spans 0..255 for any segment length; with the
default 10 ms segments it is eq. 11 exactly. Polarity is ignored, as in the paper. Note that a pixel
whose only event is the segment's earliest one gets 0, like a pixel without events (eq. 11 as written).
"""

from __future__ import annotations

import numpy as np

from dvsot.core.defaults import SEGMENT_US
from dvsot.events import EventBatch


def atsltd_frame(events: EventBatch, width: int, height: int, window_us: int = SEGMENT_US) -> np.ndarray:
    """The eq. 11 frame (uint8, height x width) of a batch of events spanning window_us microseconds."""
    if window_us <= 0:
        raise ValueError(f"window_us must be positive, got {window_us}")
    frame = np.zeros(height * width, dtype=np.int64)
    n = len(events)
    if n == 0:
        return frame.reshape(height, width).astype(np.uint8)
    t = np.asarray(events.t, dtype=np.int64)
    x = np.asarray(events.x, dtype=np.int64)
    y = np.asarray(events.y, dtype=np.int64)
    keep = (x < width) & (y < height)
    # t* + 1 so that "no event" (0) stays distinguishable while taking the per-pixel maximum.
    tstar = t - t.min() + 1
    latest = np.zeros(height * width, dtype=np.int64)
    np.maximum.at(latest, (y * width + x)[keep], tstar[keep])
    fired = latest > 0
    # round half to even (numpy) vs half up: equal except at exact .5 ties; use floor(v + 0.5) = round half up.
    values = np.floor(255.0 * (latest[fired] - 1) / float(window_us) + 0.5)
    frame[fired] = np.clip(values, 0, 255).astype(np.int64)
    return frame.reshape(height, width).astype(np.uint8)


def atsltd_frame_bgr(events: EventBatch, width: int, height: int, window_us: int = SEGMENT_US) -> np.ndarray:
    """The eq. 11 frame repeated into three channels (uint8, height x width x 3) for OpenCV trackers."""
    gray = atsltd_frame(events, width, height, window_us)
    return np.repeat(gray[:, :, None], 3, axis=2)
