"""A small labelled sequence with instance masks (a disc, so its mask is not its box), made in numpy, for the
trackers trained here (SiamMask learns from the masks)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from dvsot.dataset.boxes import object_rows
from dvsot.events import EventParams, EventSimulator
from dvsot.events.labels import TARGET_ID, LabelledFrame, object_table
from dvsot.pipeline.sequence import write_sequence


def disc_file(path: Path, width: int = 64, height: int = 48, radius: float = 8.0, duration_ms: int = 60,
              split: str = "train") -> Path:
    """A bright disc crossing a textured wall at 1 kHz with its object index masks; 10 ms segments."""
    yy, xx = np.mgrid[0:height, 0:width].astype(np.float32)
    wall = 0.15 + 0.05 * np.sin(0.5 * xx) * np.cos(0.4 * yy)
    table = object_table()
    ids_known = np.array([row["id"] for row in table])
    frames, rows, t = [], [], np.arange(duration_ms + 1) * 1000
    for k in range(len(t)):
        cx, cy = 14 + 0.5 * k, 16 + 0.2 * k
        disc = np.hypot(xx + 0.5 - cx, yy + 0.5 - cy) <= radius
        level = wall.copy()
        level[disc] = 0.6 + 0.2 * np.sin(0.8 * xx[disc])
        ids = np.where(disc, TARGET_ID, 0).astype(np.uint8)
        frames.append(LabelledFrame(np.log(level + 1e-3), ids))
        on = float(disc.sum())
        rows.append(object_rows(ids, ids_known, {TARGET_ID: (disc, on, on)}))
    stacked = {name: np.stack([r[name] for r in rows]) for name in rows[0]}

    def boxes() -> dict:
        return {"t_us": t, "xywh": stacked["boxes_amodal"][:, 1], "xywh_visible": stacked["boxes_visible"][:, 1],
                "visibility": stacked["visibility"][:, 1], "truncation": np.zeros(len(t), np.float32),
                "objects": stacked}

    sim = EventSimulator(width, height, EventParams(cp=0.2, cn=0.2), seed=1)
    out, _ = write_sequence(path, frames, t, sim, {"name": path.stem, "split": split}, 10_000, is_log=True,
                            boxes=boxes, masks=True, objects=table)
    return out
