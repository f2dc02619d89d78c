"""Which object made each event: label frames (an object id per pixel at each sample) -> an id per event.

The rule (docs/events.md, "Object labels per event"), for an event at pixel (x, y) and time t in
(t0, t1] between the samples t0 and t1, whose label frames give the pixel the ids a (at t0) and b (at t1):

1. a == b, an object: that object (the pixel showed it all along);
2. a == b == background (id 0): if a neighbour of the pixel (its 8-neighbourhood) changed id between the
   samples, the object whose boundary moved there (that neighbour's id by rules 3 and 4; the highest id
   if several), else the background. The renderer's pixel filter (Cycles' Blackman-Harris, 1.5 px wide)
   lets an edge passing next to a pixel change its intensity while the pixel's centre, whose id the
   object-index pass gives, never leaves the background;
3. exactly one of a, b is the background: the other one. The pixel lies on an edge that one object's
   boundary moved over in the interval (its leading edge arriving or its trailing edge leaving), and that
   object made the change the event reports, whatever the time of the event;
4. a and b two different objects: the one of the nearer sample, by the event's time
   (t - t0 < t1 - t: a; otherwise b, so the midpoint goes to the later sample);
5. noise events (signal False: shot noise and leak) get NOISE_ID, whatever the pixel shows.

Ids are small integers (u1): 0 the background (the background plane and the world), 1 the target,
2.. the scene's other objects in the order of the scene file, NOISE_ID the noise. The object table
(`object_table`) lists them with a name and a role.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from dvsot.core.errors import UserError
from dvsot.events.batch import EventBatch

BACKGROUND_ID = 0
TARGET_ID = 1
NOISE_ID = 255
MAX_OBJECTS = NOISE_ID - 2  # ids 2..254 for the objects beside the target
ROLES = ("background", "target", "distractor", "occluder", "noise")
LABEL_DTYPE = np.uint8


@dataclass(frozen=True)
class LabelledFrame:
    """A frame for the simulator (any kind EventSimulator.step takes) with its object ids (height, width) u1."""

    frame: Any
    objects: np.ndarray


def object_table(others: Sequence[tuple[str, str]] = (), target: str = "target",
                 background: str = "background") -> list[dict]:
    """The table of a scene's ids: background 0, target 1, others (name, role) from 2 in order, noise NOISE_ID."""
    if len(others) > MAX_OBJECTS:
        raise UserError(f"objects: {len(others)} objects beside the target, at most {MAX_OBJECTS} get an id "
                        "of their own in the per-event labels")
    rows = [{"id": BACKGROUND_ID, "name": background, "role": "background"},
            {"id": TARGET_ID, "name": target, "role": "target"}]
    rows += [{"id": 2 + i, "name": name, "role": role} for i, (name, role) in enumerate(others)]
    rows.append({"id": NOISE_ID, "name": "noise", "role": "noise"})
    return rows


def table_problem(ids: np.ndarray, names: Sequence[str], roles: Sequence[str]) -> str | None:
    """What is wrong with an object table (ids unique in 0..255, a known role each), or None."""
    ids = np.asarray(ids)
    if not (len(ids) == len(names) == len(roles)):
        return f"/objects/id, /objects/name and /objects/role differ in length ({len(ids)}, {len(names)}, {len(roles)})"
    if len(ids) and (ids.min() < 0 or ids.max() > NOISE_ID):
        return f"/objects/id holds {int(ids.max() if ids.max() > NOISE_ID else ids.min())}, expected 0..{NOISE_ID}"
    if len(np.unique(ids)) != len(ids):
        return "/objects/id holds an id twice"
    bad = [r for r in roles if r not in ROLES]
    if bad:
        return f"/objects/role holds {bad[0]!r}, expected one of {', '.join(ROLES)}"
    targets = [int(i) for i, r in zip(ids, roles) if r == "target"]
    if len(targets) != 1:  # the target's events are the ones a tracker is trained and scored on
        return (f"/objects/role names {len(targets)} targets" + (f" (ids {', '.join(map(str, targets))})"
                if targets else "") + ", expected exactly one row with role 'target'")
    return None


