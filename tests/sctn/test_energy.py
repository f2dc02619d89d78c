"""Energy accounting on hand-made cases: synaptic operations per layer, the fast mode's operations, per-candidate
counts and bias additions."""

import numpy as np
import pytest
import torch

from dvsot.events import EventBatch
from sctn.encoding import encode_boxes
from sctn.energy import conv_fanout, count_search_ops, count_synaptic_ops, energy_pj
from sctn.network import SCTN, NetworkConfig

torch.set_num_threads(1)


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
    # conv3's spikes reach fc1 through the crops, once per distinct crop: here the one aligned crop
    assert per["ac_ops_by_layer"]["conv3"] > 0
    assert search["ac_ops_by_layer"]["conv3"] == pytest.approx(per["ac_ops_by_layer"]["conv3"])
    assert search["mac_ops"] == 0 and search["crops_evaluated"] == 1
    # half a cell off, a bilinear crop mixes fc1's sums over the four crops around it: MACs on top
    region = torch.nn.functional.pad(x, (0, 8, 0, 8))
    shifted = count_search_ops(net, region, torch.tensor([[4.0, 4.0]]), torch.tensor([[4.0, 4.0, 107.0, 107.0]]),
                               crop="bilinear")
    steps_with_conv3_spikes = int((net.forward_search(region, torch.tensor([[4.0, 4.0]]), torch.tensor(
        [[4.0, 4.0, 107.0, 107.0]]), record=True)[1]["conv3"].flatten(1).sum(1) > 0).sum())
    assert shifted["crops_evaluated"] == 4 and shifted["mac_ops"] == 4 * 64 * steps_with_conv3_spikes > 0
    assert shifted["energy_pj"] == pytest.approx(shifted["ac_ops"] * 0.9 + shifted["mac_ops"] * 4.6)


def test_per_candidate_energy_counts_every_candidates_own_spikes_and_biases_apart():
    from sctn.energy import bias_additions
    from sctn.sparse.evaluate import candidate_ops

    torch.manual_seed(1)
    rng = np.random.default_rng(1)
    net = SCTN()
    with torch.no_grad():
        for layer in list(net.convs) + list(net.fcs):
            layer.weight.mul_(6.0)
    n = 3000
    ev = EventBatch(rng.integers(60, 140, n).astype(np.uint16), rng.integers(40, 120, n).astype(np.uint16),
                    np.sort(rng.integers(0, 10_000, n)).astype(np.int64), rng.integers(0, 2, n).astype(np.uint8))
    boxes = np.array([[70.0, 50, 50, 40], [90, 60, 30, 30], [60, 40, 80, 80], [300, 200, 20, 20]])
    dense = sum(count_synaptic_ops(net, encode_boxes(ev, 0, b[None]))["ac_ops_per_sample"] for b in boxes)
    assert dense > 0 and candidate_ops(net, ev, 0, boxes) == pytest.approx(dense, rel=1e-6)
    assert bias_additions(net) == 0.0
    biased = SCTN(NetworkConfig(bias=True, tail_steps=2))
    per_step = 8 * 26 * 26 + 16 * 12 * 12 + 16 * 10 * 10 + 64 + 32 + 2
    assert bias_additions(biased) == per_step * 12
