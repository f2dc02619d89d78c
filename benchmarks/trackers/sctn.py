"""`sctn` in the benchmark: the spiking tracker of sctn/ (shipped checkpoint by default), with its energy per segment."""

from __future__ import annotations

import numpy as np

from benchmarks.trackers import register
from benchmarks.trackers.base import Tracker
from dvsot.dataset import Segment


@register("sctn")
class SCTNBenchTracker(Tracker):
    """SCTN (Algorithm 1) behind the benchmark interface; options pass to sctn.tracker.SCTNTracker."""

    name = "sctn"

    def __init__(self, checkpoint: str | None = None, seed: int = 0, fast: bool = True, energy_every: int = 10,
                 **options) -> None:
        import torch

        from sctn.tracker import SCTNTracker

        torch.set_num_threads(1)  # the benchmark runs sequences in parallel processes
        self.tracker = SCTNTracker(checkpoint, seed=seed, fast=fast, **options)
        self.energy_every = energy_every
        self._updates = 0
        self._energy: dict | None = None

    def init(self, segment: Segment, box_xywh: np.ndarray, width: int, height: int) -> None:
        """Fine-tune (first time) and start from the ground-truth box."""
        self.tracker.init(segment.events, segment.t0_us, box_xywh, width, height)

    def update(self, segment: Segment) -> np.ndarray:
        """Score 256 candidates, return the top-3 mean box; every `energy_every` segments count the spikes."""
        box = self.tracker.track(segment.events, segment.t0_us)
        self._updates += 1
        if self.energy_every and self._updates % self.energy_every == 1:
            self._energy = self._count(segment, box)
        return box

    def _count(self, segment: Segment, box: np.ndarray) -> dict:
        from sctn.encoding import encode_boxes
        from sctn.energy import E_AC_PJ, count_synaptic_ops

        cfg = self.tracker.model.cfg
        x = encode_boxes(segment.events, segment.t0_us, box[None], cfg.input_size, cfg.steps, cfg.step_us)
        ops = count_synaptic_ops(self.tracker.model, x)["ac_ops_per_sample"]
        # per segment: one network evaluation per candidate (the paper-faithful count)
        total = ops * self.tracker.n_candidates
        return {"ac_ops_per_candidate": ops, "ac_ops": total, "energy_pj": total * E_AC_PJ}

    def energy_per_segment(self) -> dict | None:
        """AC operations and pJ of the last counted segment."""
        return self._energy
