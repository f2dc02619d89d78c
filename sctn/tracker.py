"""SCTN tracking (paper Algorithm 1): fine-tune on the initialisation segment, then score candidates per segment.

Per segment: 256 gaussian candidates around the last box (translation range `trans` x mean box
size, scale 1.05), each scored by the maximum voltage of the target neuron over the time window;
the boxes of the top 3 voltages give the mean voltage V* and the mean box. V* >= 0.2 resets the
translation range to its initial value; otherwise it grows by `trans_growth` up to `trans_max`.

The default is the paper's method: each candidate encoded on its own masked canvas and evaluated by
the whole network. `fast=True` is a named approximation: the convolutions run once over a search
region that holds every candidate (unmasked), then each candidate's crop of conv3's map, with cells
outside its box zeroed, feeds the fully connected layers (SCTN.forward_search); `crop` picks that
crop's sampling (bilinear at the sub-cell offset, or the nearest cell), and the fine-tuning adds
`finetune_search_iters` mini-batches run through the fast mode itself.

Candidates are drawn from a generator seeded by (seed, the previous box rounded to whole pixels), so
the same location always gets the same candidates (the paper fixes the test seed "to ensure the
target candidates generated for the same location are fixed"), whatever happened before.

Initialisation is Algorithm 1 (steps 1-2) under the protocol's re-initialisation, which reads (as VOT
and GOT-10k read it) as a new tracker: every initialisation, the first and each after a failure, fine-tunes
a fresh copy of the trained network on that segment's ground truth, with the fine-tuning's generator and
torch's seed restarted and the translation range reset, so nothing learnt or drawn on earlier segments
carries over (`reinit="new"`, the preset). Two named variants: `reinit="online"` tunes the network tuned so
far further at each re-initialisation (online learning on the test sequence; the row `online_tuning`), and
`reinit="once"` keeps the first tuning and resets only the box and the translation range (the row
`tuned_once`).

Fine-tuning's own settings (`error_time`, `finetune_balanced`, `finetune_layers`) are sctn.finetune's.
"""

from __future__ import annotations

import copy
import os

import numpy as np
import torch

from dvsot.events import EventBatch
from sctn.encoding import encode_search
from sctn.finetune import finetune
from sctn.network import SCTN
from sctn.params import SCTNParams
from sctn.samples import TRACK, propose
from sctn.sparse.evaluate import per_candidate_voltages


def location_rng(seed: int, box_xywh: np.ndarray) -> np.random.Generator:
    """The candidates' generator for a box: seeded by the seed and the box rounded to whole pixels."""
    return np.random.default_rng([int(seed)] + [int(v) for v in np.round(np.asarray(box_xywh, np.float64)) + 2**31])


class SCTNTracker:
    """Single-object tracker on event segments with a (fine-tuned copy of a) trained SCTN."""

    def __init__(self, model: SCTN | str | os.PathLike | None = None, params: SCTNParams | None = None,
                 **settings) -> None:
        """`model`: a network or a checkpoint path (the shipped one if None); `params` (SCTNParams), with any of
        its fields given as keywords on top (SCTNTracker(model, seed=1, fast=True)); bad values raise
        pydantic's ValidationError naming the field."""
        self.params = p = SCTNParams(**{**(params.model_dump(exclude_unset=True) if params is not None else {}),
                                        **settings})
        if model is None or isinstance(model, (str, os.PathLike)):
            from sctn.checkpoint import load_checkpoint

            model, _ = load_checkpoint(model)
        self.base = model
        self.model: SCTN = model
        self.seed, self.fast, self.finetune_iters, self.crop = p.seed, p.fast, p.finetune_iters, p.crop
        self.finetune_search_iters = p.finetune_search_iters if p.fast else 0
        self.finetune_options = {"error_time": p.error_time, "balanced": p.finetune_balanced,
                                 "layers": p.finetune_layers}
        self.reinit = p.reinit
        self.n_candidates, self.trans0, self.trans_growth, self.trans_max = (p.n_candidates, p.trans, p.trans_growth,
                                                                            p.trans_max)
        self.vstar_threshold, self.top_k = p.vstar_threshold, p.top_k
        self.rng = np.random.default_rng(p.seed)
        self.box = np.full(4, np.nan)
        self.trans = p.trans
        self.image_wh = (0, 0)
        self.tuned = False
        self.last_stats: dict = {}
        self.last_search: tuple[np.ndarray, np.ndarray] | None = None

    def init(self, events: EventBatch, t0_us: int, box_xywh: np.ndarray, width: int, height: int) -> None:
        """Start tracking box_xywh (pixels): fine-tune a fresh copy of the trained model on this segment, as a new
        tracker would (reinit "new"; "online" tunes the tuned one further, "once" only the first time)."""
        self.box = np.asarray(box_xywh, np.float64).copy()
        self.image_wh = (int(width), int(height))
        self.trans = self.trans0
        self.last_search = None
        first = not self.tuned
        if first or self.reinit == "new":
            self.rng = np.random.default_rng(self.seed)
            torch.manual_seed(self.seed)
            self.model = copy.deepcopy(self.base)
        self.last_stats = {}
        if self.finetune_iters > 0 and (first or self.reinit != "once"):
            self.last_stats = finetune(self.model, events, t0_us, self.box, self.image_wh, self.rng,
                                       iters=self.finetune_iters, search_iters=self.finetune_search_iters,
                                       crop=self.crop, **self.finetune_options)
        self.tuned = True

    def candidates(self) -> np.ndarray:
        """Gaussian candidates (N, 4) around the last box with the current translation range, fixed per location."""
        return propose(location_rng(self.seed, self.box), self.box, self.n_candidates, "gaussian", self.trans,
                       TRACK.scale, self.image_wh)

    def score(self, events: EventBatch, t0_us: int, boxes: np.ndarray) -> np.ndarray:
        """Maximum target-neuron voltage of each candidate over the time window."""
        cfg = self.model.cfg
        if hasattr(self.model, "candidate_scores"):  # a model that scores the boxes from the events itself (sctn.ann)
            return self.model.candidate_scores(events, t0_us, boxes)
        with torch.no_grad():
            if not self.fast:
                # event-driven, equal to the dense evaluation; the dense one for a model where it would not be
                v, self.candidate_path = per_candidate_voltages(self.model, events, t0_us, boxes)
                return v[:, :, 1].max(dim=1).values.numpy()
            region, origins, rboxes = encode_search(events, t0_us, boxes, self.box, cfg)
            v = self.model.forward_search(region, origins, rboxes, crop=self.crop)
            return v[:, :, 1].max(dim=1).values.numpy()

    def track(self, events: EventBatch, t0_us: int) -> np.ndarray:
        """The target's box (4,) xywh pixels at the end of this segment."""
        boxes = self.candidates()
        self.last_search = (boxes, self.box.copy())  # what was scored, for energy accounting
        scores = self.score(events, t0_us, boxes)
        top = np.argsort(-scores, kind="stable")[: self.top_k]
        vstar = float(scores[top].mean())
        # Algorithm 1: confident -> reset the search range, else widen it; the box is C* either way
        if vstar >= self.vstar_threshold:
            self.trans = self.trans0
        else:
            self.trans = min(self.trans * self.trans_growth, self.trans_max)
        self.box = boxes[top].mean(axis=0)
        self.last_stats = {"vstar": vstar, "trans": self.trans}
        return self.box.astype(np.float32).copy()