def target_id(table: Sequence[dict]) -> int:
    """The id of an object table's one row with role 'target' (the table is checked: table_problem)."""
    return next(int(row["id"]) for row in table if row["role"] == "target")


def label_frames(before: np.ndarray, after: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(early, late): the id (u1, height x width) an event at each pixel gets by the module's rules 1-4 when it
    is nearer the sample before (early) or after (late); before and after are the label frames at t0 and t1."""
    a, b = np.asarray(before, LABEL_DTYPE), np.asarray(after, LABEL_DTYPE)
    changed = a != b
    out = []
    for nearer in (a, b):
        moved = np.where(a == BACKGROUND_ID, b, np.where(b == BACKGROUND_ID, a, nearer))  # rules 1, 3 and 4
        ring = _max3x3(np.where(changed, moved, BACKGROUND_ID).astype(LABEL_DTYPE))  # rule 2: a moved neighbour
        out.append(np.where(moved == BACKGROUND_ID, ring, moved).astype(LABEL_DTYPE))
    return out[0], out[1]


def _max3x3(ids: np.ndarray) -> np.ndarray:
    """The largest id in each pixel's 3x3 neighbourhood (outside the frame counts as 0)."""
    h, w = ids.shape
    padded = np.zeros((h + 2, w + 2), ids.dtype)
    padded[1:-1, 1:-1] = ids
    out = ids.copy()
    for dy in range(3):
        for dx in range(3):
            if dy != 1 or dx != 1:
                np.maximum(out, padded[dy:dy + h, dx:dx + w], out=out)
    return out


def event_objects(x: np.ndarray, y: np.ndarray, t: np.ndarray, signal: np.ndarray | None, t0: int, t1: int,
                  before: np.ndarray, after: np.ndarray) -> np.ndarray:
    """The object id (u1) of each event at pixel (x, y), time t in (t0, t1] (microseconds), by the module's rule.

    before and after are the label frames (height, width) at t0 and t1; signal False marks noise events.
    """
    early, late = label_frames(before, after)
    pix = np.asarray(y, np.intp) * before.shape[1] + np.asarray(x, np.intp)
    t = np.asarray(t, np.int64)
    later = (t - t0) >= (t1 - t)  # rule 4: the nearer sample, the midpoint to the later one
    out = np.where(later, late.reshape(-1)[pix], early.reshape(-1)[pix])
    if signal is not None:
        out[~np.asarray(signal, bool)] = NOISE_ID
    return out.astype(LABEL_DTYPE, copy=False)


class EventLabeller:
    """Labels each interval's events from the label frames at its two ends (the previous one is kept)."""

    def __init__(self, width: int, height: int) -> None:
        self.width, self.height = int(width), int(height)
        self._prev: np.ndarray | None = None
        self._t_prev: int | None = None

    def label(self, batch: EventBatch, objects: np.ndarray, t_us: int) -> EventBatch:
        """batch (the events up to t_us, microseconds) with its object column; objects: the label frame at t_us."""
        a = np.asarray(objects)
        if a.shape != (self.height, self.width):
            raise UserError(f"label frame has shape {a.shape}, expected ({self.height}, {self.width})")
        if a.dtype.kind not in "ui" or (a.size and (a.min() < 0 or a.max() > NOISE_ID)):
            raise UserError(f"label frame must hold integer ids 0..{NOISE_ID}")
        a = a.astype(LABEL_DTYPE, copy=True)
        if self._prev is None:
            ids = np.full(len(batch), NOISE_ID, LABEL_DTYPE) if len(batch) else np.empty(0, LABEL_DTYPE)
        else:
            ids = event_objects(batch.x, batch.y, batch.t, batch.signal, self._t_prev, int(t_us), self._prev, a)
        self._prev, self._t_prev = a, int(t_us)
        return dataclasses.replace(batch, object=ids)
