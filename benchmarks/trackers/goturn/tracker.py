"""`goturn`: GOTURN tracking (Held et al. 2016) on the ATSLTD frame of each segment.

init: the init segment's frame and the ground-truth box become the previous frame and box. update: the crop of
the previous frame and of this segment's frame, both over the previous box's region (crops.region: twice its size
around its centre), go through the network together; its output, in the search crop's parametrisation
(crops.decode), is the new box, and this frame and box become the previous ones. No online adaptation, no
window or penalty: GOTURN regresses the box directly.
"""

from __future__ import annotations

import numpy as np
import torch

from benchmarks.trackers import register
from benchmarks.trackers.goturn.crops import crop_region, decode, region
from benchmarks.trackers.goturn.model import GOTURN, load_goturn
from benchmarks.trackers.trained_here import NetworkTracker, check_sensor, dense_counts, sensor_problem
from dvsot.core.strict import Strict
from dvsot.dataset import Segment

MIN_SIZE_PX = 4.0


class GOTURNOptions(Strict):
    """`--option goturn.KEY=VALUE` settings."""

    checkpoint: str | None = None


@register("goturn")
class GOTURNTracker(NetworkTracker):
    """GOTURN on ATSLTD frames with weights trained here (--checkpoint, else the shipped one)."""

    name = "goturn"
    options_type = GOTURNOptions
    load = staticmethod(load_goturn)

    def _start(self, model: GOTURN, opts: GOTURNOptions) -> None:
        self.model = model
        self.prev_frame: np.ndarray | None = None
        self._macs: tuple[dict, dict] | None = None

    @classmethod
    def frame_problem(cls, width: int, height: int) -> str | None:
        """Why this tracker cannot take frames of width x height px, or None (checked before a run)."""
        return sensor_problem("goturn", width, height)

    def init(self, segment: Segment, box_xywh: np.ndarray, width: int, height: int) -> None:
        """The init segment's frame and box_xywh (pixels) become the previous frame and box."""
        box = self._checked_box(box_xywh)
        self.wh = check_sensor("goturn", width, height)
        self.prev_frame, self.box = self._frame(segment), box.copy()

    def update(self, segment: Segment) -> np.ndarray:
        """The box (xywh pixels) at the end of this segment."""
        if self.prev_frame is None:
            raise RuntimeError("goturn: update() before init()")
        size = self.model.cfg.size
        rect = region(self.box)
        frame = self._frame(segment)
        z = torch.from_numpy(crop_region(self.prev_frame, rect, size))[None, None]
        x = torch.from_numpy(crop_region(frame, rect, size))[None, None]
        with torch.no_grad():
            out = self.model.track(z, x)[0].numpy()
        found = decode(out, rect)
        if np.all(np.isfinite(found)):
            centre = np.clip(found[:2] + found[2:] / 2, 0, self.wh)  # the centre stays on the sensor
            wh = np.clip(found[2:], MIN_SIZE_PX, self.wh)
            self.box = np.concatenate([centre - wh / 2, wh])
        self.prev_frame = frame
        return self.box.astype(np.float32)

    def _counts(self) -> tuple[dict, dict]:
        """(update, init) operations, counted once: MACs (both crops through the trunk, the regressor), pJ and
        ReLU activations; an init computes nothing."""
        if self._macs is None:
            from sctn.energy import count_activations
            from sctn.macs import count_macs

            s = self.model.cfg.size
            z = torch.zeros(1, 1, s, s)
            macs = count_macs(lambda xs: self.model.track(z, xs), z.clone(), root=self.model)["mac_ops"]
            acts = count_activations(lambda xs: self.model.track(z, xs), z.clone())
            self._macs = dense_counts(macs, acts, 0.0, 0.0)
        return self._macs


def validation_tracker(model: GOTURN, seed: int) -> GOTURNTracker:
    """The benchmark tracker of a network being trained (the training registry's; deterministic, seed unused)."""
    return GOTURNTracker.from_model(model)
