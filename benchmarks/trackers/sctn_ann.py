"""`sctn_ann` in the benchmark: SCTN's ANN twin (sctn/ann.py) tracked by SCTN's own Algorithm 1 (sctn/tracker.py).

The same tracker code as `sctn` runs it: fine-tuning on the first segment, 256 gaussian candidates per
segment each evaluated separately (the per-candidate path; the twin has no fast mode), top-3 scores
and the V* >= 0.2 rule on the target unit's output. Energy: dense MACs, the same for every candidate.
"""

from __future__ import annotations

from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field, Strict

from benchmarks.trackers import register
from benchmarks.trackers.sctn import SCTNBenchTracker

Int = Annotated[int, Strict()]
Float = Annotated[float, Strict()]


class TwinOptions(BaseModel):
    """`--option sctn_ann.KEY=VALUE` settings; unset ones keep SCTNTracker's defaults."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    checkpoint: str | None = None
    energy_every: Int = Field(10, ge=0, description="report operations every N segments; 0 = never")
    seed: Int | None = Field(None, ge=0)
    finetune_iters: Int | None = Field(None, ge=0)
    n_candidates: Int | None = Field(None, ge=1)
    trans: Float | None = Field(None, gt=0)
    trans_growth: Float | None = Field(None, ge=1)
    trans_max: Float | None = Field(None, gt=0)
    vstar_threshold: Float | None = None
    top_k: Int | None = Field(None, ge=1)


@register("sctn_ann")
class TwinBenchTracker(SCTNBenchTracker):
    """The ANN twin behind the benchmark interface (shipped checkpoint by default)."""

    name = "sctn_ann"

    def __init__(self, **options) -> None:
        from sctn.ann import load_twin
        from sctn.tracker import SCTNTracker

        opts = TwinOptions(**options)
        model, _ = load_twin(opts.checkpoint)
        kwargs = opts.model_dump(exclude_none=True, exclude={"checkpoint", "energy_every"})
        self.tracker = SCTNTracker(model, fast=False, **kwargs)
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
