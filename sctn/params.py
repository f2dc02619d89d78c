"""The SCTN tracker's settings as typed models (pydantic, no torch: the benchmark's option checks stay light)."""

from __future__ import annotations

from typing import Any, Literal, get_args

from pydantic import Field, model_validator
from pydantic_core import PydanticCustomError

from dvsot.core.strict import Bool, Float, Int, Strict
from sctn.samples import TRACK

Crop = Literal["bilinear", "nearest"]  # the fast mode's crop of conv3's map (SCTN.forward_search)
CROPS: tuple[str, ...] = get_args(Crop)
# where a sample's error sits in time (sctn/loss.py): STCA's rule as its paper states it, its authors' code's edge
# cases, or V's maximum
ErrorTime = Literal["stca", "stca_code", "max"]
ERROR_TIMES: tuple[str, ...] = get_args(ErrorTime)
FinetuneLayers = Literal["all", "fc"]  # what fine-tuning updates (sctn/finetune.py)
# what a re-initialisation after a failure starts from (sctn/tracker.py): a new tracker (the trained network tuned
# afresh), online learning on the test sequence (the tuned network tuned further), or Algorithm 1's single tuning kept
Reinit = Literal["new", "online", "once"]
REINITS: tuple[str, ...] = get_args(Reinit)
# the settings `reinit` replaced, and what each old value is now
RETIRED = {"finetune_on_reinit": "finetune_on_reinit=false is reinit=once, true reinit=online",
           "reinit_from": "reinit_from=trained is reinit=new (the generator now restarts too), tuned reinit=online"}


class SearchParams(Strict):
    """Algorithm 1's settings for any model the tracker runs (SCTN or its ANN twin): seed, fine-tuning, what a
    re-initialisation starts from, candidates (translation range in mean box sizes), the V* rule and the top-k mean
    box. The defaults are the paper's, and where it is silent the validation scenes' choice."""

    seed: Int = Field(0, ge=0, description="fixes the fine-tuning and the candidates drawn at each location")
    finetune_iters: Int = Field(10, ge=0, description="fine-tuning mini-batches at each initialisation")
    # the protocol "reinitializes the tracker" after a failure: a new tracker, as VOT and GOT-10k read it
    reinit: Reinit = Field("new", description="a re-initialisation: a new tracker (Algorithm 1 again from the trained "
                           "network), online learning on the test sequence, or the single tuning kept")
    n_candidates: Int = Field(TRACK.n, ge=1)
    trans: Float = Field(TRACK.trans, gt=0, description="initial translation range, x mean box size")
    trans_growth: Float = Field(1.5, ge=1, description="factor on the range after an unconfident segment")
    trans_max: Float = Field(1.5, gt=0, description="largest translation range")
    vstar_threshold: Float = Field(0.2, description="V* at or above it resets the range")
    top_k: Int = Field(3, ge=1, description="candidates whose mean box and voltage are C* and V*")

    @model_validator(mode="before")
    @classmethod
    def _retired_settings(cls, data: Any) -> Any:
        """Refuse the settings `reinit` replaced, in one line naming the replacement."""
        if isinstance(data, dict):
            for old, now in RETIRED.items():
                if old in data:
                    raise ValueError(f"{old} was replaced by reinit (new, online, once): {now}")
        return data

    @model_validator(mode="after")
    def _honoured(self) -> SearchParams:
        """Refuse, in one line naming the settings, a combination the tracker cannot honour."""
        problem = self.combination_problem()
        if problem:
            raise PydanticCustomError("combination", problem)
        return self

    def combination_problem(self) -> str | None:
        """Why these settings together cannot be run as they say, or None."""
        if self.top_k > self.n_candidates:
            return f"top_k {self.top_k} needs at least as many candidates (n_candidates is {self.n_candidates})"
        if self.trans > self.trans_max:
            return f"trans {self.trans:g} starts above trans_max {self.trans_max:g}, the range's largest"
        if self.reinit != "new" and self.finetune_iters == 0:
            return (f"reinit {self.reinit!r} keeps a tuning, but finetune_iters is 0: nothing is tuned (every "
                    "re-initialisation is then a new tracker; leave reinit out)")
        return None


# the fast mode's own settings: given without fast=true, the tracker would ignore them
FAST_ONLY = ("crop", "finetune_search_iters")
# fine-tuning's own settings: given where nothing is fine-tuned, the tracker would ignore them
FINETUNE_ONLY = ("error_time", "finetune_balanced", "finetune_layers")


class SCTNParams(SearchParams):
    """SCTNTracker's settings: Algorithm 1's (SearchParams) and the fast mode, a named approximation (off)."""

    fast: Bool = False  # strict: the text "False" must not mean true
    crop: Crop = "bilinear"
    finetune_search_iters: Int = Field(10, ge=0, description="fast mode: fine-tuning mini-batches run through it")
    error_time: ErrorTime = Field("stca", description="fine-tuning: the step each sample's error sits at")
    finetune_balanced: Bool = Field(False, description="fine-tuning mini-batches of 32 positives and 96 negatives")
    finetune_layers: FinetuneLayers = Field("all", description="fine-tune every layer, or the fully connected ones")

    def combination_problem(self) -> str | None:
        """Algorithm 1's combinations (SearchParams'), then the fast mode's and fine-tuning's settings given where the
        tracker would ignore them (a search-tuning count of 0 without the fast mode is no request, so it passes)."""
        problem = super().combination_problem()
        if problem:
            return problem
        given = self.model_fields_set
        if not self.fast:
            for name in FAST_ONLY:
                if name in given and not (name == "finetune_search_iters" and self.finetune_search_iters == 0):
                    return f"{name} is the fast mode's setting: it needs fast=true"
        tunes = self.finetune_iters > 0 or (self.fast and self.finetune_search_iters > 0)
        if not tunes:
            for name in FINETUNE_ONLY:
                if name in given:
                    return f"{name} is fine-tuning's setting, but nothing is fine-tuned (finetune_iters is 0)"
        return None
