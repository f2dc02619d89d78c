"""`ocean`: Ocean tracking (Zhang et al. 2020) on the ATSLTD frame of each segment; the anchor-free tracking
AutoMatch shares (`AnchorFreeTracker`).

init: the template crop of the init segment's frame around the ground-truth box, its kernels kept.
update: one search crop (SiamFC's geometry) around the current centre; per location its box (decoded
distances) and its score, `ratio` x sigmoid(regular-region logit) + (1 - ratio) x sigmoid(object-aware logit);
the scale and aspect penalty exp(-(r_c s_c - 1) penalty_k) (r_c, s_c: the box's aspect and size change against
the current target's, max(c, 1 / c)) multiplies the score, which is mixed with a cosine window
(`window_influence`); the best location's box centre is the new centre, and the size moves towards its box by
lr x penalty x score (SiamRPN's and Ocean's update). Defaults are pysot's SiamRPN++ values (Ocean tunes them per
benchmark and its paper gives none); `ratio` 0.5 weighs both scores equally. The template is never updated.
A re-initialisation starts afresh: nothing of an earlier target is kept.
"""

from __future__ import annotations

import numpy as np
import torch
from pydantic import Field

from benchmarks.trackers import register
from benchmarks.trackers.ocean.boxes import decode, locations
from benchmarks.trackers.ocean.crops import box_in_crop
from benchmarks.trackers.ocean.model import TOTAL_STRIDE, load_ocean
from benchmarks.trackers.siamfc.crops import crop, exemplar_extent
from benchmarks.trackers.siamfc.tracker import hann_window
from benchmarks.trackers.siamrpn.tracker import select
from benchmarks.trackers.trained_here import NetworkTracker, dense_counts
from dvsot.core.errors import UserError
from dvsot.core.strict import Float, Strict
from dvsot.dataset import Segment

MIN_SIZE_PX = 4.0


class AnchorFreeOptions(Strict):
    """`--option NAME.KEY=VALUE` settings of an anchor-free tracker (ocean, automatch)."""

    checkpoint: str | None = None
    window_influence: Float = Field(0.44, ge=0, le=1)
    penalty_k: Float = Field(0.04, ge=0)
    lr: Float = Field(0.4, ge=0, le=1)
    ratio: Float = Field(0.5, ge=0, le=1)


class AnchorFreeTracker(NetworkTracker):
    """Siamese anchor-free tracking on ATSLTD frames; subclasses set `name` and `load(path) -> (model, meta)`."""

    name = "anchor_free"
    options_type = AnchorFreeOptions

    def _start(self, model: torch.nn.Module, opts: AnchorFreeOptions) -> None:
        self.model, self.opts = model, opts
        r = model.response_size()
        self.window = hann_window(r).ravel()
        self.pos = locations(r, model.cfg.search_size, TOTAL_STRIDE)
        self.cached = None
        self._macs: tuple[dict, dict] | None = None

    def init(self, segment: Segment, box_xywh: np.ndarray, width: int, height: int) -> None:
        """Template kernels from the init segment's frame around box_xywh (pixels)."""
        if int(width) < 1 or int(height) < 1:
            raise UserError(f"{self.name}: a {width}x{height} px frame is no frame the network can take")
        box = self._checked_box(box_xywh)
        self.wh = (int(width), int(height))
        self.centre = box[:2] + box[2:] / 2
        self.size = box[2:].copy()
        cfg = self.model.cfg
        z_ext = exemplar_extent(self.size)
        z = crop(self._frame(segment), tuple(self.centre), z_ext, cfg.exemplar_size)
        z_box = box_in_crop(box, self.centre, z_ext, cfg.exemplar_size).astype(np.float32)
        with torch.no_grad():
            self.cached = self.model.template(torch.from_numpy(z)[None, None], torch.from_numpy(z_box)[None])

    def update(self, segment: Segment) -> np.ndarray:
        """The box (xywh pixels) at the end of this segment."""
        if self.cached is None:
            raise RuntimeError(f"{self.name}: update() before init()")
        cfg = self.model.cfg
        x_ext = exemplar_extent(self.size) * cfg.search_size / cfg.exemplar_size
        x = crop(self._frame(segment), tuple(self.centre), x_ext, cfg.search_size)
        with torch.no_grad():
            dist, cls, aware = self.model.track(self.cached, torch.from_numpy(x)[None, None])
            boxes = decode(dist, self.pos)[0].flatten(1).numpy().astype(np.float64)  # (4, R R) crop px
        score = (self.opts.ratio * torch.sigmoid(cls) + (1 - self.opts.ratio) * torch.sigmoid(aware)).ravel().numpy()
        scale = cfg.search_size / x_ext  # crop px per sensor px
        w = np.maximum(boxes[2] - boxes[0], 1e-3)
        h = np.maximum(boxes[3] - boxes[1], 1e-3)
        best, penalty = select(score, np.stack([w, h]), self.size * scale, self.window, self.opts.penalty_k,
                               self.opts.window_influence)
        b = boxes[:, best]
        self.centre = np.clip(self.centre + ((b[:2] + b[2:]) / 2 - cfg.search_size / 2) / scale, 0, self.wh)
        lr = penalty[best] * score[best] * self.opts.lr
        self.size = np.clip(self.size * (1 - lr) + np.array([w[best], h[best]]) / scale * lr, MIN_SIZE_PX, self.wh)
        return np.concatenate([self.centre - self.size / 2, self.size]).astype(np.float32)

    def _counts(self) -> tuple[dict, dict]:
        """(update, init) operations, counted once on the layers that run: MACs and ReLU activations."""
        if self._macs is None:
            from sctn.energy import count_activations, count_macs

            cfg = self.model.cfg
            z = torch.zeros(1, 1, cfg.exemplar_size, cfg.exemplar_size)
            z_box = torch.tensor([[cfg.exemplar_size / 4, cfg.exemplar_size / 4, cfg.exemplar_size * 3 / 4,
                                   cfg.exemplar_size * 3 / 4]])
            x = torch.zeros(1, 1, cfg.search_size, cfg.search_size)
            with torch.no_grad():
                cached = self.model.template(z, z_box)
            frame = count_macs(lambda xs: self.model.track(cached, xs), x)["mac_ops"]
            init = count_macs(lambda zs: self.model.template(zs, z_box), z)["mac_ops"]
            acts = count_activations(lambda xs: self.model.track(cached, xs), x)
            init_acts = count_activations(lambda zs: self.model.template(zs, z_box), z)
            self._macs = dense_counts(frame, acts, init, init_acts)
        return self._macs


@register("ocean")
class OceanTracker(AnchorFreeTracker):
    """Ocean on ATSLTD frames with weights trained here (--checkpoint, else the shipped one)."""

    name = "ocean"
    load = staticmethod(load_ocean)


def trained_tracker(model: torch.nn.Module, seed: int) -> OceanTracker:
    """The benchmark tracker of an Ocean network being trained, read as it is (the validation ARscore)."""
    return OceanTracker.from_model(model)
