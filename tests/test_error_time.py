"""Where a sample's error sits in time (sctn.loss.error_steps): STCA's rule, the preset's, against the maximum."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from sctn.loss import error_steps, error_voltages, peak_steps

sys.path.insert(0, str(Path(__file__).parent))
from synthetic import moving_square_file  # noqa: E402

torch.set_num_threads(1)


def _volts(*rows: list[float]) -> torch.Tensor:
    """(N, T, 1) voltages of one neuron from rows of T values."""
    return torch.tensor(rows, dtype=torch.float32)[:, :, None]


def test_peak_steps_closed_form() -> None:
    v = _volts([0.0, 0.2, 0.1, 0.3, 0.25],   # two peaks: 0.3 at step 3 is the higher
               [0.0, 0.0, -0.2, -0.4, -0.1],  # no peak: rest, then below rest, rising at the end from below
               [0.0, 0.0, -0.2, -0.1, -0.3],  # a peak below rest at step 3
               [0.1, 0.2, 0.3, 0.4, 0.45],    # rising to the end: the last step
               [0.0, 0.7, 0.2, 0.1, 0.0])     # its only peak is at theta or above: none below it
    assert peak_steps(v)[:, 0].tolist() == [3, 4, 3, 4, -1]
    assert peak_steps(_volts([0.0, 0.0, 0.0]))[:, 0].tolist() == [-1]  # resting: no peak


def test_stca_steps_by_case() -> None:
    v = _volts([0.0, 0.0, -0.3, -0.2, -0.4],  # should fire, never did, a peak at step 3
               [0.0, 0.0, -0.1, -0.2, -0.3],  # should fire, no peak: a drawn step
               [0.0, 0.6, 0.2, 0.8, 0.1],     # fired: its firing step of largest V
               [0.0, 0.3, 0.1, 0.0, 0.0])     # should not fire: the step of largest V
    should = torch.tensor([[True], [True], [True], [False]])
    rng = np.random.default_rng(5)
    drawn = np.random.default_rng(5).integers(0, 5, size=(4, 1))
    steps = error_steps(v, should, "stca", rng)[:, 0].tolist()
    assert steps == [3, int(drawn[1, 0]), 3, 1]
    assert error_steps(v, should, "max")[:, 0].tolist() == [0, 0, 3, 1]  # the first of equal maxima: a quiet step
    with pytest.raises(ValueError, match="random generator"):
        error_steps(v, should, "stca")
    with pytest.raises(ValueError, match="unknown error time"):
        error_steps(v, should, "mean")


def test_max_rule_is_vmax_and_gradient_sits_at_one_step() -> None:
    volts = torch.randn(6, 10, 2, requires_grad=True)
    pos = torch.tensor([True, False, True, False, True, False])
    assert torch.equal(error_voltages(volts, pos, "max"), volts.max(dim=1).values)
    v = error_voltages(volts, pos, "stca", np.random.default_rng(0))
    v.sum().backward()
    assert torch.equal((volts.grad != 0).sum(dim=1), torch.ones(6, 2, dtype=torch.long))


def test_shipped_checkpoint_with_negative_target_row_learns_only_with_stca(tmp_path) -> None:
    """The shipped network with its target neuron's weights set to -|w| never fires; on a segment whose first
    2 ms are quiet the maximum sits on a quiet step (zero gradient, loss not zero); STCA's rule reaches every
    layer."""
    from dvsot.dataset import Dataset
    from sctn.checkpoint import load_checkpoint
    from sctn.encoding import encode_boxes
    from sctn.samples import TRAIN, labelled_samples
    from sctn.train import TrainConfig, batch_loss

    path = moving_square_file(tmp_path / "syn.h5", duration_ms=40, seed=1)
    model, _ = load_checkpoint(None)
    with torch.no_grad():
        model.fcs[2].weight[1] = -model.fcs[2].weight[1].abs()
    with Dataset(path) as ds:
        seg, wh = ds.segment(2), (ds.width, ds.height)
    boxes, iou, pos = labelled_samples(np.random.default_rng(0), seg.box, TRAIN, wh)
    x = encode_boxes(seg.events, seg.t0_us - 2000, boxes, model.cfg)  # the segment 2 ms later: steps 0-1 quiet
    assert x[:, :2].sum() == 0 and x.sum() > 0
    iou, pos = torch.from_numpy(iou), torch.from_numpy(pos)
    layers = list(model.convs) + list(model.fcs)
    grads = {}
    for rule in ("max", "stca"):
        model.zero_grad()
        loss = batch_loss(model(x), iou, pos, TrainConfig(error_time=rule), np.random.default_rng(0))
        loss.backward()
        assert float(loss.detach()) > 0
        grads[rule] = [float(layer.weight.grad.abs().sum()) for layer in layers]
    assert grads["max"] == [0.0] * len(layers)
    assert all(g > 0 for g in grads["stca"]), grads["stca"]
