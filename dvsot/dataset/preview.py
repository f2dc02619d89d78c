"""Pictures of event data: event frames (ON red, OFF blue, on white or dark) with boxes drawn, written as GIF or MP4.

A preview frame is one segment: every pixel that fired in the segment takes the colour of its last
event's polarity. The ground-truth box (the segment's amodal box at its end time) is green; other box
tracks (tracker predictions, one box per segment) get colours of their own, listed in a legend in
the top-left corner.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Literal

import cv2
import numpy as np

from dvsot.core.bounds import preview_problem
from dvsot.core.errors import UserError
from dvsot.events import EventBatch
from dvsot.runtime.outputs import replacing

GT_COLOUR = (40, 170, 40)  # RGB
PALETTE = [(230, 120, 0), (150, 40, 200), (0, 150, 200), (200, 0, 80), (120, 90, 20), (110, 110, 110)]
ON_COLOUR = np.array([220, 30, 30], np.uint8)
OFF_COLOUR = np.array([30, 60, 220], np.uint8)
_BACKGROUNDS = {"white": 255, "dark": 20}
_TEXT = {"white": (0, 0, 0), "dark": (235, 235, 235)}
_SUFFIXES = (".gif", ".mp4")
PREVIEW_SEGMENTS = 200  # frames of a scene's preview GIF (dvsot generate's), one per segment


def check_preview_size(source: str, cfg, label: str = "preview") -> None:
    """UserError before rendering if a scene's preview would hold more frames in memory than allowed."""
    segments = int(cfg.duration_s * 1e6) // int(round(cfg.segment_ms * 1000))
    problem = preview_problem(cfg.sensor.width, cfg.sensor.height, min(PREVIEW_SEGMENTS, segments))
    if problem:
        raise UserError(f"{source}: {label}: {problem}")


def event_frame(events: EventBatch, width: int, height: int,
                background: Literal["white", "dark"] = "white") -> np.ndarray:
    """An RGB uint8 (height, width, 3) image: pixels whose last event was ON red, OFF blue, others background."""
    if background not in _BACKGROUNDS:
        raise ValueError(f"background must be one of {sorted(_BACKGROUNDS)}, got {background!r}")
    img = np.full((height * width, 3), _BACKGROUNDS[background], np.uint8)
    if len(events):
        x, y = events.x.astype(np.int64), events.y.astype(np.int64)
        if x.max() >= width or y.max() >= height:
            raise ValueError(f"events outside the {width}x{height} frame")
        # later events overwrite earlier ones at the same pixel (numpy's fancy assignment keeps the last)
        img[y * width + x] = np.where(events.p[:, None] > 0, ON_COLOUR, OFF_COLOUR)
    return img.reshape(height, width, 3)


def draw_box(img: np.ndarray, xywh: np.ndarray, colour: tuple[int, int, int], label: str | None = None) -> None:
    """Draw a box (xywh pixels, covering [x, x+w) x [y, y+h)) in place, with an optional label; nothing if NaN."""
    b = np.asarray(xywh, float)
    if not np.all(np.isfinite(b)) or b[2] <= 0 or b[3] <= 0:
        return
    # the last covered pixel is x + w - 1 (half-open box); cv2.rectangle's corners are inclusive
    x0, y0 = int(round(b[0])), int(round(b[1]))
    x1, y1 = max(int(round(b[0] + b[2])) - 1, x0), max(int(round(b[1] + b[3])) - 1, y0)
    cv2.rectangle(img, (x0, y0), (x1, y1), colour, 1)
    if label:
        cv2.putText(img, label, (x0, max(y0 - 3, 8)), cv2.FONT_HERSHEY_SIMPLEX, 0.35, colour, 1, cv2.LINE_AA)


def draw_legend(img: np.ndarray, entries: list[tuple[str, tuple[int, int, int]]]) -> None:
    """Draw coloured legend names in the top-left corner of img, in place (one line each)."""
    for k, (name, colour) in enumerate(entries):
        y = 12 + 12 * k
        cv2.rectangle(img, (4, y - 7), (10, y - 1), colour, -1)
        cv2.putText(img, name, (14, y), cv2.FONT_HERSHEY_SIMPLEX, 0.35, colour, 1, cv2.LINE_AA)


def write_preview(dataset, out_path: str | os.PathLike, boxes: dict[str, np.ndarray] | None = None,
                  start: int = 0, max_segments: int = 300, fps: float = 30.0,
                  background: Literal["white", "dark"] = "white") -> Path:
    """Write event frames of segments [start, start+max_segments) with ground truth (green) and other
    per-segment box tracks (dict name -> (n <= num_segments, 4) xywh) to a .gif or .mp4 at fps frames/s."""
    from dvsot.dataset import Dataset

    out = Path(out_path)
    if out.suffix.lower() not in _SUFFIXES:
        raise ValueError(f"{out}: preview must end in {' or '.join(_SUFFIXES)}")
    own = not isinstance(dataset, Dataset)
    ds = Dataset(dataset) if own else dataset
    try:
        tracks = {name: np.asarray(b, float).reshape(-1, 4) for name, b in (boxes or {}).items()}
        for name, b in tracks.items():
            # shorter is fine (a benchmark run limited to the first segments); longer is someone else's track
            if len(b) > ds.num_segments:
                raise ValueError(f"{ds.path}: box track '{name}' has {len(b)} rows, more than one per segment "
                                 f"({ds.num_segments})")
        legend = [("ground truth", GT_COLOUR)] + [(n, PALETTE[k % len(PALETTE)]) for k, n in enumerate(tracks)]
        frames = []
        stop = min(ds.num_segments, start + max_segments)
        problem = preview_problem(ds.width, ds.height, max(0, stop - start))  # every frame is held until written
        if problem:
            raise ValueError(f"{ds.path}: {problem}")
        for seg in ds.segments(start, stop):
            img = event_frame(seg.events, ds.width, ds.height, background)
            draw_box(img, seg.box, GT_COLOUR)
            for (_, colour), track in zip(legend[1:], tracks.values()):
                if seg.index < len(track):
                    draw_box(img, track[seg.index], colour)
            if tracks:  # a lone green box needs no legend; with predictions, say which is which
                draw_legend(img, legend)
            cv2.putText(img, f"{seg.t1_us / 1000:.0f} ms", (4, ds.height - 6), cv2.FONT_HERSHEY_SIMPLEX, 0.4,
                        _TEXT[background], 1, cv2.LINE_AA)
            frames.append(img)
        if not frames:
            raise ValueError(f"{ds.path}: no segments to preview from segment {start}")
        width, height = ds.width, ds.height
    finally:
        if own:
            ds.close()
    out.parent.mkdir(parents=True, exist_ok=True)
    # written beside the target and renamed, so a crash never leaves a half-written preview behind
    with replacing(out) as tmp:
        if out.suffix.lower() == ".gif":
            import imageio.v2 as imageio

            imageio.mimsave(tmp, frames, duration=1000.0 / fps, loop=0)  # Pillow plugin: milliseconds per frame
        else:
            writer = cv2.VideoWriter(str(tmp), cv2.VideoWriter_fourcc(*"mp4v"), fps, (width, height))
            if not writer.isOpened():
                raise ValueError(f"{out}: OpenCV cannot write MP4 (mp4v) here")
            for f in frames:
                writer.write(cv2.cvtColor(f, cv2.COLOR_RGB2BGR))
            writer.release()
    return out
