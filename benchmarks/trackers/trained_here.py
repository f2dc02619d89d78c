"""Checkpoints and narrowing of the paper's ANN trackers trained here (GOTURN, SiamRPN, SiamMask, Ocean, AutoMatch).

A shipped checkpoint of one of these is seed 0 trained to its validation plateau: `<kind>_dvsot21.pt`, with the
`.json` saying how it was made, under CHECKPOINT_DIR (default_path); a tracker given no --checkpoint uses it. Where
none is there, the tracker says so in one line and how to train one. A checkpoint is read by sctn.checkpoint (format
"<kind>-checkpoint": another model's checkpoint is refused naming the model it holds; missing, damaged or
non-finite weights and a config the network cannot be built from are refused naming the file). The narrowing of
each network is measured against the paper-size network of benchmarks.trackers.reference_nets: parameters and
multiply-accumulates per tracked frame. `NetworkTracker` is what their trackers (and SiamFC's) share: the ATSLTD
frame of a segment, the initial box's check, a tracker on a checkpoint or on a network in memory, and the
operation counts of a dense network.
"""

from __future__ import annotations

import os
from abc import abstractmethod
from collections.abc import Callable
from pathlib import Path

import numpy as np
import torch

from benchmarks.trackers.atsltd import atsltd_frame
from benchmarks.trackers.base import Tracker
from dvsot.core.errors import UserError
from dvsot.dataset import Segment

CHECKPOINT_DIR = Path(__file__).resolve().parent / "checkpoints"


def default_path(kind: str) -> Path:
    """The shipped checkpoint of `kind` (seed 0 at its validation plateau, its .json beside it), if it is there."""
    return CHECKPOINT_DIR / f"{kind}_dvsot21.pt"


def load_trained(path: str | os.PathLike | None, kind: str, label: str,
                 build: Callable[[dict], torch.nn.Module], article: str = "a") -> tuple[torch.nn.Module, dict]:
    """The network and metadata of a `kind` checkpoint; UserError in one line if there is none or it is unusable."""
    from sctn.checkpoint import load_model

    if path is None and not default_path(kind).is_file():
        raise UserError(f"{kind}: no shipped checkpoint exists (no such checkpoint {default_path(kind)}); train one "
                        f"with `dvsot train --model {kind} -o {kind}.pt` and give it with --checkpoint {kind}.pt")
    return load_model(path, default_path(kind), kind, label, build, article=article)


def narrowing(ours: torch.nn.Module, reference: torch.nn.Module, in_channels: int = 1) -> dict:
    """Parameters and MACs per tracked frame (template cached) of a network here beside its paper-size reference
    (three input channels), and their ratios; both networks implement reference_nets.SiameseNet's split."""
    from benchmarks.trackers.reference_nets import count_siamese
    from sctn.macs import count_macs

    def params(net: torch.nn.Module) -> int:
        return int(sum(p.numel() for p in net.parameters()))

    ref = count_siamese(reference)
    net = ours.eval()
    z = torch.zeros(1, in_channels, net.template_size, net.template_size)
    x = torch.zeros(1, in_channels, net.search_size, net.search_size)
    with torch.no_grad():
        cached = net.template(z)
    macs = count_macs(lambda xs: net.track(cached, xs), x, root=net)["mac_ops"]
    ref_params = params(reference)
    return {"params": params(ours), "params_reference": ref_params, "params_ratio": params(ours) / ref_params,
            "frame_macs": macs, "frame_macs_reference": ref["per_frame"]["mac_ops"],
            "frame_macs_ratio": macs / ref["per_frame"]["mac_ops"]}


MIN_SENSOR_PX = 8  # a smaller frame holds no target these crops can resolve


def sensor_problem(name: str, width: int, height: int) -> str | None:
    """Why tracker `name` cannot take frames of width x height px, or None."""
    if int(width) < MIN_SENSOR_PX or int(height) < MIN_SENSOR_PX:
        return (f"{name}: a {int(width)}x{int(height)} px frame is smaller than the {MIN_SENSOR_PX}x{MIN_SENSOR_PX} "
                "px this network's crops need")
    return None


