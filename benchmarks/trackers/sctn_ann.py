"""`sctn_ann` in the benchmark: SCTN's ANN twin (sctn/ann.py) tracked by SCTN's own Algorithm 1 (sctn/tracker.py).

The same tracker code as `sctn` runs it: fine-tuning on the first segment, 256 gaussian candidates per
segment each evaluated separately (the per-candidate path; the twin has no fast mode), top-3 scores
and the V* >= 0.2 rule on the target unit's output. Energy: dense MACs, the same for every candidate.
"""

from __future__ import annotations

from benchmarks.trackers import register
from benchmarks.trackers.sctn import BENCH_FIELDS, BenchOptions, SCTNBenchTracker
from sctn.params import SearchParams


class TwinOptions(SearchParams, BenchOptions):
    """`--option sctn_ann.KEY=VALUE` settings: Algorithm 1's (sctn.params.SearchParams; the twin has no fast mode)
    and the benchmark's own."""


@register("sctn_ann")
class TwinBenchTracker(SCTNBenchTracker):
    """The ANN twin behind the benchmark interface (shipped checkpoint by default)."""

    name = "sctn_ann"

    def __init__(self, **options) -> None:
        from sctn.ann import load_twin
        from sctn.tracker import SCTNTracker

        opts = TwinOptions(**options)
        model, _ = load_twin(opts.checkpoint)
        self.tracker = SCTNTracker(model, fast=False, **opts.model_dump(exclude=BENCH_FIELDS))
        self._start(opts.energy_every)
        self._per_candidate: float | None = None

    def _count(self, segment, box) -> dict:
        """Dense MACs of the segment: one twin evaluation per candidate (counted once on the layers)."""
        from sctn.ann import twin_macs
        from sctn.energy import E_MAC_PJ

        if self._per_candidate is None:
            self._per_candidate = twin_macs(self.tracker.model)["mac_ops"]
        total = self._per_candidate * len(self.tracker.last_search[0])
        return {"mac_ops_per_candidate": self._per_candidate, "ac_ops": 0.0, "mac_ops": total,
                "energy_pj": total * E_MAC_PJ}
