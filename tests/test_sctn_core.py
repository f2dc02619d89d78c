"""C-LIF neuron, network, encoding, loss and energy accounting against closed-form and hand-made cases."""

import math

import numpy as np
import pytest
import torch

from dvsot.events import EventBatch
from sctn.encoding import encode_boxes, encode_region
from sctn.energy import ann_macs, conv_fanout, count_search_ops, count_synaptic_ops, energy_pj
from sctn.loss import feedback, voltage_loss
from sctn.network import SCTN, NetworkConfig
from sctn.neurons import CLIF, psp_kernel

torch.set_num_threads(1)


def test_single_input_spike_gives_the_psp_kernel_with_peak_one_at_the_closed_form_time():
    neuron = CLIF(1, alpha_m=5.0, alpha_s=2.0)
    neuron.theta = 1e9  # never fires: pure PSP
    x = torch.zeros(20, 1, 1)
    x[3] = 1.0
    _, v = neuron(x)
    v = v[:, 0, 0].detach().double()
    a_m, a_s = (float(a.detach()) for a in neuron.time_constants())
    t_star = a_m * a_s / (a_m - a_s) * math.log(a_m / a_s)  # 3.054 ms
    k = torch.arange(1, 20 - 3 + 1, dtype=torch.float64)
    discrete = torch.exp(-k / a_m) - torch.exp(-k / a_s)
    np.testing.assert_allclose(v[3:], discrete / discrete.max(), atol=1e-6)
    assert v[:3].abs().max() == 0
    k_peak = int(torch.argmax(v)) - 3 + 1
    assert k_peak in (math.floor(t_star), math.ceil(t_star)) and float(v.max()) == pytest.approx(1.0, abs=1e-6)
    # the continuous kernel peaks at exactly 1 at t*
    assert float(psp_kernel(torch.tensor([t_star]), a_m, a_s)) == pytest.approx(1.0)
    assert float(psp_kernel(torch.tensor([t_star - 0.5, t_star + 0.5]), a_m, a_s).max()) < 1.0


def test_reset_kernel_after_an_output_spike():
    neuron = CLIF(1, alpha_m=5.0, alpha_s=2.0)
    a_m, _ = (float(a.detach()) for a in neuron.time_constants())
    x = torch.zeros(12, 1, 1)
    x[0] = 2.0  # strong input: one spike at the kernel's peak
    s, v = neuron(x)
    first = int(torch.nonzero(s[:, 0, 0])[0])
    _, v_free = CLIF(1, 5.0, 2.0, theta=1e9)(x)
    n = torch.arange(first + 1, 12)
    expected = v_free[first + 1:, 0, 0] - 0.5 * torch.exp(-(n - first) / a_m)
    # until a second spike, V = L - theta * exp(-(t - t_s) / a_m)
    second = [int(i) for i in torch.nonzero(s[first + 1:, 0, 0])[:, 0]]
    stop = first + 1 + (second[0] if second else len(n))
    np.testing.assert_allclose(v[first + 1:stop, 0, 0].detach(), expected[: stop - first - 1].detach(), atol=1e-6)


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


def test_loss_values_by_hand():
    iou = torch.tensor([0.8, 1.0, 0.3, 0.2])
    pos = torch.tensor([True, True, False, False])
    np.testing.assert_allclose(feedback(iou, pos, "exp"), [math.exp(4) / 100, math.exp(5) / 100, -0.3, -0.3], rtol=1e-6)
    np.testing.assert_allclose(feedback(iou, pos, "linear"), [0.7, 1.5, -0.3, -0.3], rtol=1e-6)
    np.testing.assert_allclose(feedback(iou, pos, "basic"), [1.0, 1.0, -0.3, -0.3])
    # target V_max: pos 0.5 (short by e^4/100), pos 3.0 (ok), neg 0.1 (ok), neg 0.6 (0.4 too high);
    # background V_max: pos 0.1 (ok), pos 0.5 (0.3 too high), neg 0.9 (ok), neg 0.6 (short by 0.2)
    vmax = torch.tensor([[0.1, 0.5], [0.5, 3.0], [0.9, 0.1], [0.6, 0.6]])
    expected = ((math.exp(4) / 100) ** 2 + 0.3 ** 2 + 0.4 ** 2 + 0.2 ** 2) / 4
    assert float(voltage_loss(vmax, iou, pos, "exp")) == pytest.approx(expected, rel=1e-5)


