"""`siamrpn`: SiamRPN tracking (Li et al. 2018) on the ATSLTD frame of each segment.

init: the template crop (SiamFC's context square) of the init segment's frame around the ground-truth box; its
classification and regression kernels are kept (the template is never updated). update: one search crop of
search_size / exemplar_size times the context square around the current centre; every anchor's target score
(softmax) and refined box (anchors.decode); SiamRPN's proposal selection: the score times the penalty
exp(-(r s - 1) penalty_k), r and s the change of aspect ratio and of (context) scale from the current box
(each max(c, 1 / c)), then mixed with a cosine window (`window_influence`); the best anchor's refined box moves the
centre and moves the size by lr x its penalised score. Defaults: SiamRPN's code's published values (0.42,
0.055, 0.295).
"""

from __future__ import annotations

import numpy as np
import torch
from pydantic import Field

from benchmarks.trackers import register
from benchmarks.trackers.siamfc.crops import crop, exemplar_extent
from benchmarks.trackers.siamrpn.anchors import decode, make_anchors
from benchmarks.trackers.siamrpn.model import TOTAL_STRIDE, SiamRPN, load_siamrpn
from benchmarks.trackers.trained_here import NetworkTracker, check_sensor, dense_counts, sensor_problem
from dvsot.core.strict import Float, Strict
from dvsot.dataset import Segment

MIN_SIZE_PX = 4.0


class SiamRPNOptions(Strict):
    """`--option siamrpn.KEY=VALUE` settings (SiamRPN's published values by default)."""

    checkpoint: str | None = None
    window_influence: Float = Field(0.42, ge=0, le=1)
    penalty_k: Float = Field(0.055, ge=0)
    lr: Float = Field(0.295, ge=0, le=1)


def change(r: np.ndarray) -> np.ndarray:
    """max(r, 1 / r): how far a ratio is from 1, either way."""
    return np.maximum(r, 1.0 / r)


def context_size(w: np.ndarray, h: np.ndarray) -> np.ndarray:
    """SiamRPN's scale of a box: the side of its context square sqrt((w + p)(h + p)), p = (w + h) / 2."""
    p = (w + h) * 0.5
    return np.sqrt((w + p) * (h + p))


def select(score: np.ndarray, sizes: np.ndarray, size_crop: np.ndarray, window: np.ndarray, penalty_k: float,
           window_influence: float) -> tuple[int, np.ndarray]:
    """SiamRPN's proposal selection (Ocean's too): the index of the best of the flat proposals (score (N,), sizes
    (2, N) w, h crop px) for a target of size_crop (w, h crop px), and the scale/aspect penalty of every proposal."""
    s_c = change(context_size(sizes[0], sizes[1]) / context_size(size_crop[0], size_crop[1]))
    r_c = change((size_crop[0] / size_crop[1]) / (sizes[0] / sizes[1]))
    penalty = np.exp(-(r_c * s_c - 1.0) * penalty_k)
    pscore = penalty * score * (1 - window_influence) + window * window_influence
    return int(np.argmax(pscore)), penalty


