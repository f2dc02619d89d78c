"""Checkpoints and narrowing of the paper's ANN trackers trained here (GOTURN, SiamRPN, SiamMask, Ocean, AutoMatch).

A shipped checkpoint of one of these is seed 0 trained to its validation plateau: `<kind>_dvsot21.pt`, with the
`.json` saying how it was made, under CHECKPOINT_DIR (default_path); a tracker given no --checkpoint uses it. Where
none is there, the tracker says so in one line and how to train one. A checkpoint is read by sctn.checkpoint (format
"<kind>-checkpoint": another model's checkpoint is refused naming the model it holds; missing, damaged or
non-finite weights and a config the network cannot be built from are refused naming the file). The narrowing of
each network is measured against the paper-size network of benchmarks.trackers.reference_nets: parameters and
multiply-accumulates per tracked frame.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

import torch

from dvsot.core.errors import UserError

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
