"""ESIM-style event generation: linear or log intensity frames in, timestamped polarity events out."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class EventBatch:
    """Events in time order: x, y (pixels, u2), t (microseconds, i8), p (1 brighter, 0 darker, u1), signal (bool or None)."""

    x: np.ndarray
    y: np.ndarray
    t: np.ndarray
    p: np.ndarray
    signal: np.ndarray | None = None

    def __len__(self) -> int:
        return int(self.t.shape[0])

    @staticmethod
    def empty() -> "EventBatch":
        """A batch with no events."""
        return EventBatch(np.empty(0, np.uint16), np.empty(0, np.uint16), np.empty(0, np.int64),
                          np.empty(0, np.uint8), np.empty(0, bool))

    @staticmethod
    def concatenate(batches: list["EventBatch"]) -> "EventBatch":
        """Join batches in the given order (the caller keeps them time-ordered)."""
        if not batches:
            return EventBatch.empty()
        sig = None
        if all(b.signal is not None for b in batches):
            sig = np.concatenate([b.signal for b in batches])
        return EventBatch(np.concatenate([b.x for b in batches]), np.concatenate([b.y for b in batches]),
                          np.concatenate([b.t for b in batches]), np.concatenate([b.p for b in batches]), sig)

    def select(self, mask_or_index: np.ndarray) -> "EventBatch":
        """The events picked by a boolean mask or an index array."""
        sig = None if self.signal is None else self.signal[mask_or_index]
        return EventBatch(self.x[mask_or_index], self.y[mask_or_index], self.t[mask_or_index],
                          self.p[mask_or_index], sig)
