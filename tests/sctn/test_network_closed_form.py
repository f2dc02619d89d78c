"""C-LIF neuron, network, encoding, loss and energy accounting against closed-form and hand-made cases."""

import math

import numpy as np
import pytest
import torch

from dvsot.events import EventBatch
from sctn.encoding import encode_boxes, encode_region
from sctn.energy import conv_fanout, count_search_ops, count_synaptic_ops, energy_pj
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


def test_inference_path_equals_the_training_recurrence_and_follows_parameter_changes():
    torch.manual_seed(0)
    neuron = CLIF(3, alpha_m=5.0, alpha_s=2.0)
    x = torch.rand(12, 4, 3, 5, 5) * 0.6  # (T, B, C, H, W): many spikes and resets
    s_train, v_train = neuron(x)
    with torch.no_grad():
        s_fast, v_fast = neuron(x)
    assert s_train.sum() > 20 and torch.equal(s_train, s_fast)
    np.testing.assert_allclose(v_fast, v_train.detach(), atol=1e-5)
    with torch.no_grad():
        neuron.p_m.add_(0.5)  # the cached decays must follow an in-place update (fine-tuning does that)
        s_new, v_new = neuron(x)
    s_ref, v_ref = neuron(x)
    assert torch.equal(s_new, s_ref) and not torch.equal(v_new, v_fast)
    np.testing.assert_allclose(v_new, v_ref.detach(), atol=1e-5)


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
@pytest.mark.parametrize("grads", ["spikes and volts", "volts", "spikes"])
def test_compiled_training_path_equals_the_autograd_loop(dtype, grads):
    torch.manual_seed(1)
    neuron = CLIF(3, alpha_m=5.0, alpha_s=2.0).to(dtype)
    x = (torch.rand(12, 4, 3, 5, 5, dtype=dtype) * 0.6).requires_grad_()
    g_s, g_v = torch.randn(2, 12, 4, 3, 5, 5, dtype=dtype)
    results = []
    for forward in (neuron.forward, neuron._forward_reference):
        neuron.zero_grad()
        x.grad = None
        s, v = forward(x)
        loss = {"spikes and volts": (s * g_s).sum() + (v * g_v).sum(), "volts": (v * g_v).sum(),
                "spikes": (s * g_s).sum()}[grads]
        loss.backward()
        results.append((s.detach(), v.detach(), x.grad, neuron.p_m.grad, neuron.p_s.grad))
    (s, v, g_x, g_pm, g_ps), (s_ref, v_ref, g_x_ref, g_pm_ref, g_ps_ref) = results
    assert s.sum() > 100 and g_x_ref.abs().sum() > 0 and g_pm_ref.abs().sum() > 0
    # same operations in the same order: outputs and the current's gradient bit for bit
    assert torch.equal(s, s_ref) and torch.equal(v, v_ref) and torch.equal(g_x, g_x_ref)
    # the time constants' gradients are the same sums in another order (float64 accumulators)
    rtol = 1e-5 if dtype == torch.float32 else 1e-12
    np.testing.assert_allclose(g_pm, g_pm_ref, rtol=rtol, atol=rtol * float(g_pm_ref.abs().max()))
    np.testing.assert_allclose(g_ps, g_ps_ref, rtol=rtol, atol=rtol * float(g_ps_ref.abs().max()))


def test_compiled_training_path_tiles_wide_layers():
    from sctn.neurons import BLOCK

    torch.manual_seed(2)
    neuron = CLIF(2, alpha_m=4.0, alpha_s=1.5)
    x = (torch.rand(6, 2, 2, BLOCK + 37, dtype=torch.float32) * 0.7).requires_grad_()  # a tile and a remainder
    g_v = torch.randn(6, 2, 2, BLOCK + 37)
    grads = []
    for forward in (neuron.forward, neuron._forward_reference):
        x.grad = None
        s, v = forward(x)
        ((s + v * g_v).sum()).backward()
        grads.append((s.detach(), x.grad))
    assert torch.equal(grads[0][0], grads[1][0]) and torch.equal(grads[0][1], grads[1][1])


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


def test_encoding_places_events_at_the_right_pixel_step_and_channel():
    ev = EventBatch(np.array([50, 52, 10], np.uint16), np.array([40, 41, 10], np.uint16),
                    np.array([1_000, 3_500, 2_000]), np.array([1, 0, 1], np.uint8))
    x = encode_boxes(ev, 0, np.array([[40, 30, 20, 20], [0, 0, 400, 300]]), NetworkConfig(input_size=107, steps=10))
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


