"""`automatch`: AutoMatch tracking (Zhang et al. 2021) on the ATSLTD frame of each segment: Ocean's anchor-free
tracking (benchmarks/trackers/ocean/tracker.py AnchorFreeTracker: one search crop, scores mixed from the regular
and object-aware branches, scale and aspect penalty, cosine window), AutoMatch's network. The template's
features and target mask are kept from the initialisation; a re-initialisation starts afresh."""

from __future__ import annotations

import torch

from benchmarks.trackers import register
from benchmarks.trackers.automatch.model import load_automatch
from benchmarks.trackers.ocean.tracker import AnchorFreeTracker


@register("automatch")
class AutoMatchTracker(AnchorFreeTracker):
    """AutoMatch on ATSLTD frames with weights trained here (--checkpoint, else the shipped one)."""

    name = "automatch"
    load = staticmethod(load_automatch)


def trained_tracker(model: torch.nn.Module, seed: int) -> AutoMatchTracker:
    """The benchmark tracker of an AutoMatch network being trained, read as it is (the validation ARscore)."""
    return AutoMatchTracker.from_model(model)
