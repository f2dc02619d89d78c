"""C-LIF neurons (paper eq. 1-4) in discrete time with a 1 ms step, and the STCA-style surrogate gradient.

Continuous model: V(t) = L(t) - E(t), with the synaptic drive L(t) = sum_i w_i sum_j K(t - t_i^j),
K(t) = V0 [exp(-t/a_m) - exp(-t/a_s)] (a_m > a_s, V0 normalises the kernel's peak to 1), and the
reset E(t) = theta * sum_{t_s < t} exp(-(t - t_s)/a_m) after each output spike t_s.

Discrete update (step n = 1 ms, d_m = exp(-1/a_m), d_s = exp(-1/a_s); the input of step n arrives
at the start of the step and V is read at its end, so an input at step n0 contributes K(n - n0 + 1)):

    m[n] = d_m (m[n-1] + I[n])          I[n] = sum_i w_i x_i[n]   (weighted input spikes)
    s[n] = d_s (s[n-1] + I[n])
    L[n] = V0 (m[n] - s[n])             = sum over inputs of V0 (d_m^k - d_s^k), k = n - n0 + 1
    r[n] = d_m (r[n-1] + S[n-1])        = sum over output spikes of exp(-(n - n_s)/a_m)
    V[n] = L[n] - theta r[n]
    S[n] = H(V[n] - theta)

V0 = 1 / max_k (d_m^k - d_s^k) over integer k >= 1: the peak of the discrete kernel is exactly 1, at
k* = floor or ceil of t* = a_m a_s / (a_m - a_s) ln(a_m / a_s), the continuous peak time.

a_m and a_s are learnable per channel: a_s = 1 + softplus(p_s), a_m = a_s + 0.05 + softplus(p_m),
so a_m > a_s always and V0 stays finite. The spike's gradient is STCA's rectangular surrogate:
dS/dV = 1/width where |V - theta| < width/2, else 0.
"""

from __future__ import annotations

import math

import numpy as np
import torch
from torch import nn
from torch.nn import functional as F

THETA = 0.5


class RectSurrogate(torch.autograd.Function):
    """Heaviside spike forward; rectangular window of width `width` around the threshold backward."""

    @staticmethod
    def forward(ctx, v_minus_theta: torch.Tensor, width: float) -> torch.Tensor:  # type: ignore[override]
        ctx.save_for_backward(v_minus_theta)
        ctx.width = width
        return (v_minus_theta >= 0).to(v_minus_theta.dtype)

    @staticmethod
    def backward(ctx, grad: torch.Tensor):  # type: ignore[override]
        (v,) = ctx.saved_tensors
        window = (v.abs() < ctx.width / 2).to(grad.dtype) / ctx.width
        return grad * window, None


def _inverse_softplus(y: float) -> float:
    return math.log(math.expm1(y))


def kernel_norm(d_m: torch.Tensor, d_s: torch.Tensor, a_m: torch.Tensor, a_s: torch.Tensor) -> torch.Tensor:
    """V0: one over the peak of the discrete kernel d_m^k - d_s^k, k >= 1 integer (differentiable in the decays)."""
    t_star = a_m * a_s / (a_m - a_s) * torch.log(a_m / a_s)
    k_lo = torch.clamp(torch.floor(t_star), min=1.0).detach()
    k_hi = (k_lo + 1.0).detach()
    peak = torch.maximum(d_m ** k_lo - d_s ** k_lo, d_m ** k_hi - d_s ** k_hi)
    return 1.0 / peak


def psp_kernel(t_ms: torch.Tensor, alpha_m: float, alpha_s: float) -> torch.Tensor:
    """Continuous PSP kernel K(t) (eq. 4), normalised so its peak is 1; t in milliseconds."""
    t_star = alpha_m * alpha_s / (alpha_m - alpha_s) * math.log(alpha_m / alpha_s)
    v0 = 1.0 / (math.exp(-t_star / alpha_m) - math.exp(-t_star / alpha_s))
    t = torch.as_tensor(t_ms, dtype=torch.float64)
    return torch.where(t >= 0, v0 * (torch.exp(-t / alpha_m) - torch.exp(-t / alpha_s)), torch.zeros_like(t))