def _search_reference(net: SCTN, feat: torch.Tensor, origins: torch.Tensor, boxes: torch.Tensor) -> tuple:
    """fc1 inputs and output voltages of candidates whose canvases start at the nearest cell, computed one by one."""
    n_cells = net.cfg.conv_sizes()[-1]
    stride, rf = net.receptive_field()
    inputs = []
    for (ox, oy), (bx, by, bw, bh) in zip(origins.tolist(), boxes.tolist()):
        cx, cy = round(ox / stride), round(oy / stride)
        crop = feat[:, :, cy:cy + n_cells, cx:cx + n_cells].clone()
        centre = torch.arange(n_cells) * stride + rf / 2
        keep_x = (ox + centre >= bx) & (ox + centre < bx + bw)
        keep_y = (oy + centre >= by) & (oy + centre < by + bh)
        crop *= (keep_y[:, None] & keep_x[None, :]).float()
        inputs.append(crop.flatten(1))
    h = torch.stack(inputs, dim=1)  # (T, N, C * cells * cells): the full fc1 input, masked per box
    with torch.no_grad():
        for fc, neuron in zip(net.fcs, net.neurons[3:]):
            h, v = neuron(fc(h))
    return torch.stack(inputs, dim=1), v.transpose(0, 1)


def _small_calibrated_net(seed: int) -> tuple[SCTN, torch.Tensor]:
    torch.manual_seed(seed)
    net = SCTN(NetworkConfig(channels=(4, 8, 4), fc=(16, 8)))
    region = (torch.rand(1, 10, 2, 107 + 16, 107 + 16) < 0.08).float()
    net.calibrate(region[:, :, :, :107, :107])
    with torch.no_grad():  # masked crops get less input than the calibration's full canvas
        for fc in net.fcs:
            fc.weight.mul_(4.0)
    return net, region


def test_fast_search_masks_cells_outside_each_box_and_leaves_out_cells_no_box_keeps():
    net, region = _small_calibrated_net(2)
    # aligned canvases (integer cells), boxes of different sizes: different masks, none the full canvas
    origins = torch.tensor([[0.0, 0.0], [8.0, 16.0], [16.0, 8.0]])
    boxes = torch.tensor([[30.0, 35.0, 40.0, 30.0], [8 + 20.0, 16 + 25.0, 60.0, 50.0], [16 + 40.0, 8 + 40.0, 20.0, 20.0]])
    for crop in ("nearest", "bilinear"):  # aligned: both crops are the same cells
        with torch.no_grad():
            v_fast, rec = net.forward_search(region, origins, boxes, record=True, crop=crop)
        inputs, v = _search_reference(net, rec["conv3"][:, 0], origins, boxes)
        assert float(v.abs().max()) > 0.05  # the output neurons do receive input
        np.testing.assert_allclose(v_fast, v, atol=1e-5)
        assert rec["crops"].shape[2] < net.cfg.channels[-1] * net.cfg.conv_sizes()[-1] ** 2  # masked for all: out
        assert torch.equal(rec["crops"].sum(dim=2), inputs.sum(dim=2))


def test_nearest_crops_snap_to_the_cell_and_evaluate_each_distinct_crop_once():
    net, region = _small_calibrated_net(3)
    gen = torch.Generator().manual_seed(0)
    origins = torch.rand(40, 2, generator=gen) * 16  # sub-cell offsets: several candidates share a cell
    sizes = 40 + 30 * torch.rand(40, 2, generator=gen)
    boxes = torch.cat([origins + 53.5 - sizes / 2, sizes], dim=1)
    with torch.no_grad():
        v_fast, rec = net.forward_search(region, origins, boxes, record=True, crop="nearest")
        v_bilinear = net.forward_search(region, origins, boxes, crop="bilinear")
    _, v = _search_reference(net, rec["conv3"][:, 0], origins, boxes)
    np.testing.assert_allclose(v_fast, v, atol=1e-5)
    assert rec["crops"].shape[1] < 40  # fewer distinct crops than candidates were evaluated
    assert not torch.allclose(v_bilinear, v_fast, atol=1e-3)  # bilinear crops are a different sampling


