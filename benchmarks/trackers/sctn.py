"""`sctn` in the benchmark: the spiking tracker of sctn/ (shipped checkpoint by default), with its operations per
tracked segment and per initialisation (sctn.energy_run)."""

from __future__ import annotations

import numpy as np
from pydantic import Field

from benchmarks.trackers import register
from benchmarks.trackers.base import Tracker
from dvsot.core.strict import Int, Strict
from dvsot.dataset import Segment
from sctn.params import SCTNParams

BENCH_FIELDS = {"checkpoint", "energy_every"}  # the benchmark's own options; the others are the tracker's


class BenchOptions(Strict):
    """The options every SCTN-like benchmark tracker adds to its tracker's settings."""

    checkpoint: str | None = None
    energy_every: Int = Field(10, ge=0, description="count operations every N segments; 0 = never")


class SCTNOptions(SCTNParams, BenchOptions):
    """`--option sctn.KEY=VALUE` settings: SCTNTracker's (sctn.params.SCTNParams, typed and range-checked, the
    paper's defaults) and the benchmark's own."""


@register("sctn")
class SCTNBenchTracker(Tracker):
    """SCTN (Algorithm 1) behind the benchmark interface; options (SCTNOptions) pass to sctn.tracker.SCTNTracker."""

    name = "sctn"
    operations = ("ac_ops", "mac_ops", "state_updates")
    count_every_call = {"energy_every": 1}

    def __init__(self, **options) -> None:
        from sctn.tracker import SCTNTracker

        opts = SCTNOptions(**options)
        self.tracker = SCTNTracker(
            opts.checkpoint, SCTNParams(**opts.model_dump(exclude=BENCH_FIELDS, exclude_unset=True))
        )
        self._start(opts.energy_every)

    @classmethod
    def wrap(cls, tracker, energy_every: int = 0) -> SCTNBenchTracker:
        """The benchmark interface around an SCTNTracker already built (e.g. on a model just trained)."""
        self = cls.__new__(cls)
        self.tracker = tracker
        self._start(energy_every)
        return self

    def _start(self, energy_every: int) -> None:
        self.energy_every = energy_every
        self._updates = 0
        self._energy: dict | None = None
        self._due: tuple[Segment, np.ndarray] | None = None

    def init(self, segment: Segment, box_xywh: np.ndarray, width: int, height: int) -> None:
        """Start from the ground-truth box: a fresh fine-tuned copy of the trained network (SCTNParams.reinit)."""
        self.tracker.init(segment.events, self._t0(segment), box_xywh, width, height)

    def update(self, segment: Segment) -> np.ndarray:
        """Score 256 candidates, return the top-3 mean box; every `energy_every` segments mark it for counting."""
        box = self.tracker.track(segment.events, self._t0(segment))
        self._updates += 1
        if self.energy_every and (self._updates - 1) % self.energy_every == 0:  # updates 1, 1 + N, 1 + 2N, ...
            self._due = (segment, box)  # counted in energy_per_segment, outside the protocol's timed update
        return box

    def _t0(self, segment: Segment) -> int:
        """Where the network's time steps start: the segment's start, or for a longer window (a streaming call's
        events since its last one) its latest steps x step_us, so that the newest events are the ones encoded."""
        cfg = self.tracker.model.cfg
        return max(int(segment.t0_us), int(segment.t1_us) - cfg.steps * cfg.step_us)

    def _count(self, segment: Segment, box: np.ndarray) -> dict:
        """Operations of the segment just tracked: the search actually run (fast), or every candidate's own evaluation
        (spikes x fan-out, counted from each of the N candidates' spikes; bias additions apart)."""
        from sctn.encoding import encode_search
        from sctn.energy import bias_additions, count_search_ops, snn_state_updates, tracker_energy
        from sctn.sparse.evaluate import candidate_ops

        model, cfg = self.tracker.model, self.tracker.model.cfg
        candidates, ref_box = self.tracker.last_search
        if self.tracker.fast:
            inputs = encode_search(segment.events, self._t0(segment), candidates, ref_box, cfg)
            ops = count_search_ops(model, *inputs, crop=self.tracker.crop)
            n = len(candidates)  # per evaluation: a segment's share per candidate, as the energy table states it
            row = tracker_energy(n, ac_ops=ops["ac_ops"] / n, mac_ops=ops["mac_ops"] / n,
                                 state_updates=ops["state_updates"] / n)["per_segment"]
            return {"ac_ops": row["ac_ops"], "mac_ops": row["mac_ops"], "energy_pj": row["energy_pj"],
                    "state_updates": row["state_updates"], "activations": 0.0, "evaluations": n}
        n = len(candidates)
        ops = candidate_ops(model, segment.events, self._t0(segment), candidates)
        bias = bias_additions(model) * n  # 0 in the paper preset (no biases)
        row = tracker_energy(n, ac_ops=(ops + bias) / n, state_updates=snn_state_updates(cfg))  # the table's function
        return {"ac_ops_per_candidate": ops / n, "ac_ops": ops, "bias_ac_ops": bias, "mac_ops": 0.0,
                "energy_pj": row["per_segment"]["energy_pj"], "state_updates": row["per_segment"]["state_updates"],
                "activations": 0.0, "evaluations": n}

    def _init_counts(self) -> dict:
        """Operations of the initialisation just run: fine-tuning's forward as its spikes ran and its backward
        (sctn.energy_run.finetune_operations); nothing when it did not fine-tune."""
        from sctn.energy_run import dense_macs, finetune_operations

        return finetune_operations(self.tracker.last_stats, True, dense_macs(self.tracker.model.cfg))

    def energy_per_init(self) -> dict | None:
        """Operations and pJ of the last initialisation (fine-tuning's forward and backward), when counting."""
        if not getattr(self, "energy_every", 0):
            return None
        from sctn.energy_run import split

        counts = self._init_counts()
        return {**counts, "energy_pj": split(counts)["synaptic"]["energy_pj"]}

    def energy_per_segment(self) -> dict | None:
        """AC operations and pJ of the last counted segment (counted now if the last update was due)."""
        due, self._due = getattr(self, "_due", None), None
        if due is not None:
            self._energy = self._count(*due)
        return self._energy