def check_sensor(name: str, width: int, height: int) -> tuple[int, int]:
    """(width, height) of a sensor the tracker can crop from; UserError naming the size otherwise."""
    problem = sensor_problem(name, width, height)
    if problem:
        raise UserError(problem)
    return int(width), int(height)


def dense_counts(frame_macs: float, frame_activations: float, init_macs: float,
                 init_activations: float) -> tuple[dict, dict]:
    """(update, init) operations of a dense network (Tracker.energy_per_segment's keys): MACs, their pJ
    (sctn.energy.E_MAC_PJ a MAC) and ReLU activations; no ACs, no neuron state."""
    from sctn.energy import E_MAC_PJ

    return ({"ac_ops": 0.0, "mac_ops": frame_macs, "energy_pj": frame_macs * E_MAC_PJ, "state_updates": 0.0,
             "activations": frame_activations, "evaluations": 1},
            {"ac_ops": 0.0, "mac_ops": init_macs, "energy_pj": init_macs * E_MAC_PJ, "state_updates": 0.0,
             "activations": init_activations})


class NetworkTracker(Tracker):
    """A tracker of one network on ATSLTD frames (paper eq. 11, divided by 255): on a checkpoint (`--option
    NAME.checkpoint`, else the shipped one) or on a network in memory (from_model). Subclasses set `name`,
    `options_type` (with a `checkpoint` field), `load(path) -> (network, metadata)`, `_start(model, opts)` and
    `_counts() -> (update, init)` operations."""

    options_type: type
    operations = ("mac_ops", "activations")  # energy_per_segment's counts, timed by a declared latency

    @staticmethod
    @abstractmethod
    def load(path: str | None) -> tuple[torch.nn.Module, dict]:
        """The network and metadata of a checkpoint of this tracker's model (the subclass's loader)."""

    def __init__(self, **options) -> None:
        opts = self.options_type(**options)
        self._start(type(self).load(opts.checkpoint)[0], opts)

    @classmethod
    def from_model(cls, model: torch.nn.Module, **options) -> NetworkTracker:
        """The tracker on a network in memory (one being trained, for its validation score); `options` as the
        options type's less the checkpoint. The network is read, never changed."""
        opts = cls.options_type(**options)
        if opts.checkpoint is not None:
            raise ValueError(f"{cls.name}: a tracker on a given network takes no checkpoint")
        self = cls.__new__(cls)
        self._start(model, opts)
        return self

    @abstractmethod
    def _start(self, model: torch.nn.Module, opts) -> None:
        """Hold the network and the options; reset the tracking state."""

    def _frame(self, segment: Segment) -> np.ndarray:
        """The segment's ATSLTD frame (height, width) float32 in [0, 1] on the sensor set by init (self.wh)."""
        window = max(1, int(segment.t1_us) - int(segment.t0_us))
        return atsltd_frame(segment.events, self.wh[0], self.wh[1], window).astype(np.float32) / 255.0

    def _checked_box(self, box_xywh: np.ndarray) -> np.ndarray:
        """box_xywh as float64 (4,) px; ValueError naming the tracker if it is absent (NaN) or empty."""
        box = np.asarray(box_xywh, np.float64).reshape(4)
        if not np.all(np.isfinite(box)) or box[2] <= 0 or box[3] <= 0:
            raise ValueError(f"{self.name}: cannot initialise on an absent or empty box {box.tolist()}")
        return box

    @abstractmethod
    def _counts(self) -> tuple[dict, dict]:
        """Operations of one update and of one initialisation (energy_per_segment's and energy_per_init's dicts)."""

    def energy_per_segment(self) -> dict | None:
        """MACs, pJ (4.6 pJ a MAC) and ReLU activations of one update: dense, the same for every frame."""
        return self._counts()[0]

    def energy_per_init(self) -> dict | None:
        """MACs, pJ and activations of one init (what it computes ahead: the template's features, if any)."""
        return self._counts()[1]