def test_bilinear_crops_equal_grid_sampling_of_the_spike_map():
    net, region = _small_calibrated_net(4)
    gen = torch.Generator().manual_seed(1)
    origins = torch.rand(30, 2, generator=gen) * 16
    sizes = 40 + 50 * torch.rand(30, 2, generator=gen)
    boxes = torch.cat([origins + 53.5 - sizes / 2, sizes], dim=1)
    with torch.no_grad():
        v_fast, rec = net.forward_search(region, origins, boxes, record=True, crop="bilinear")
        feat = rec["conv3"][:, 0]  # (T, C, fh, fw)
        n_cells = net.cfg.conv_sizes()[-1]
        stride, rf = net.receptive_field()
        fh, fw = feat.shape[2:]
        cell = torch.arange(n_cells, dtype=torch.float32)
        gx = (origins[:, 0:1] / stride + cell) / (fw - 1) * 2 - 1
        gy = (origins[:, 1:2] / stride + cell) / (fh - 1) * 2 - 1
        centre = stride * cell + rf / 2
        keep_x = (origins[:, 0:1] + centre >= boxes[:, 0:1]) & (origins[:, 0:1] + centre < boxes[:, 0:1] + boxes[:, 2:3])
        keep_y = (origins[:, 1:2] + centre >= boxes[:, 1:2]) & (origins[:, 1:2] + centre < boxes[:, 1:2] + boxes[:, 3:4])
        grid = torch.stack([gx[:, None, :].expand(30, n_cells, n_cells), gy[:, :, None].expand(30, n_cells, n_cells)], -1)
        sampled = torch.stack([torch.nn.functional.grid_sample(f[None].expand(30, -1, -1, -1), grid, align_corners=True)
                               for f in feat])  # (T, N, C, cells, cells)
        h = (sampled * (keep_y[:, :, None] & keep_x[:, None, :])[None, :, None]).flatten(2)
        for fc, neuron in zip(net.fcs, net.neurons[3:]):
            h, v = neuron(fc(h))
    np.testing.assert_allclose(v_fast, v.transpose(0, 1), atol=1e-4)
    assert rec["mix_macs"] > 0


def test_search_region_covers_what_the_kept_cells_see():
    from sctn.encoding import encode_search
    from sctn.samples import TRACK, propose

    net, _ = _small_calibrated_net(5)
    rng = np.random.default_rng(0)
    n_ev = 4000
    ev = EventBatch(rng.integers(0, 320, n_ev).astype(np.uint16), rng.integers(0, 240, n_ev).astype(np.uint16),
                    np.sort(rng.integers(0, 10_000, n_ev)), rng.integers(0, 2, n_ev).astype(np.uint8))
    for ref in (np.array([140.0, 100.0, 30.0, 40.0]), np.array([100.0, 60.0, 150.0, 120.0])):  # scale 1 and < 1
        boxes = propose(rng, ref, 64, "gaussian", TRACK.trans, TRACK.scale, (320, 240))
        tail2 = net.cfg.model_copy(update={"tail_steps": 2})
        region, origins, rboxes = encode_search(ev, 0, boxes, ref, tail2)
        scale = min(1.0, 107 / ref[2:].max())
        corner = boxes[0, :2] - rboxes[0, :2].numpy() / scale
        canvases = (np.ptp(boxes[:, 0]) * scale + 107) * (np.ptp(boxes[:, 1]) * scale + 107)
        if ref[2] < 50:  # a small box: its region is well inside the union of the canvases
            assert region.shape[-1] * region.shape[-2] < 0.85 * canvases
        # the same search on a region 3 cells larger on every side (the whole canvases and more)
        pad = 3 * 8
        big = encode_region(ev, 0, corner - pad / scale, scale, (region.shape[-2] + 2 * pad, region.shape[-1] + 2 * pad),
                            tail2)
        for crop in ("nearest", "bilinear"):
            with torch.no_grad():
                v = net.forward_search(region, origins, rboxes, crop=crop)
                v_big = net.forward_search(big, origins + pad, rboxes + torch.tensor([pad, pad, 0, 0]), crop=crop)
            np.testing.assert_allclose(v, v_big, atol=1e-5)


def test_event_driven_fc1_sums_equal_the_dense_product():
    net, region = _small_calibrated_net(6)
    gen = torch.Generator().manual_seed(2)
    origins = torch.rand(50, 2, generator=gen) * 16 - 4  # some canvases start left of / above the region
    sizes = 30 + 60 * torch.rand(50, 2, generator=gen)
    boxes = torch.cat([origins + 53.5 - sizes / 2, sizes], dim=1)
    for crop in ("nearest", "bilinear"):
        with torch.no_grad():
            v_sparse = net.forward_search(region, origins, boxes, crop=crop)  # inference: spike_sums
            v_dense, _ = net.forward_search(region, origins, boxes, crop=crop, record=True)  # gathered crops x W
        assert float(v_dense.abs().max()) > 0.05
        np.testing.assert_allclose(v_sparse, v_dense, atol=1e-5)


