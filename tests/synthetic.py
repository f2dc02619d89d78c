"""Synthetic test inputs: scene files (the smallest valid one, a tiny one for real renders) and labelled sequences
made in numpy (no Blender): a textured square moving over a textured wall."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from dvsot.dataset import DatasetWriter
from dvsot.events import EventParams, EventSimulator

# the smallest valid scene file: a cube in front of the camera, nothing else set
MINIMAL_SCENE = """name: t
duration_s: 0.1
camera:
  keyframes: [{t: 0, location: [0, -10, 0], look_at: [0, 0, 0]}]
target:
  shape: cube
  trajectory:
    keyframes: [{t: 0, location: [0, 0, 0]}]
"""


TINY_DURATION_S = 0.2  # the tiny scene's length, seconds


def linear_path(start: tuple[float, float, float], end: tuple[float, float, float]) -> dict[str, Any]:
    """A scene file trajectory from start to end (metres, world x y z), linear over the tiny scene's duration."""
    return {"interpolation": "linear",
            "keyframes": [{"t": 0, "location": list(start)}, {"t": TINY_DURATION_S, "location": list(end)}]}


def tiny_scene(name: str, target: dict[str, Any], objects: list[dict[str, Any]] | None = None, threads: int = 2,
               sampling: dict[str, Any] | None = None) -> str:
    """A tiny scene file for real renders: 160x120 px over TINY_DURATION_S, the camera 10 m in front of a dark
    self-lit wall, no lights, a grey world, sampled at 50 Hz at least; target and each of objects are that object's
    scene file fields and sampling further sampling fields, written as YAML flow mappings."""
    sampling = {"min_rate_hz": 50, **(sampling or {})}
    lines = [f"name: {name}",
             f"duration_s: {TINY_DURATION_S}",
             "sensor: {width: 160, height: 120, focal_mm: 35}",
             "camera:",
             "  keyframes: [{t: 0, location: [0, -10, 0], look_at: [0, 0, 0]}]",
             f"target: {json.dumps(target)}"]
    if objects:
        lines.append(f"objects: {json.dumps(objects)}")
    lines += ["background:",
              "  material: {color: [0.1, 0.1, 0.1], emission: 0.3}",
              "lights: []",
              "world: {color: [0.5, 0.5, 0.5], strength: 1.0}",
              f"render: {{threads: {threads}}}",
              f"sampling: {json.dumps(sampling)}"]
    return "\n".join(lines) + "\n"


def moving_square_file(path: Path, width: int = 160, height: int = 120, size: int = 30, duration_ms: int = 200,
                       velocity_px_s: tuple[float, float] = (150.0, 60.0), start: tuple[float, float] = (30.0, 30.0),
                       split: str = "train", seed: int = 0, rate_hz: int = 1000) -> Path:
    """Write a dataset file of a bright textured square moving at constant velocity; exact boxes."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:height, 0:width].astype(np.float32)
    wall = 0.15 + 0.05 * np.sin(0.5 * xx + rng.uniform(0, 6)) * np.cos(0.4 * yy)
    tex = 0.6 + 0.3 * np.sign(np.sin(0.9 * np.arange(size)[:, None]) * np.cos(0.7 * np.arange(size)[None, :]))
    sim = EventSimulator(width, height, EventParams(cp=0.2, cn=0.2, sigma_cp=0.02, sigma_cn=0.02), seed)
    n = duration_ms * rate_hz // 1000 + 1
    with DatasetWriter(path, width, height, 10_000, {"name": path.stem, "split": split}) as w:
        for i in range(n):
            t = i / rate_hz
            x = start[0] + velocity_px_s[0] * t
            y = start[1] + velocity_px_s[1] * t
            frame = wall.copy()
            # sub-pixel placement by area-weighted blend of the texture (keeps motion smooth)
            xi, yi = int(np.floor(x)), int(np.floor(y))
            fx, fy = x - xi, y - yi
            patch = np.zeros((size + 1, size + 1), np.float32)
            for dy, wy in ((0, 1 - fy), (1, fy)):
                for dx, wx in ((0, 1 - fx), (1, fx)):
                    patch[dy:dy + size, dx:dx + size] += wy * wx * tex
            ys, xs = slice(max(yi, 0), min(yi + size + 1, height)), slice(max(xi, 0), min(xi + size + 1, width))
            sub = patch[ys.start - yi:ys.stop - yi, xs.start - xi:xs.stop - xi]
            frame[ys, xs] = np.where(sub > 0, sub + (1 - np.clip(sub / 0.3, 0, 1)) * frame[ys, xs], frame[ys, xs])
            w.append_events(sim.step(frame, int(round(t * 1e6))))
            w.append_boxes(int(round(t * 1e6)), [x, y, size, size])
        w.close(int(round((n - 1) / rate_hz * 1e6)) + 1)
    return path


def small_square_file(directory: Path, name: str = "syn.h5") -> Path:
    """A small labelled dataset file in directory (64x48, 60 ms, a 12 px square from (10, 10) at (100, 40) px/s):
    enough for a training run of a step or two."""
    return moving_square_file(directory / name, width=64, height=48, size=12, duration_ms=60,
                              velocity_px_s=(100.0, 40.0), start=(10.0, 10.0))


def kept_sequence(directory: Path, width: int = 96, height: int = 72, n: int = 41, name: str = "seq",
                  frames_dir: Path | None = None, start: tuple[float, float] = (10, 20),
                  split: str = "test", params: EventParams | None = None,
                  record_settings: bool = True) -> tuple[Path, Path]:
    """A bright square crossing a textured wall at 1 kHz, as `dvsot generate --keep-frames` leaves it: its luma frames
    (NNNNNN.npy) in frames_dir (default directory/frames) and its dataset file directory/<name>.h5 (event seed 3)."""
    from dvsot.pipeline.sequence import write_sequence

    frames_dir = Path(frames_dir) if frames_dir is not None else Path(directory) / "frames"
    frames_dir.mkdir(parents=True)
    yy, xx = np.mgrid[0:height, 0:width].astype(np.float32)
    wall = 0.2 + 0.05 * np.sin(0.5 * xx) * np.cos(0.4 * yy)
    t_us = np.arange(n) * 1000
    boxes, frames = [], []
    for i in range(n):
        xi, yi = int(start[0] + 0.6 * i), int(start[1] + 0.2 * i)
        f = wall.copy()
        f[yi:yi + 16, xi:xi + 16] = 0.8 + 0.1 * np.sin(xx[yi:yi + 16, xi:xi + 16])
        np.save(frames_dir / f"{i:06d}.npy", f)
        frames.append(f)
        boxes.append([xi, yi, 16, 16])
    box = np.array(boxes, np.float32)
    params = params if params is not None else EventParams()
    sim = EventSimulator(width, height, params, 3)
    attrs = {"name": name, "split": split, "event_seed": 3}
    if record_settings:
        attrs["simulator"] = params.model_dump()
    from dvsot.pipeline.kept_frames import DIGEST_ATTR, FrameDigest

    digest = FrameDigest()
    for f in frames:
        digest.update(f)
    path, _ = write_sequence(Path(directory) / f"{name}.h5", frames, t_us, sim, attrs, 10_000,
                             boxes=lambda: (t_us, box, box), final_attrs=lambda: {DIGEST_ATTR: digest.hexdigest()})
    return path, frames_dir
