"""`siamfc`: SiamFC tracking (Bertinetto et al. 2016) on the ATSLTD frame of each segment.

init: the exemplar crop of the init segment's frame around the ground-truth box, its features kept.
update: search crops at `scale_num` scales (scale_step ** (-1, 0, 1) of the current search extent),
one response map each, upsampled `response_up` x (bicubic); the off-centre scales are multiplied by
`scale_penalty`; the scale with the highest peak wins; its map is normalised to sum 1 and mixed with a
cosine (Hann) window (`window_influence`); the peak's displacement from the map's centre moves the
target, and the size moves towards the chosen scale by `scale_lr`. SiamFC's published settings
(3 scales, 1.0375, 0.9745, 0.59, 0.176, 16). The exemplar is never updated.
"""

from __future__ import annotations

import cv2
import numpy as np
import torch
from pydantic import Field

from benchmarks.trackers import register
from benchmarks.trackers.siamfc.crops import crop, exemplar_extent
from benchmarks.trackers.siamfc.model import TOTAL_STRIDE, SiamFC, load_siamfc
from benchmarks.trackers.trained_here import NetworkTracker, dense_counts
from dvsot.core.strict import Float, Int, Strict
from dvsot.dataset import Segment

MIN_SIZE_PX = 4.0


class SiamFCOptions(Strict):
    """`--option siamfc.KEY=VALUE` settings (SiamFC's published values by default)."""

    checkpoint: str | None = None
    scale_num: Int = Field(3, ge=1)
    scale_step: Float = Field(1.0375, ge=1.0)
    scale_penalty: Float = Field(0.9745, gt=0, le=1)
    scale_lr: Float = Field(0.59, ge=0, le=1)
    window_influence: Float = Field(0.176, ge=0, le=1)
    response_up: Int = Field(16, ge=1)


def hann_window(n: int) -> np.ndarray:
    """The n x n cosine window, normalised to sum 1."""
    h = np.outer(np.hanning(n), np.hanning(n))
    return (h / h.sum()).astype(np.float32)


def upsample(response: np.ndarray, factor: int) -> np.ndarray:
    """Bicubic upsampling (S, R, R) -> (S, R factor, R factor)."""
    size = response.shape[-1] * factor
    return np.stack([cv2.resize(r, (size, size), interpolation=cv2.INTER_CUBIC) for r in response])


def frame_macs(model: SiamFC, scale_num: int = 3, response_up: int = 16) -> dict:
    """MACs of one update, counted on the layers that run (backbone on the scale pyramid, cross-correlation), plus
    the bicubic upsampling (16 per output pixel per scale) and the window mix (1 per pixel); and of one init."""
    from sctn.energy import count_macs

    cfg = model.cfg
    x = torch.zeros(scale_num, 1, cfg.search_size, cfg.search_size)
    z = torch.zeros(1, 1, cfg.exemplar_size, cfg.exemplar_size)
    with torch.no_grad():
        z_feat = model.features(z)
    net = count_macs(lambda xs: model.correlate(z_feat, model.features(xs)), x)
    side = cfg.response_size() * response_up
    post = scale_num * side * side * 16 + side * side
    return {"mac_ops": net["mac_ops"] + post, "network_mac_ops": net["mac_ops"], "postprocess_mac_ops": post,
            "by_layer": net["by_layer"], "init_mac_ops": count_macs(model.features, z)["mac_ops"]}


