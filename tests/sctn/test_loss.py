"""The voltage loss and its feedback by hand: the paper's eq. 5 and its named deviations, and its gradient."""

import math

import numpy as np
import pytest
import torch

from sctn.loss import feedback, voltage_loss

torch.set_num_threads(1)


def test_loss_values_by_hand():
    iou = torch.tensor([0.8, 1.0, 0.3, 0.2])
    pos = torch.tensor([True, True, False, False])
    np.testing.assert_allclose(feedback(iou, pos, "exp"), [math.exp(4) / 100, math.exp(5) / 100, -0.3, -0.3], rtol=1e-6)
    np.testing.assert_allclose(feedback(iou, pos, "linear"), [0.7, 1.5, -0.3, -0.3], rtol=1e-6)
    np.testing.assert_allclose(feedback(iou, pos, "basic"), [1.0, 1.0, -0.3, -0.3])
    # target V_max: pos 0.5 (short by e^4/100), pos 3.0 (ok), neg 0.1 (ok), neg 0.6 (0.4 too high);
    # background V_max: pos 0.1 (ok), pos 0.5 (0.3 too high), neg 0.9 (ok), neg 0.6 (short by 0.2)
    vmax = torch.tensor([[0.1, 0.5], [0.5, 3.0], [0.9, 0.1], [0.6, 0.6]])
    # the paper's eq. 5: the target neuron's errors, as they are, averaged over the samples
    paper = (math.exp(4) / 100 + 0.4) / 4
    assert float(voltage_loss(vmax, iou, pos, "exp")) == pytest.approx(paper, rel=1e-5)
    # the named deviations: squared errors, and the mirrored background neuron
    squared = ((math.exp(4) / 100) ** 2 + 0.4 ** 2) / 4
    assert float(voltage_loss(vmax, iou, pos, "exp", squared=True)) == pytest.approx(squared, rel=1e-5)
    both = ((math.exp(4) / 100) ** 2 + 0.3 ** 2 + 0.4 ** 2 + 0.2 ** 2) / 4
    assert float(voltage_loss(vmax, iou, pos, "exp", squared=True, background=True)) == pytest.approx(both, rel=1e-5)
    linear_bg = (math.exp(4) / 100 + 0.3 + 0.4 + 0.2) / 4
    assert float(voltage_loss(vmax, iou, pos, "exp", background=True)) == pytest.approx(linear_bg, rel=1e-5)
    # its gradient: -1/N on the short positive, +1/N on the wrong negative, 0 where eq. 5 is satisfied
    v = vmax.clone().requires_grad_()
    voltage_loss(v, iou, pos, "exp").backward()
    np.testing.assert_allclose(v.grad[:, 1], [-0.25, 0.0, 0.0, 0.25])
    assert float(v.grad[:, 0].abs().sum()) == 0.0