def test_encoding_places_events_at_the_right_pixel_step_and_channel():
    ev = EventBatch(np.array([50, 52, 10], np.uint16), np.array([40, 41, 10], np.uint16),
                    np.array([1_000, 3_500, 2_000]), np.array([1, 0, 1], np.uint8))
    x = encode_boxes(ev, 0, np.array([[40, 30, 20, 20], [0, 0, 400, 300]]), size=107, steps=10)
    assert x.shape == (2, 10, 2, 107, 107)
    # box 0 centred at (50, 40): pixel centre (50.5, 40.5) -> canvas (54, 54) at step 1, ON;
    # (52.5, 41.5) -> (56, 55) at step 3, OFF; (10, 10) is outside box 0
    assert x[0, 1, 1, 54, 54] == 1 and x[0, 3, 0, 55, 56] == 1 and x[0].sum() == 2
    # box 1 is 400 px wide: scaled by 107/400 around its centre (200, 150)
    u = int(np.floor((10.5 - 200) * 107 / 400 + 53.5))
    v = int(np.floor((10.5 - 150) * 107 / 400 + 53.5))
    assert x[1, 2, 1, v, u] == 1 and x[1].sum() == 3
    r = encode_region(ev, 0, np.array([0.0, 0.0]), 1.0, (60, 60))
    assert r[0, 1, 1, 40, 50] == 1 and r.sum() == 3


def test_fast_search_matches_per_candidate_evaluation_on_aligned_full_boxes():
    torch.manual_seed(1)
    net = SCTN()
    region = (torch.rand(1, 10, 2, 107 + 16, 107 + 16) < 0.05).float()
    net.calibrate(region[:, :, :, :107, :107])
    origins = torch.tensor([[0.0, 0.0], [8.0, 16.0]])
    boxes = torch.tensor([[0.0, 0.0, 107.0, 107.0], [8.0, 16.0, 107.0, 107.0]])
    fast = net.forward_search(region, origins, boxes)
    crops = torch.cat([region[:, :, :, 0:107, 0:107], region[:, :, :, 16:123, 8:115]])
    slow = net(crops)
    np.testing.assert_allclose(fast.detach(), slow.detach(), atol=1e-4)


def test_energy_counts_on_a_hand_made_spike_pattern():
    cfg = NetworkConfig(channels=(8, 16, 16), fc=(64, 32))
    net = SCTN(cfg)
    with torch.no_grad():  # silence everything after the input: only input spikes cost
        for layer in list(net.convs) + list(net.fcs):
            layer.weight.zero_()
    x = torch.zeros(1, 10, 2, 107, 107)
    x[0, 0, 0, 0, 0] = 1  # covered by one 4x4/stride-4 window: 8 synapses
    x[0, 5, 1, 50, 50] = 1  # idem
    x[0, 7, 1, 106, 106] = 1  # beyond the last window (104 = 26 * 4): drives nothing
    res = count_synaptic_ops(net, x)
    assert res["ac_ops_by_layer"]["input"] == 2 * 8 and res["ac_ops_per_sample"] == 16
    assert res["spikes_by_layer"]["input"] == 3 and res["spikes_by_layer"]["conv1"] == 0
    fan = conv_fanout(net.convs[1], (26, 26))
    # 3x3 stride 2: even interior pixels lie in 2x2 windows, odd ones in one
    assert fan[0, 0] == 16 and fan[2, 2] == 16 * 4 and fan[3, 3] == 16 and fan[2, 3] == 16 * 2
    macs = ann_macs(cfg)["mac_ops"]
    by_hand = 8 * 2 * 16 * 26 * 26 + 16 * 8 * 9 * 12 * 12 + 16 * 16 * 9 * 10 * 10 + 1600 * 64 + 64 * 32 + 32 * 2
    assert macs == by_hand
    assert energy_pj(10, 2)["energy_pj"] == pytest.approx(10 * 0.9 + 2 * 4.6)


def test_search_ops_of_one_aligned_candidate_equal_the_per_candidate_count():
    torch.manual_seed(2)
    net = SCTN()
    x = (torch.rand(1, 10, 2, 107, 107) < 0.05).float()
    net.calibrate(x)
    per = count_synaptic_ops(net, x)
    search = count_search_ops(net, x, torch.zeros(1, 2), torch.tensor([[0.0, 0.0, 107.0, 107.0]]))
    for layer in ("input", "conv1", "conv2", "fc1", "fc2"):
        assert search["ac_ops_by_layer"][layer] == pytest.approx(per["ac_ops_by_layer"][layer])
    # conv3's spikes reach fc1 as (here exact, integer-aligned) crops, counted as MACs
    assert per["ac_ops_by_layer"]["conv3"] > 0
    assert search["mac_ops"] == pytest.approx(per["ac_ops_by_layer"]["conv3"])
    assert search["energy_pj"] == pytest.approx(search["ac_ops"] * 0.9 + search["mac_ops"] * 4.6)
