"""The SCTN tracker's settings as typed models (pydantic, no torch: the benchmark's option checks stay light)."""

from __future__ import annotations

from typing import Literal, get_args

from pydantic import Field, model_validator

from dvsot.core.strict import Bool, Float, Int, Strict
from sctn.samples import TRACK

Crop = Literal["bilinear", "nearest"]  # the fast mode's crop of conv3's map (SCTN.forward_search)
CROPS: tuple[str, ...] = get_args(Crop)
ErrorTime = Literal["stca", "max"]  # where a sample's error sits in time: STCA's rule, or V's maximum (sctn/loss.py)
ERROR_TIMES: tuple[str, ...] = get_args(ErrorTime)
FinetuneLayers = Literal["all", "fc"]  # what fine-tuning updates (sctn/finetune.py)
ReinitFrom = Literal["tuned", "trained"]  # the network a re-initialisation fine-tunes (sctn/tracker.py)


class SearchParams(Strict):
    """Algorithm 1's settings for any model the tracker runs (SCTN or its ANN twin): seed, fine-tuning, candidates
    (translation range in mean box sizes), the V* rule and the top-k mean box. The defaults are the paper's, and
    where it is silent the validation scenes' choice."""

    seed: Int = Field(0, ge=0, description="fixes the fine-tuning and the candidates drawn at each location")
    finetune_iters: Int = Field(10, ge=0, description="fine-tuning mini-batches at each initialisation")
    # the protocol "reinitializes the tracker" after a failure; whether that repeats Algorithm 1's fine-tuning the
    # paper does not say, and the validation scenes chose it (docs/sctn.md, Ablations)
    finetune_on_reinit: Bool = Field(True, description="fine-tune again at each re-initialisation after a failure")
    # a re-initialisation tunes the network tuned so far further, or starts again from a fresh copy of the trained
    # one (VOT's new tracker per re-initialisation; the row reinit_from_trained)
    reinit_from: ReinitFrom = Field("tuned", description="re-initialisation: tune the tuned network, or the trained")
    n_candidates: Int = Field(TRACK.n, ge=1)
    trans: Float = Field(TRACK.trans, gt=0, description="initial translation range, x mean box size")
    trans_growth: Float = Field(1.5, ge=1, description="factor on the range after an unconfident segment")
    trans_max: Float = Field(1.5, gt=0, description="largest translation range")
    vstar_threshold: Float = Field(0.2, description="V* at or above it resets the range")
    top_k: Int = Field(3, ge=1, description="candidates whose mean box and voltage are C* and V*")

    @model_validator(mode="after")
    def _fresh_start_is_tuned(self) -> "SearchParams":
        """A fresh copy of the trained network at a re-initialisation needs that re-initialisation's fine-tuning."""
        if self.reinit_from == "trained" and not self.finetune_on_reinit:
            raise ValueError("reinit_from 'trained' needs finetune_on_reinit: the fresh copy would track untuned")
        return self


class SCTNParams(SearchParams):
    """SCTNTracker's settings: Algorithm 1's (SearchParams) and the fast mode, a named approximation (off)."""

    fast: Bool = False  # strict: the text "False" must not mean true
    crop: Crop = "bilinear"
    finetune_search_iters: Int = Field(10, ge=0, description="fast mode: fine-tuning mini-batches run through it")
    error_time: ErrorTime = Field("stca", description="fine-tuning: the step each sample's error sits at")
    finetune_balanced: Bool = Field(False, description="fine-tuning mini-batches of 32 positives and 96 negatives")
    finetune_layers: FinetuneLayers = Field("all", description="fine-tune every layer, or the fully connected ones")
