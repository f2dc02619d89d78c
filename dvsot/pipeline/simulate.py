"""Frames you already have (image directory, video, .npy stack) -> events -> a dataset file: `dvsot simulate`'s library.

`simulate_file` does the whole run; `frame_times` and `read_box_csv` (dvsot.interop.text_inputs) are its checked
inputs. Messages name a setting by its parameter name unless `labels` says otherwise ({"fps": "--fps",
...}: how the command line calls them).
"""

from __future__ import annotations

import os
import time
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from dvsot.core.defaults import SEGMENT_US
from dvsot.core.errors import UserError, label
from dvsot.events import EventParams
from dvsot.interop.text_inputs import read_box_csv, read_timestamps

MAX_FPS = 1e6  # timestamps are whole microseconds: a faster rate would give frames the same time


def frame_times(count: int, fps: float | None = None, timestamps: str | os.PathLike | None = None,
                source_fps: float | None = None, source: str = "frames",
                labels: Mapping[str, str] | None = None) -> np.ndarray:
    """Times in microseconds of `count` frames: from a timestamps file (seconds), else fps, else the source's rate."""
    from dvsot.core.bounds import MAX_DURATION_S

    if timestamps is not None:
        t_us = read_timestamps(timestamps, count)
        span, what = (int(t_us[-1]) - int(t_us[0])) / 1e6 if len(t_us) else 0.0, f"{timestamps}: timestamps"
    else:
        rate = fps if fps is not None else source_fps
        if not rate or not 0 < rate <= MAX_FPS:  # a video's own rate: None, or whatever its header says
            raise UserError(f"{source}: give {label('fps', labels)} N (positive) or "
                            f"{label('timestamps', labels)} FILE")
        span = (count - 1) / rate  # before any array is made: a tiny rate would overflow microseconds
        what = f"{label('fps', labels)} {fps:g}: {count} frames" if fps is not None else f"{source}: its frames"
    if span >= MAX_DURATION_S:  # ms_to_idx holds an entry per millisecond of the span
        raise UserError(f"{what} span {span:g} s, more than the bound of {MAX_DURATION_S} s per dataset file")
    if timestamps is None:
        t_us = np.rint(np.arange(count) * 1e6 / rate).astype(np.int64)
    return t_us


def event_params(settings: EventParams | Mapping[str, object] | None,
                 labels: Mapping[str, str] | None = None) -> EventParams:
    """The simulator's parameters: given, or EventParams' fields (None = the preset's value) over the preset's;
    a bad value raises UserError naming its field (or its label)."""
    from pydantic import ValidationError

    from dvsot.events.simulator import param_problem

    if settings is None or isinstance(settings, EventParams):
        return settings if settings is not None else EventParams()
    try:
        return EventParams(**{k: v for k, v in settings.items() if v is not None})
    except ValidationError as exc:
        raise UserError(param_problem(exc, dict(labels or {}))) from None


def check_settings(seed: int, segment_us: int, fps: float | None, labels: Mapping[str, str] | None = None) -> None:
    """UserError naming the setting if the seed, the segment length (us) or the frame rate (Hz) is out of range."""
    import math

    from dvsot.core.bounds import MAX_SEGMENT_US, MIN_SEGMENT_US, range_problem

    if not 0 <= seed < 2**63:  # numpy's seeds are non-negative; the file stores the seed as int64
        raise UserError(f"{label('seed', labels)} must be >= 0 (and below 2**63), got {seed}")
    if segment_us < MIN_SEGMENT_US:
        raise UserError(f"{label('segment_us', labels)} must be at least {MIN_SEGMENT_US} (1 ms), got {segment_us}")
    problem = range_problem(label("segment_us", labels), segment_us, MIN_SEGMENT_US, MAX_SEGMENT_US, "us")
    if problem:
        raise UserError(problem)
    if fps is not None and not (math.isfinite(fps) and 0 < fps <= MAX_FPS):
        raise UserError(f"{label('fps', labels)} must be positive and finite (at most {MAX_FPS:g}), got {fps}")