class CLIF(nn.Module):
    """A layer of C-LIF neurons with learnable per-channel time constants (ms); input (T, B, C, ...) currents."""

    def __init__(self, channels: int, alpha_m: float = 4.0, alpha_s: float = 1.5, theta: float = THETA,
                 surrogate_width: float = 1.0) -> None:
        super().__init__()
        if not alpha_m > alpha_s + 0.05 or alpha_s <= 1.0:
            raise ValueError("need alpha_m > alpha_s + 0.05 and alpha_s > 1 (ms)")
        self.theta = theta
        self.surrogate_width = surrogate_width
        self.p_s = nn.Parameter(torch.full((channels,), _inverse_softplus(alpha_s - 1.0)))
        self.p_m = nn.Parameter(torch.full((channels,), _inverse_softplus(alpha_m - alpha_s - 0.05)))

    def time_constants(self) -> tuple[torch.Tensor, torch.Tensor]:
        """(alpha_m, alpha_s) per channel, milliseconds."""
        a_s = 1.0 + F.softplus(self.p_s)
        return a_s + 0.05 + F.softplus(self.p_m), a_s

    def _constants(self, shape: tuple[int, ...]) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(d_m, d_s, V0) per channel, viewed to `shape`."""
        a_m, a_s = self.time_constants()
        d_m, d_s = torch.exp(-1.0 / a_m), torch.exp(-1.0 / a_s)
        return d_m.view(shape), d_s.view(shape), kernel_norm(d_m, d_s, a_m, a_s).view(shape)

    def _inference_constants(self, shape: tuple[int, ...]) -> tuple[torch.Tensor, np.ndarray]:
        """V0 and the stacked decays (d_m, d_s) for _infer, cached until the parameters change (tracking
        calls every layer once per segment with the same weights; fine-tuning updates them in place)."""
        key = (shape, self.p_m.data_ptr(), self.p_m._version, self.p_s.data_ptr(), self.p_s._version)
        if getattr(self, "_cache_key", None) != key:
            d_m, d_s, v0 = self._constants(shape)
            self._cache = (v0, torch.stack([d_m.expand_as(d_s), d_s])[:, None].numpy())
            self._cache_key = key
        return self._cache

    def forward(self, current: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Spikes and voltages (both (T, B, C, ...)) for input currents (T, B, C, ...)."""
        shape = (-1,) + (1,) * (current.dim() - 3)
        if not (torch.is_grad_enabled() and (current.requires_grad or self.p_m.requires_grad)):
            with torch.no_grad():
                return self._infer(current, *self._inference_constants(shape))
        d_m, d_s, v0 = self._constants(shape)
        m = torch.zeros_like(current[0])
        s = torch.zeros_like(current[0])
        r = torch.zeros_like(current[0])
        spike = torch.zeros_like(current[0])
        spikes, volts = [], []
        for n in range(current.shape[0]):
            m = d_m * (m + current[n])
            s = d_s * (s + current[n])
            r = d_m * (r + spike)
            v = v0 * (m - s) - self.theta * r
            spike = RectSurrogate.apply(v - self.theta, self.surrogate_width)
            spikes.append(spike)
            volts.append(v)
        return torch.stack(spikes), torch.stack(volts)

    def _infer(self, current: torch.Tensor, v0: torch.Tensor, decay: np.ndarray) -> tuple[torch.Tensor, torch.Tensor]:
        """The same recurrence without autograd, fused for speed (tracking's hot path).

        m and the reset r decay alike, so u = V0 m - theta r obeys u[n] = d_m (u[n-1] + V0 I[n] -
        theta S[n-1]) and V = u - V0 s: with V0 folded into the input once, the state is one stacked
        (2, ...) array with four in-place updates per step. The loop runs in numpy on the tensors'
        memory: tracking's layers are small, and numpy's per-call cost is a fraction of torch's.
        """
        cur = (current * v0).numpy()
        volts = np.empty(cur.shape, np.float32)
        fired = np.empty(cur.shape, bool)
        us = np.zeros((2,) + cur.shape[1:], np.float32)  # us[0] = u, us[1] = V0 s
        u, s = us
        for n in range(cur.shape[0]):
            us += cur[n]
            if n:
                np.subtract(u, self.theta, out=u, where=fired[n - 1])
            us *= decay
            np.subtract(u, s, out=volts[n])
            np.greater_equal(volts[n], self.theta, out=fired[n])
        return torch.from_numpy(fired.astype(np.float32)), torch.from_numpy(volts)