class RPNTracker(NetworkTracker):
    """The RPN trackers' state and step (SiamRPN; SiamMask adds the mask): subclasses give the network and
    `outputs(x)` -> (scores (2, k, R, R), offsets (4, k, R, R)) of one search crop."""

    name = "siamrpn"
    options_type: type = SiamRPNOptions
    load = staticmethod(load_siamrpn)

    def _start(self, model: torch.nn.Module, opts) -> None:
        self.opts, self.model = opts, model
        cfg = model.cfg
        r = cfg.score_size()
        self.anchors = make_anchors(r, TOTAL_STRIDE, cfg.ratios, cfg.anchor_scale).reshape(4, -1)
        hann = np.outer(np.hanning(r), np.hanning(r))
        self.window = np.tile(hann.ravel(), len(cfg.ratios))
        self.cached = None
        self._macs: tuple[dict, dict] | None = None

    @classmethod
    def frame_problem(cls, width: int, height: int) -> str | None:
        """Why this tracker cannot take frames of width x height px, or None (checked before a run)."""
        return sensor_problem(cls.name, width, height)

    def init(self, segment: Segment, box_xywh: np.ndarray, width: int, height: int) -> None:
        """Template kernels from the init segment's frame around box_xywh (pixels)."""
        box = self._checked_box(box_xywh)
        self.wh = check_sensor(self.name, width, height)
        self.centre, self.size = box[:2] + box[2:] / 2, box[2:].copy()
        z = crop(self._frame(segment), tuple(self.centre), exemplar_extent(self.size), self.model.cfg.exemplar_size)
        with torch.no_grad():
            self.cached = self.model.template(torch.from_numpy(z)[None, None])

    def search(self, segment: Segment) -> tuple[torch.Tensor, float]:
        """The search crop (1, 1, S, S) of this segment's frame and its scale (crop px per sensor px)."""
        cfg = self.model.cfg
        extent = exemplar_extent(self.size) * cfg.search_size / cfg.exemplar_size
        x = crop(self._frame(segment), tuple(self.centre), extent, cfg.search_size)
        return torch.from_numpy(x)[None, None], cfg.search_size / extent

    def step(self, scores: torch.Tensor, offsets: torch.Tensor, scale: float) -> int:
        """Move the state by the selected proposal of one search crop's outputs; returns its flat index."""
        score = torch.softmax(scores[0], dim=0)[1].reshape(-1).numpy().astype(np.float64)
        boxes = decode(offsets[0].reshape(4, -1).numpy(), self.anchors)
        best, penalty = select(score, boxes[2:], self.size * scale, self.window, self.opts.penalty_k,
                               self.opts.window_influence)
        found = boxes[:, best] / scale
        lr = penalty[best] * score[best] * self.opts.lr
        self.centre = np.clip(self.centre + found[:2], 0, self.wh)
        self.size = np.clip(self.size * (1 - lr) + found[2:] * lr, MIN_SIZE_PX, self.wh)
        return best

    def box(self) -> np.ndarray:
        """The current box, xywh float32 px."""
        return np.concatenate([self.centre - self.size / 2, self.size]).astype(np.float32)

    def update(self, segment: Segment) -> np.ndarray:
        """The box (xywh pixels) at the end of this segment."""
        if self.cached is None:
            raise RuntimeError(f"{self.name}: update() before init()")
        x, scale = self.search(segment)
        with torch.no_grad():
            scores, offsets = self.model.track(self.cached, x)
        self.step(scores, offsets, scale)
        return self.box()

    def frame_macs(self) -> dict:
        """MACs of one update (the search branch and head on the cached kernels) and of one init (sctn.macs)."""
        from sctn.macs import count_macs

        cfg = self.model.cfg
        z = torch.zeros(1, 1, cfg.exemplar_size, cfg.exemplar_size)
        x = torch.zeros(1, 1, cfg.search_size, cfg.search_size)
        with torch.no_grad():
            cached = self.model.template(z)
        frame = count_macs(lambda xs: self.network_pass(cached, xs), x, root=self.model)
        return {"mac_ops": frame["mac_ops"], "by_layer": frame["by_layer"],
                "init_mac_ops": count_macs(self.model.template, z, root=self.model)["mac_ops"]}

    def network_pass(self, cached, x: torch.Tensor):
        """What one update runs on the network for a search crop x (for counting)."""
        return self.model.track(cached, x)

    def _counts(self) -> tuple[dict, dict]:
        """(update, init) operations, counted once: MACs, the pJ they cost (4.6 pJ a MAC) and ReLU activations."""
        if self._macs is None:
            from sctn.energy import count_activations

            m, cfg = self.frame_macs(), self.model.cfg
            z = torch.zeros(1, 1, cfg.exemplar_size, cfg.exemplar_size)
            with torch.no_grad():
                cached = self.model.template(z)
            acts = count_activations(lambda xs: self.network_pass(cached, xs),
                                     torch.zeros(1, 1, cfg.search_size, cfg.search_size))
            self._macs = dense_counts(m["mac_ops"], acts, m["init_mac_ops"], count_activations(self.model.template, z))
        return self._macs


@register("siamrpn")
class SiamRPNTracker(RPNTracker):
    """SiamRPN on ATSLTD frames with weights trained here (--checkpoint, else the shipped one)."""

    name = "siamrpn"


def validation_tracker(model: SiamRPN, seed: int) -> SiamRPNTracker:
    """The benchmark tracker of a network being trained (the training registry's; deterministic, seed unused)."""
    return SiamRPNTracker.from_model(model)
