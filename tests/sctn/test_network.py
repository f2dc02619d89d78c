"""SCTN as a whole: gradients reach the weights and time constants through the surrogate; the paper preset is
silent without events."""

import torch

from sctn.loss import voltage_loss
from sctn.network import SCTN

torch.set_num_threads(1)


def test_gradients_flow_through_the_surrogate_and_time_constants_learn():
    torch.manual_seed(0)
    net = SCTN()
    x = (torch.rand(4, 10, 2, 107, 107) < 0.05).float()
    net.calibrate(x)
    before = [p.detach().clone() for p in (net.neurons[0].p_m, net.neurons[4].p_s)]
    opt = torch.optim.SGD(net.parameters(), lr=0.5)
    vmax = net(x).max(dim=1).values
    loss = voltage_loss(vmax, torch.tensor([0.9, 0.8, 0.1, 0.2]), torch.tensor([True, True, False, False]))
    loss.backward()
    assert net.convs[0].weight.grad.abs().sum() > 0 and net.neurons[0].p_m.grad is not None
    opt.step()
    after = [net.neurons[0].p_m, net.neurons[4].p_s]
    assert any(not torch.equal(b, a) for b, a in zip(before, after))


def test_paper_preset_is_silent_without_events_and_has_ten_steps():
    torch.manual_seed(0)
    net = SCTN()
    assert net.cfg.steps == 10 and net.cfg.tail_steps == 0 and not net.cfg.bias
    assert all(layer.bias is None for layer in list(net.convs) + list(net.fcs))
    with torch.no_grad():
        for layer in list(net.convs) + list(net.fcs):
            layer.weight.mul_(50.0)  # weights strong enough to fire on any input at all
        volts, spikes = net.forward_record(torch.zeros(3, 10, 2, 107, 107))
        assert volts.shape == (3, 10, 2)
        assert all(float(s.abs().sum()) == 0.0 for s in spikes) and float(volts.abs().max()) == 0.0
        _, spikes = net.forward_record((torch.rand(3, 10, 2, 107, 107) < 0.02).float())
        assert float(spikes[1].sum()) > 0  # and they do fire once events arrive
