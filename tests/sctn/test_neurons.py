"""The C-LIF neuron against closed forms: its PSP kernel and reset kernel; the inference path, the compiled
training path and the autograd loop agree."""

import math

import numpy as np
import pytest
import torch

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
