"""Frames -> events -> dataset file: the loop `dvsot simulate` and `dvsot generate` share.

Frames come from any iterable (a FrameSource's read-ahead decoder, or renders); the simulator runs in
the calling thread and the writer compresses and writes chunks on its own thread, so decoding,
simulation and writing overlap.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Iterable, Sequence

import numpy as np

from dvsot.dataset import DatasetWriter
from dvsot.errors import UserError
from dvsot.events import EventSimulator


@dataclass(frozen=True)
class SimulationCounts:
    """What simulate_frames did: frames consumed, events written, ON events among them."""

    frames: int
    events: int
    positive: int


def simulate_frames(frames: Iterable[np.ndarray], t_us: Sequence[int], sim: EventSimulator, writer: DatasetWriter,
                    source: str = "frames", progress: Callable[[int, int], None] | None = None,
                    is_log: bool = False) -> SimulationCounts:
    """Step sim through frames at t_us (microseconds) and append every event to writer; progress(frame, events)."""
    n_pos, n = 0, 0
    for i, frame in enumerate(frames):
        if i >= len(t_us):
            raise UserError(f"{source}: more frames than the {len(t_us)} timestamps")
        try:
            batch = sim.step(frame, int(t_us[i]), is_log=is_log, copy=False)  # frames are ours to keep
        except UserError as exc:
            raise UserError(f"{source}: frame {i}: {exc}") from None
        writer.append_events(batch)
        n_pos += int(np.count_nonzero(batch.p))
        n = i + 1
        if progress is not None:
            progress(n, writer.num_events)
    return SimulationCounts(n, writer.num_events, n_pos)
