"""Frames -> events -> dataset file: the loop `dvsot simulate` and `dvsot generate` share (write_sequence).

Frames come from any iterable (a FrameSource's read-ahead decoder, or renders); the simulator runs in
the calling thread and the writer compresses and writes chunks on its own thread, so decoding,
simulation and writing overlap.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dvsot.core.defaults import SEGMENT_US
from dvsot.core.errors import UserError
from dvsot.dataset import DatasetWriter
from dvsot.events import EventSimulator
from dvsot.events.labels import EventLabeller, LabelledFrame


@dataclass(frozen=True)
class SimulationCounts:
    """What simulate_frames did: frames consumed, events written, ON events among them."""

    frames: int
    events: int
    positive: int


def simulate_frames(frames: Iterable[np.ndarray], t_us: Sequence[int], sim: EventSimulator, writer: DatasetWriter,
                    source: str = "frames", progress: Callable[[int, int], None] | None = None,
                    is_log: bool = False, masks: bool = False) -> SimulationCounts:
    """Step sim through frames at t_us (microseconds) and append every event to writer; progress(frame, events).

    Frames given as LabelledFrame (all of them or none) label each event with its object (dvsot.events.labels);
    masks: each LabelledFrame's object index image is also kept, as the file's /masks/objects row of its sample.
    """
    from dvsot.runtime import interrupts

    n_pos, n = 0, 0
    labeller: EventLabeller | None = None
    for i, frame in enumerate(frames):
        interrupts.check()  # a signal whose exception a callback swallowed stops the run here
        if i >= len(t_us):
            raise UserError(f"{source}: more frames than the {len(t_us)} timestamps")
        labelled = isinstance(frame, LabelledFrame)
        if i == 0 and labelled:
            labeller = EventLabeller(sim.width, sim.height)
        elif labelled != (labeller is not None):
            raise UserError(f"{source}: frame {i}: either every frame comes with object labels or none does")
        if masks and not labelled:
            raise UserError(f"{source}: frame {i}: masks are the frames' object labels, and it has none")
        try:
            if labelled:
                batch = labeller.label(sim.step(frame.frame, int(t_us[i]), is_log=is_log, copy=False),
                                       frame.objects, int(t_us[i]))
            else:
                batch = sim.step(frame, int(t_us[i]), is_log=is_log, copy=False)  # frames are ours to keep
        except UserError as exc:
            raise UserError(f"{source}: frame {i}: {exc}") from None
        writer.append_events(batch)
        if masks:
            writer.append_mask(frame.objects)
        n_pos += int(np.count_nonzero(batch.p))
        n = i + 1
        if progress is not None:
            progress(n, writer.num_events)
    return SimulationCounts(n, writer.num_events, n_pos)


# (t_us (N,), xywh (N, 4)[, xywh_visible (N, 4)[, visibility (N,)]]) or a dict of DatasetWriter.append_boxes' keyword
# arguments, which may add "objects": every object's rows stacked (DatasetWriter.append_object_rows)
BoxRows = tuple | dict


def write_sequence(path: str | Path, frames: Iterable[np.ndarray], t_us: Sequence[int], sim: EventSimulator,
                   attrs: dict, segment_us: int = SEGMENT_US, *, source: str = "frames", is_log: bool = False,
                   boxes: Callable[[], BoxRows | None] | None = None, progress: bool = False,
                   desc: str | None = None, bar_after_error: bool = True,
                   objects: list[dict] | None = None, masks: bool = False,
                   final_attrs: Callable[[], dict] | None = None) -> tuple[Path, SimulationCounts]:
    """Frames at t_us (microseconds) -> events -> a new dataset file at path (with boxes); its path and counts.

    The frames -> events -> file loop of `dvsot generate` and `dvsot simulate`. boxes() is called once
    every frame is consumed, so a renderer may collect its boxes while it yields frames. The file is
    renamed into place only when complete (DatasetWriter); on any error nothing is left behind, and the
    progress bar stays on screen unless bar_after_error is False (then the error line stands alone).
    objects: the object table (dvsot.events.labels.object_table) when the frames are LabelledFrames; masks: keep
    their object index images too (/masks/objects).
    final_attrs(): root attributes known once every frame is consumed (the kept frames' digest).
    """
    with DatasetWriter(path, sim.width, sim.height, segment_us, attrs, objects=objects) as writer:
        bar = shown = None
        if progress:  # tqdm's import is a tenth of `dvsot simulate`'s start-up: only for the bar
            from tqdm import tqdm

            bar = tqdm(total=len(t_us), unit="frame", desc=desc or source)

            def shown(done: int, events: int) -> None:
                bar.update(1)
                bar.set_postfix_str(f"t={t_us[done - 1] / 1e6:.3f}s events={events:,}", refresh=False)

        try:
            counts = simulate_frames(frames, t_us, sim, writer, source, shown, is_log=is_log, masks=masks)
        except BaseException:
            if bar is not None:
                bar.leave = bar_after_error
            raise
        finally:
            if bar is not None:
                bar.close()
        if counts.frames != len(t_us):
            raise UserError(f"{source}: expected {len(t_us)} frames, read {counts.frames}")
        rows = boxes() if boxes is not None else None
        if isinstance(rows, dict):
            rows = dict(rows)
            object_rows = rows.pop("objects", None)
            writer.append_boxes(**rows)
            if object_rows is not None:
                writer.append_object_rows(object_rows)
        elif rows is not None:
            writer.append_boxes(*rows)
        if final_attrs is not None:
            writer.set_attrs(**final_attrs())
        sensor = sim.sensor_counts()
        if sensor is not None:  # what the readout dropped and what was still delayed past the last frame
            writer.set_attrs(sensor_counts=sensor)
        out = writer.close(int(t_us[-1]) + 1)
    return out, counts
