"""`siammask`: SiamMask tracking (Wang et al. 2019) on the ATSLTD frame of each segment.

The state moves as SiamRPN's (benchmarks/trackers/siamrpn/tracker.py: the penalised, windowed best anchor's
refined box, with SiamMask's published settings: window influence 0.4, penalty k 0.04, lr 1.0); the box reported
is the one taken from the mask predicted at that anchor's cell (siammask/masks.py: probabilities over its
response window, thresholded at `mask_threshold`, SiamMask's 0.35; `mask_box` "axis" (min-max) or "minarea" (the
minimum-area rectangle, made upright)), as SiamMask's tracker reports the mask's rectangle while its state follows
the regression. A mask with no pixel above the threshold reports the state's box.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
import torch
from pydantic import Field

from benchmarks.trackers import register
from benchmarks.trackers.siammask.masks import mask_box, window_centre, window_probabilities
from benchmarks.trackers.siammask.model import SiamMask, load_siammask
from benchmarks.trackers.siamrpn.model import TOTAL_STRIDE
from benchmarks.trackers.siamrpn.tracker import RPNTracker
from dvsot.core.strict import Float, Strict
from dvsot.dataset import Segment


class SiamMaskOptions(Strict):
    """`--option siammask.KEY=VALUE` settings (SiamMask's published values by default)."""

    checkpoint: str | None = None
    window_influence: Float = Field(0.4, ge=0, le=1)
    penalty_k: Float = Field(0.04, ge=0)
    lr: Float = Field(1.0, ge=0, le=1)
    mask_threshold: Float = Field(0.35, gt=0, lt=1)
    mask_box: Literal["axis", "minarea"] = "axis"


@register("siammask")
class SiamMaskTracker(RPNTracker):
    """SiamMask on ATSLTD frames with weights trained here (--checkpoint, else the shipped one)."""

    name = "siammask"
    options_type = SiamMaskOptions
    load = staticmethod(load_siammask)

    def update(self, segment: Segment) -> np.ndarray:
        """The box (xywh pixels) at the end of this segment: the predicted mask's rectangle."""
        if self.cached is None:
            raise RuntimeError("siammask: update() before init()")
        x, scale = self.search(segment)
        with torch.no_grad():
            scores, offsets, masks = self.model.track(self.cached, x)
        centre = self.centre.copy()  # the search crop's centre, before the step moves it
        best = self.step(scores, offsets, scale)
        cfg = self.model.cfg
        r = cfg.score_size()
        row, col = divmod(best % (r * r), r)
        prob = window_probabilities(masks[0, :, :, row, col].numpy(), cfg.exemplar_size)
        box = mask_box(prob, self.opts.mask_threshold, self.opts.mask_box)
        if not np.all(np.isfinite(box)):
            return self.box()
        wx, wy = window_centre(row, col, r, TOTAL_STRIDE, cfg.search_size)
        corner = (np.array([wx, wy]) - cfg.exemplar_size / 2 + box[:2] - cfg.search_size / 2) / scale + centre
        lo = np.clip(corner, 0, self.wh)
        hi = np.clip(corner + box[2:] / scale, 0, self.wh)
        if np.any(hi - lo <= 0):
            return self.box()
        return np.concatenate([lo, hi - lo]).astype(np.float32)


def validation_tracker(model: SiamMask, seed: int) -> SiamMaskTracker:
    """The benchmark tracker of a network being trained (the training registry's; deterministic, seed unused)."""
    return SiamMaskTracker.from_model(model)
