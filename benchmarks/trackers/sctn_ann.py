"""`sctn_ann` in the benchmark: SCTN's ANN twin (sctn/ann.py) tracked by SCTN's own Algorithm 1 (sctn/tracker.py).

The same tracker code as `sctn` runs it: fine-tuning on the first segment, 256 gaussian candidates per
segment each evaluated separately (the per-candidate path; the twin has no fast mode), top-3 scores
and the V* >= 0.2 rule on the target unit's output. Energy: dense MACs and activations, the same for
every candidate; an initialisation's are fine-tuning's forward and backward (sctn.energy_run).
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
    operations = ("mac_ops", "activations")

    def __init__(self, **options) -> None:
        from sctn.ann import load_twin
        from sctn.tracker import SCTNTracker

        opts = TwinOptions(**options)
        model, _ = load_twin(opts.checkpoint)
        self.tracker = SCTNTracker(model, fast=False, **opts.model_dump(exclude=BENCH_FIELDS, exclude_unset=True))
        self._start(opts.energy_every)
        self._per_candidate: float | None = None

    def _per_sample(self) -> tuple[float, float]:
        """(MACs, activations) of one twin evaluation, counted once on the layers."""
        if self._per_candidate is None:
            import torch

            from sctn.ann import twin_macs
            from sctn.energy import count_activations

            model, cfg = self.tracker.model, self.tracker.model.cfg
            acts = count_activations(model, torch.zeros(1, cfg.steps, 2, cfg.input_size, cfg.input_size))
            self._per_candidate = (twin_macs(model)["mac_ops"], acts)
        return self._per_candidate

    def _count(self, segment, box) -> dict:
        """Dense MACs and activations of the segment: one twin evaluation per candidate."""
        from sctn.energy import E_MAC_PJ

        macs, acts = self._per_sample()
        n = len(self.tracker.last_search[0])
        return {"mac_ops_per_candidate": macs, "ac_ops": 0.0, "mac_ops": macs * n, "energy_pj": macs * n * E_MAC_PJ,
                "state_updates": 0.0, "activations": acts * n, "evaluations": n}

    def _init_counts(self) -> dict:
        """Fine-tuning's dense forward and backward MACs and activations (sctn.energy_run.finetune_operations)."""
        from sctn.energy_run import finetune_operations

        macs, acts = self._per_sample()
        return finetune_operations(self.tracker.last_stats, False, macs, acts)
