"""Fine-tuning SCTN in place on one segment (paper Algorithm 1, steps 1-2): what the tracker runs at a sequence's start.

Kept apart from sctn/training/snn.py so that inference (sctn/tracker.py) does not depend on the training loop.
"""

from __future__ import annotations

import numpy as np
import torch

from dvsot.events import EventBatch
from sctn.encoding import encode_boxes, encode_search
from sctn.loss import voltage_loss
from sctn.network import SCTN
from sctn.samples import FINETUNE, labelled_samples


def finetune(model: SCTN, events: EventBatch, t0_us: int, box: np.ndarray, image_wh: tuple[int, int],
             rng: np.random.Generator, iters: int = 10, batch: int = 128, lr: float = 1e-3, kind: str = "exp",
             specs=FINETUNE, search_iters: int = 0, crop: str = "bilinear") -> dict:
    """Fine-tune in place on one segment: 500 gaussian positives, 1000 uniform + 1000 whole-image negatives.

    search_iters more mini-batches then run through the fast mode (SCTN.forward_search with `crop`)
    on the samples within two box sizes of the box (whole-image negatives would make the region the
    whole sensor), so the network also adapts to the fast mode's inputs.
    """
    box = np.asarray(box, np.float64)
    boxes, iou, pos = labelled_samples(rng, box, specs, image_wh)
    offset = np.abs(boxes[:, :2] + boxes[:, 2:] / 2 - box[:2] - box[2:] / 2).max(axis=1)
    near = np.flatnonzero(offset <= 2 * box[2:].max())  # the positives and the uniform negatives
    cfg = model.cfg
    opt = torch.optim.Adam(model.parameters(), lr=lr)
    model.train()
    losses = []
    for i in range(iters + search_iters):
        if i < iters:
            pick = rng.choice(len(boxes), min(batch, len(boxes)), replace=False)
            x = encode_boxes(events, t0_us, boxes[pick], cfg)
            vmax = model(x).max(dim=1).values
        else:
            pick = rng.choice(near, min(batch, len(near)), replace=False)
            region, origins, rboxes = encode_search(events, t0_us, boxes[pick], box, cfg)
            vmax = model.forward_search(region, origins, rboxes, crop=crop).max(dim=1).values
        loss = voltage_loss(vmax, torch.from_numpy(iou[pick]), torch.from_numpy(pos[pick]), kind)
        opt.zero_grad()
        loss.backward()
        opt.step()
        losses.append(float(loss.detach()))
    model.eval()
    return {"finetune_loss_first": losses[0] if losses else None, "finetune_loss_last": losses[-1] if losses else None}
