"""Pictures of event data: event frames (ON red, OFF blue on white) with boxes drawn, written as GIF or MP4."""

from __future__ import annotations

import os
from pathlib import Path

import cv2
import numpy as np

from dvsot.events import EventBatch

GT_COLOUR = (40, 170, 40)  # RGB
PALETTE = [(230, 120, 0), (150, 40, 200), (0, 150, 200), (200, 0, 80), (120, 90, 20), (0, 0, 0)]


def event_frame(events: EventBatch, width: int, height: int) -> np.ndarray:
    """An RGB uint8 image: white, pixels whose last event was ON red, OFF blue."""
    img = np.full((height * width, 3), 255, np.uint8)
    if len(events):
        idx = events.y.astype(np.int64) * width + events.x
        # later events overwrite earlier ones at the same pixel (fancy assignment keeps the last)
        img[idx] = np.where(events.p[:, None] > 0, np.array([220, 30, 30], np.uint8), np.array([30, 60, 220], np.uint8))
    return img.reshape(height, width, 3)


def draw_box(img: np.ndarray, xywh: np.ndarray, colour: tuple[int, int, int], label: str | None = None) -> None:
    """Draw a box (xywh pixels) in place; nothing for an absent (NaN) box."""
    b = np.asarray(xywh, float)
    if not np.all(np.isfinite(b)):
        return
    x0, y0, x1, y1 = int(round(b[0])), int(round(b[1])), int(round(b[0] + b[2])) - 1, int(round(b[1] + b[3])) - 1
    cv2.rectangle(img, (x0, y0), (x1, y1), colour, 1)
    if label:
        cv2.putText(img, label, (x0, max(y0 - 3, 8)), cv2.FONT_HERSHEY_SIMPLEX, 0.35, colour, 1, cv2.LINE_AA)


def write_preview(dataset, out_path: str | os.PathLike, boxes: dict[str, np.ndarray] | None = None,
                  start: int = 0, max_segments: int = 300, fps: float = 30.0) -> Path:
    """Write event frames of segments with ground truth (green) and other boxes per segment; .gif or .mp4."""
    from dvsot.dataset import Dataset

    own = not isinstance(dataset, Dataset)
    ds = Dataset(dataset) if own else dataset
    try:
        frames = []
        stop = min(ds.num_segments, start + max_segments)
        for seg in ds.segments(start, stop):
            img = event_frame(seg.events, ds.width, ds.height)
            draw_box(img, seg.box, GT_COLOUR, "gt")
            for k, (name, track) in enumerate((boxes or {}).items()):
                draw_box(img, track[seg.index], PALETTE[k % len(PALETTE)], name)
            cv2.putText(img, f"{seg.t1_us / 1000:.0f} ms", (4, ds.height - 6), cv2.FONT_HERSHEY_SIMPLEX, 0.4,
                        (0, 0, 0), 1, cv2.LINE_AA)
            frames.append(img)
    finally:
        if own:
            ds.close()
    out = Path(out_path)
    if not frames:
        raise ValueError(f"{ds.path}: no segments to preview")
    tmp = out.with_name(f".{out.stem}.tmp{out.suffix}")
    if out.suffix.lower() == ".gif":
        import imageio.v2 as imageio

        imageio.mimsave(tmp, frames, duration=1.0 / fps, loop=0)
    else:
        writer = cv2.VideoWriter(str(tmp), cv2.VideoWriter_fourcc(*"mp4v"), fps, (ds.width, ds.height))
        for f in frames:
            writer.write(cv2.cvtColor(f, cv2.COLOR_RGB2BGR))
        writer.release()
    os.replace(tmp, out)
    return out