def simulate_file(frames: str | os.PathLike, output: str | os.PathLike,
                  params: EventParams | Mapping[str, object] | None = None, seed: int = 0, *,
                  fps: float | None = None, timestamps: str | os.PathLike | None = None,
                  boxes: str | os.PathLike | None = None, srgb: bool = False, segment_us: int = SEGMENT_US,
                  progress: bool = False, labels: Mapping[str, str] | None = None) -> dict:
    """Stream frames (directory, video or .npy) through the event simulator into a dataset file; a summary.

    `params`: EventParams, or its fields (None = the preset's value) over `preset`'s. Frame times: `timestamps`
    (a file of seconds, one per line), else `fps`, else a video's own rate; they are rebased to the first frame.
    `boxes`: optional CSV t_s,x,y,w,h on the same clock. Bad input raises UserError before the file is begun;
    the file appears only when complete.
    """
    from dvsot import __version__
    from dvsot.core.bounds import MAX_SENSOR_PIXELS
    from dvsot.events import EventSimulator
    from dvsot.events.frame_sources import open_frames
    from dvsot.pipeline.sequence import write_sequence
    from dvsot.runtime.outputs import output_file

    params = event_params(params, labels)
    check_settings(seed, segment_us, fps, labels)
    inputs = [Path(p) for p in (frames, timestamps, boxes) if p]
    if inputs[0].is_dir():  # a frames directory: none of its files may be overwritten either
        inputs += sorted(inputs[0].iterdir())
    output_file(output, label("output", labels), inputs)
    source = open_frames(frames, srgb=srgb)
    if source.width * source.height > MAX_SENSOR_PIXELS:
        raise UserError(f"{frames}: frames of {source.width}x{source.height} px, more than the bound of "
                        f"{MAX_SENSOR_PIXELS} pixels")
    t_us = frame_times(source.count, fps, timestamps, source.fps, str(frames), labels)
    if source.count < 2:
        raise UserError(f"{frames}: need at least two frames, found {source.count}")
    t0 = int(t_us[0])
    t_us = t_us - t0
    box_rows = read_box_csv(boxes, t0, source.width, source.height) if boxes else None
    if box_rows is not None and not (0 <= box_rows[0][0] and box_rows[0][-1] <= t_us[-1]):
        raise UserError(f"{boxes} ({label('boxes', labels)}): box times run from {box_rows[0][0] / 1e6:g} s to "
                        f"{box_rows[0][-1] / 1e6:g} s after the first frame, outside the frames' "
                        f"0..{t_us[-1] / 1e6:g} s")
    if int(t_us[-1]) + 1 < segment_us:
        raise UserError(f"{frames}: the frames span {int(t_us[-1]) + 1} us, less than one segment of {segment_us} us "
                        f"({label('segment_us', labels)}): the file would hold no segment to track")

    from dvsot.events.memory import check_memory

    check_memory(params, source.width, source.height, float(np.diff(t_us).max()), str(frames))
    sim = EventSimulator(source.width, source.height, params, seed)
    attrs = {"name": Path(output).name.removesuffix(".h5"), "split": "", "source": str(frames),
             "simulator": params.model_dump(), "seed": seed, "generator": "dvsot simulate",
             "versions": {"dvsot": __version__, "numpy": np.__version__}}
    start = time.perf_counter()
    # log intensities (or 8/16-bit images and their log table) from the decoding threads, taken as they are
    path, counts = write_sequence(output, source.log_frames(params.log_eps, coded=True), t_us, sim, attrs, segment_us,
                                  source=str(frames), is_log=True, boxes=lambda: box_rows, progress=progress,
                                  desc="simulate")
    wall = time.perf_counter() - start
    duration = (int(t_us[-1]) + 1) / 1e6
    n_events = counts.events
    summary = {"output": str(path), "frames": source.count, "resolution": f"{source.width}x{source.height}",
               "duration_s": round(duration, 6), "events": n_events,
               "event_rate_per_s": round(n_events / duration, 1),
               "positive_fraction": round(counts.positive / n_events, 4) if n_events else None,
               "wall_s": round(wall, 3)}
    sensor = sim.sensor_counts()
    return summary if sensor is None else {**summary, "preset": params.preset, **sensor}
