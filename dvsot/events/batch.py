"""The event batch: x, y, t, p (and the signal flags) of events in time order, and tonic's structured layout."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# names of the noise_kind codes, by code: 0 a signal event, then the kinds of noise a sensor model adds
NOISE_KINDS = ("signal", "shot", "leak", "hot")

# tonic's structured event layout (fields x, y, t, p). p is signed (i1) with tonic's values 0 (darker) and
# 1 (brighter): ToFrame indexes its polarity channels by p, and ToVoxelGrid rewrites 0 to -1 in place,
# which an unsigned p turns into 255. Files keep DSEC's unsigned 1/0.
STRUCTURED_DTYPE = np.dtype([("x", np.uint16), ("y", np.uint16), ("t", np.int64), ("p", np.int8)])


@dataclass(frozen=True)
class EventBatch:
    """Events in time order: x, y (pixels, u2), t (microseconds, i8), p (1 brighter, 0 darker, u1), signal (bool or
    None), noise_kind (u1 or None: NOISE_KINDS' codes),
    object (the id of the object that made each event, u1, dvsot.events.labels; None where not labelled)."""

    x: np.ndarray
    y: np.ndarray
    t: np.ndarray
    p: np.ndarray
    signal: np.ndarray | None = None
    noise_kind: np.ndarray | None = None
    object: np.ndarray | None = None

    def __len__(self) -> int:
        return int(self.t.shape[0])

    @staticmethod
    def empty() -> EventBatch:
        """A batch with no events."""
        return EventBatch(np.empty(0, np.uint16), np.empty(0, np.uint16), np.empty(0, np.int64),
                          np.empty(0, np.uint8), np.empty(0, bool))

    @staticmethod
    def concatenate(batches: list[EventBatch]) -> EventBatch:
        """Join batches in the given order (the caller keeps them time-ordered)."""
        if not batches:
            return EventBatch.empty()
        sig = None
        if all(b.signal is not None for b in batches):
            sig = np.concatenate([b.signal for b in batches])
        kind = None
        if all(b.noise_kind is not None for b in batches):
            kind = np.concatenate([b.noise_kind for b in batches])
        obj = None
        if all(b.object is not None for b in batches):
            obj = np.concatenate([b.object for b in batches])
        return EventBatch(np.concatenate([b.x for b in batches]), np.concatenate([b.y for b in batches]),
                          np.concatenate([b.t for b in batches]), np.concatenate([b.p for b in batches]), sig, kind,
                          object=obj)

    def to_structured(self) -> np.ndarray:
        """The events as one structured array x, y, t (us), p (i1: 1 brighter, 0 darker): STRUCTURED_DTYPE."""
        out = np.empty(len(self), STRUCTURED_DTYPE)
        out["x"], out["y"], out["t"], out["p"] = self.x, self.y, self.t, self.p
        return out

    @staticmethod
    def from_structured(events: np.ndarray) -> EventBatch:
        """A batch from a structured array x, y, t (microseconds), p (0/1, -1/+1 or bool), as tonic gives."""
        names = events.dtype.names or ()
        missing = [k for k in "xytp" if k not in names]
        if missing:
            raise ValueError(f"structured events need fields x, y, t, p; missing {', '.join(missing)}")
        p = np.asarray(events["p"])
        if p.dtype.kind != "b":
            bad = (p != 0) & (p != 1) & (p != -1)
            if bad.any():
                i = int(np.flatnonzero(bad)[0])
                raise ValueError(f"structured events: field p of event {i} is {p[i]}, expected 0/1 or -1/+1")
        return EventBatch(events["x"].astype(np.uint16), events["y"].astype(np.uint16),
                          events["t"].astype(np.int64), (p > 0).astype(np.uint8))

    def select(self, mask_or_index: np.ndarray) -> EventBatch:
        """The events picked by a boolean mask or an index array."""
        sig = None if self.signal is None else self.signal[mask_or_index]
        kind = None if self.noise_kind is None else self.noise_kind[mask_or_index]
        obj = None if self.object is None else self.object[mask_or_index]
        return EventBatch(self.x[mask_or_index], self.y[mask_or_index], self.t[mask_or_index],
                          self.p[mask_or_index], sig, kind, object=obj)
