"""Fine-tuning SCTN in place on one segment (paper Algorithm 1, steps 1-2): what the tracker runs at a sequence's start.

Kept apart from sctn/training/snn.py so that inference (sctn/tracker.py) does not depend on the training loop.
"""

from __future__ import annotations

from typing import get_args

import numpy as np
import torch

from dvsot.events import EventBatch
from sctn.encoding import encode_boxes, encode_search
from sctn.energy import layer_ops, search_record_ops, snn_state_updates
from sctn.loss import error_voltages, voltage_loss
from sctn.network import SCTN
from sctn.params import FinetuneLayers
from sctn.samples import FINETUNE, labelled_samples

BALANCED = (32, 96)  # positives and negatives per balanced mini-batch (MDNet's fine-tuning batches)


def tuned_parameters(model: SCTN, layers: str = "all") -> list[torch.nn.Parameter]:
    """The parameters fine-tuning updates: every one ("all"), or the fully connected layers' weights and their
    neurons' time constants ("fc"; MDNet tunes its fully connected layers only)."""
    if layers == "all":
        return list(model.parameters())
    if layers == "fc":
        return list(model.fcs.parameters()) + [q for n in model.neurons[len(model.convs):] for q in n.parameters()]
    raise ValueError(f"fine-tuning layers must be one of {', '.join(get_args(FinetuneLayers))}, got {layers!r}")


def minibatch(rng: np.random.Generator, candidates: np.ndarray, positive: np.ndarray, batch: int,
              balanced: bool) -> np.ndarray:
    """Indices into `candidates` (sample indices) of one mini-batch: `batch` drawn without replacement, or with
    `balanced` BALANCED[0] positives and BALANCED[1] negatives (fewer where fewer exist)."""
    if not balanced:
        return rng.choice(candidates, min(batch, len(candidates)), replace=False)
    pos, neg = candidates[positive[candidates]], candidates[~positive[candidates]]
    return np.concatenate([rng.choice(pos, min(BALANCED[0], len(pos)), replace=False),
                           rng.choice(neg, min(BALANCED[1], len(neg)), replace=False)])


def finetune(model: SCTN, events: EventBatch, t0_us: int, box: np.ndarray, image_wh: tuple[int, int],
             rng: np.random.Generator, iters: int = 10, batch: int = 128, lr: float = 1e-3, kind: str = "exp",
             specs=FINETUNE, search_iters: int = 0, crop: str = "bilinear", error_time: str = "stca",
             balanced: bool = False, layers: str = "all") -> dict:
    """Fine-tune in place on one segment: 500 gaussian positives, 1000 uniform + 1000 whole-image negatives.

    Each mini-batch is `batch` samples drawn at random (about a fifth positive), or with `balanced` 32
    positives and 96 negatives; `layers` "fc" tunes the fully connected layers only (tuned_parameters);
    each sample's error sits at the step `error_time` picks (sctn.loss.error_steps, random steps from rng).

    search_iters more mini-batches then run through the fast mode (SCTN.forward_search with `crop`)
    on the samples within two box sizes of the box (whole-image negatives would make the region the
    whole sensor), so the network also adapts to the fast mode's inputs.

    Returns the first and last losses and "finetune_ops": the samples run forward and, for a spiking model, the
    synaptic operations (ACs; MACs of the fast mode's bilinear mix) and C-LIF updates their forward passes ran
    (sctn.energy_run prices them with the backward passes).
    """
    box = np.asarray(box, np.float64)
    boxes, iou, pos = labelled_samples(rng, box, specs, image_wh)
    offset = np.abs(boxes[:, :2] + boxes[:, 2:] / 2 - box[:2] - box[2:] / 2).max(axis=1)
    near = np.flatnonzero(offset <= 2 * box[2:].max())  # the positives and the uniform negatives
    cfg = model.cfg
    opt = torch.optim.Adam(tuned_parameters(model, layers), lr=lr)
    everything = np.arange(len(boxes))
    model.train()
    losses = []
    spiking = hasattr(model, "forward_record")  # SCTN: its spikes are counted as they run; the twin is dense
    ops = {"samples": 0, "forward_ac_ops": 0.0, "forward_mac_ops": 0.0, "forward_state_updates": 0.0}
    for i in range(iters + search_iters):
        if i < iters:
            pick = minibatch(rng, everything, pos, batch, balanced)
            x = encode_boxes(events, t0_us, boxes[pick], cfg)
            if spiking:  # the same voltages as model(x), with the spikes kept for counting
                volts, spikes = model.forward_record(x)
                ops["forward_ac_ops"] += float(sum(o.sum() for o in layer_ops(model, [h.detach() for h in spikes])))
                ops["forward_state_updates"] += snn_state_updates(cfg) * len(pick)
            else:
                volts = model(x)
        else:
            pick = minibatch(rng, near, pos, batch, balanced)
            region, origins, rboxes = encode_search(events, t0_us, boxes[pick], box, cfg)
            volts, rec = model.forward_search(region, origins, rboxes, record=True, crop=crop)
            run = search_record_ops(model, tuple(region.shape[-2:]), rec)
            ops["forward_ac_ops"] += run["ac_ops"]
            ops["forward_mac_ops"] += run["mac_ops"]
            ops["forward_state_updates"] += run["state_updates"]
        ops["samples"] += len(pick)
        positive = torch.from_numpy(pos[pick])
        loss = voltage_loss(error_voltages(volts, positive, error_time, rng), torch.from_numpy(iou[pick]), positive,
                            kind)
        opt.zero_grad()
        loss.backward()
        opt.step()
        losses.append(float(loss.detach()))
    model.eval()
    return {"finetune_loss_first": losses[0] if losses else None, "finetune_loss_last": losses[-1] if losses else None,
            "finetune_ops": ops}