@register("siamfc")
class SiamFCTracker(NetworkTracker):
    """SiamFC on ATSLTD frames with the weights trained here (shipped checkpoint by default)."""

    name = "siamfc"
    options_type = SiamFCOptions
    load = staticmethod(load_siamfc)

    def _start(self, model: SiamFC, opts: SiamFCOptions) -> None:
        self.opts = opts
        if self.opts.scale_num % 2 == 0:
            raise ValueError(f"scale_num must be odd (one scale at 1.0), got {self.opts.scale_num}")
        self.model: SiamFC = model
        n = self.opts.scale_num
        self.scales = self.opts.scale_step ** (np.arange(n) - (n - 1) / 2)
        self.window = hann_window(self.model.cfg.response_size() * self.opts.response_up)
        self.z_feat: torch.Tensor | None = None
        self._macs: tuple[dict, dict] | None = None

    def init(self, segment: Segment, box_xywh: np.ndarray, width: int, height: int) -> None:
        """Exemplar features from the init segment's frame around box_xywh (pixels)."""
        box = self._checked_box(box_xywh)
        self.wh = (int(width), int(height))
        self.centre = box[:2] + box[2:] / 2
        self.size = box[2:].copy()
        cfg = self.model.cfg
        self.z_extent = exemplar_extent(self.size)
        self.x_extent = self.z_extent * cfg.search_size / cfg.exemplar_size
        z = crop(self._frame(segment), tuple(self.centre), self.z_extent, cfg.exemplar_size)
        with torch.no_grad():
            self.z_feat = self.model.features(torch.from_numpy(z)[None, None])

    def search_crops(self, frame: np.ndarray) -> torch.Tensor:
        """The scale pyramid of search crops (S, 1, Sx, Sx) around the current centre."""
        size = self.model.cfg.search_size
        return torch.from_numpy(np.stack([crop(frame, tuple(self.centre), self.x_extent * s, size)
                                          for s in self.scales])[:, None])

    def update(self, segment: Segment) -> np.ndarray:
        """The box (xywh pixels) at the end of this segment."""
        if self.z_feat is None:
            raise RuntimeError("siamfc: update() before init()")
        x = self.search_crops(self._frame(segment))
        with torch.no_grad():
            response = self.model.correlate(self.z_feat, self.model.features(x))[:, 0].numpy()
        up = upsample(response, self.opts.response_up)
        mid = (len(self.scales) - 1) // 2
        peaks = up.reshape(len(up), -1).max(axis=1) * np.where(np.arange(len(up)) == mid, 1.0, self.opts.scale_penalty)
        best = int(np.argmax(peaks))
        r = up[best] - up[best].min()
        total = r.sum()
        r = r / total if total > 0 else np.zeros_like(r)  # a flat map (no events): the window alone decides
        wi = self.opts.window_influence
        r = (1 - wi) * r + wi * self.window
        py, px = np.unravel_index(int(np.argmax(r)), r.shape)
        disp = (np.array([px, py], np.float64) - (r.shape[0] - 1) / 2) * TOTAL_STRIDE / self.opts.response_up
        disp *= self.x_extent * self.scales[best] / self.model.cfg.search_size  # search-crop px -> sensor px
        self.centre = np.clip(self.centre + disp, 0, self.wh)
        s = (1 - self.opts.scale_lr) + self.opts.scale_lr * self.scales[best]
        self.size = np.clip(self.size * s, MIN_SIZE_PX, self.wh)
        self.z_extent *= s
        self.x_extent *= s
        return np.concatenate([self.centre - self.size / 2, self.size]).astype(np.float32)

    def frame_macs(self) -> dict:
        """MACs of one update and of one init (frame_macs with this tracker's settings)."""
        return frame_macs(self.model, len(self.scales), self.opts.response_up)

    def _counts(self) -> tuple[dict, dict]:
        """(update, init) operations, counted once on the layers: MACs and ReLU activations."""
        if self._macs is None:
            from sctn.energy import count_activations

            m, cfg = self.frame_macs(), self.model.cfg
            acts = count_activations(self.model.features, torch.zeros(len(self.scales), 1, cfg.search_size,
                                                                      cfg.search_size))
            init_acts = count_activations(self.model.features, torch.zeros(1, 1, cfg.exemplar_size, cfg.exemplar_size))
            self._macs = dense_counts(m["mac_ops"], acts, m["init_mac_ops"], init_acts)
        return self._macs
