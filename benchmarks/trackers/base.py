"""The one interface every tracker implements: initialise on a segment with a box, predict a box per segment."""

from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np

from dvsot.dataset import Segment


class Tracker(ABC):
    """A single-object tracker on 10 ms event segments; boxes are xywh float pixels."""

    name: str = "tracker"
    operations: tuple[str, ...] = ()  # the operations energy_per_segment counts (a declared latency times them)
    count_every_call: dict = {}  # the options that make it count every call (a declared latency needs each call's)

    @abstractmethod
    def init(self, segment: Segment, box_xywh: np.ndarray, width: int, height: int) -> None:
        """Start (or restart) tracking: the target's box at the end of `segment`, in a width x height sensor."""

    @abstractmethod
    def update(self, segment: Segment) -> np.ndarray:
        """The predicted box (4,) xywh pixels at the end of the next segment."""

    def energy_per_segment(self) -> dict | None:
        """Operations of the last update, for trackers that can count them: ac_ops, mac_ops, energy_pj (synaptic),
        state_updates (C-LIF), activations (an ANN's), evaluations (per segment); sctn.energy_run reads them."""
        return None

    def energy_per_init(self) -> dict | None:
        """Operations of the last init, fine-tuning's forward and backward included (the keys of energy_per_segment,
        less evaluations), for trackers that can count them."""
        return None