def test_window_sums_add_the_weights_of_the_spikes_inside_each_kept_window():
    from sctn.sparse.spike_sums import window_sums

    spikes = np.zeros((2, 4, 5, 3), np.uint8)  # (T, H, W, C)
    spikes[0, 1, 2, 0] = spikes[0, 1, 2, 2] = 1  # two channels of one cell
    spikes[0, 3, 4, 1] = 1
    spikes[1, 0, 0, 1] = 1
    weights = np.arange(3 * 3 * 3 * 2, dtype=np.float32).reshape(3, 3, 3, 2)  # (row, col, channel, out)
    crops = np.array([[1, 0, 0, 3, 0, 3],   # map cells x 1..3, y 0..2: holds (y1, x2) at crop (r1, q1)
                      [2, 1, 1, 2, 0, 3],   # columns 1..2 kept (x 3..4): (y1, x2) masked, (y3, x4) at (r2, q2)
                      [-1, -1, 0, 3, 0, 3]])  # reaches outside the map: (y0, x0) at (r1, q1)
    out = window_sums(spikes, weights, crops)
    np.testing.assert_array_equal(out[0, 0], weights[1, 1, 0] + weights[1, 1, 2])
    np.testing.assert_array_equal(out[0, 1], weights[2, 2, 1])
    np.testing.assert_array_equal(out[1, 2], weights[1, 1, 1])
    assert not out[1, :2].any() and not out[0, 2].any()


def test_mix_corners_weights_each_candidates_corner_sums():
    from sctn.sparse.spike_sums import mix_corners

    sums = np.arange(2 * 3 * 2, dtype=np.float32).reshape(2, 3, 2)  # (T, U, width)
    slots = np.array([[0, 2, 0, 0], [1, 1, 2, 0]])
    weights = np.array([[0.25, 0.75, 0.0, 0.0], [0.5, 0.25, 0.25, 0.0]], np.float32)
    out = mix_corners(sums, slots, weights)
    expect = np.einsum("nk,tnkw->tnw", weights, sums[:, slots])
    np.testing.assert_allclose(out, expect, rtol=1e-6)


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


def test_legacy_checkpoint_loads_with_a_note_naming_the_file(tmp_path):
    from sctn.checkpoint import LegacyLayoutWarning, load_checkpoint, save_checkpoint

    old = SCTN(NetworkConfig(bias=True, tail_steps=2))
    path = save_checkpoint(tmp_path / "old.pt", old, {})
    blob = torch.load(path, weights_only=True)
    del blob["config"]["bias"]  # as written before the bias became a setting
    torch.save(blob, path)
    with pytest.warns(LegacyLayoutWarning, match=r"old\.pt: not the paper preset: layers with biases.*2 empty tail"):
        model, _ = load_checkpoint(path)
    assert model.cfg.bias and model.cfg.tail_steps == 2
    save_checkpoint(tmp_path / "new.pt", SCTN(), {})
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        load_checkpoint(tmp_path / "new.pt")


def test_candidates_are_fixed_per_location_whatever_came_before():
    from sctn.tracker import SCTNTracker

    tracker = SCTNTracker(SCTN(), seed=4, finetune_iters=0)
    empty = EventBatch.empty()
    tracker.init(empty, 0, np.array([100.0, 80.0, 40.0, 30.0]), 320, 240)
    first = tracker.candidates()
    tracker.track(empty, 0)
    tracker.track(empty, 10_000)
    tracker.box, tracker.trans = np.array([100.2, 79.9, 40.0, 30.1]), tracker.trans0  # back at the same pixel box
    again = tracker.candidates()  # the same draws around a box 0.2 px away
    np.testing.assert_allclose(again[:, :2], first[:, :2], atol=0.5)
    np.testing.assert_allclose(again[:, 2:], first[:, 2:], rtol=0.01)
    tracker.box = np.array([101.0, 80.0, 40.0, 30.0])  # another location: other draws
    assert not np.allclose(tracker.candidates()[:, 2:], first[:, 2:], rtol=0.01)


def test_per_candidate_energy_counts_every_candidates_own_spikes_and_biases_apart():
    from sctn.energy import bias_additions, candidate_ops

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


def test_shipped_checkpoint_is_the_paper_preset_and_silent_on_an_empty_input():
    import warnings

    from sctn.checkpoint import load_checkpoint

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        model, meta = load_checkpoint(None)
    # no legacy-layout note; one line saying it was trained with the old error-time rule (no error_time recorded)
    assert [type(w.message).__name__ for w in caught] == ["TrainingRuleWarning"]
    assert "sctn_dvsot21.pt: trained with the old error-time rule" in str(caught[0].message)
    assert "\n" not in str(caught[0].message)
    assert model.cfg.steps == 10 and model.cfg.tail_steps == 0 and not model.cfg.bias
    cfg = meta["train_config"]
    assert cfg["loss"] == "exp" and not cfg["squared_error"] and not cfg["background_term"]
    assert cfg["ops_penalty"] == 0 and not cfg["calibrate"]
    with torch.no_grad():
        volts, spikes = model.forward_record(torch.zeros(2, 10, 2, 107, 107))
    assert [float(s.sum()) for s in spikes] == [0.0] * 7 and float(volts.abs().max()) == 0.0
