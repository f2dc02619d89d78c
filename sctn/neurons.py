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

import numba
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

    def _inference_constants(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(d_m, d_s, V0) per channel as float32 arrays for _infer, cached until the parameters change
        (tracking calls every layer once per segment with the same weights; fine-tuning updates them in place)."""
        key = (self.p_m.data_ptr(), self.p_m._version, self.p_s.data_ptr(), self.p_s._version)
        if getattr(self, "_cache_key", None) != key:
            self._cache = tuple(np.ascontiguousarray(a.detach().numpy(), np.float32) for a in self._constants((-1,)))
            self._cache_key = key
        return self._cache

    def forward(self, current: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Spikes and voltages (both (T, B, C, ...)) for input currents (T, B, C, ...)."""
        if not (torch.is_grad_enabled() and (current.requires_grad or self.p_m.requires_grad)):
            with torch.no_grad():
                return self._infer(current, *self._inference_constants())
        d_m, d_s, v0 = self._constants((-1,) + (1,) * (current.dim() - 3))
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

    def _infer(self, current: torch.Tensor, d_m: np.ndarray, d_s: np.ndarray,
               v0: np.ndarray) -> tuple[torch.Tensor, torch.Tensor]:
        """The same recurrence without autograd, compiled (tracking's hot path): see _clif_steps."""
        t, b, c = current.shape[:3]
        cur = current.detach().contiguous().reshape(t, b, -1).numpy()
        per = cur.shape[2] // c  # neurons per channel (pixels of a feature map, 1 in a linear layer)
        volts = np.empty(cur.shape, np.float32)
        fired = np.empty(cur.shape, np.bool_)
        _clif_steps(cur, np.repeat(d_m, per), np.repeat(d_s, per), np.repeat(v0, per), np.float32(self.theta),
                    volts, fired)
        return (torch.from_numpy(fired.astype(np.float32)).view(current.shape),
                torch.from_numpy(volts).view(current.shape))


@numba.njit(cache=True)
def _clif_steps(cur: np.ndarray, d_m: np.ndarray, d_s: np.ndarray, v0: np.ndarray, theta: np.float32,
                volts: np.ndarray, fired: np.ndarray) -> None:  # pragma: no cover - compiled
    """C-LIF over currents (T, B, M) into volts and fired; d_m, d_s, V0 per neuron (M,).

    m and the reset r decay alike, so u = V0 m - theta r obeys u[n] = d_m (u[n-1] + V0 I[n] -
    theta S[n-1]); with w = V0 s, V = u - w. Two numbers of state per neuron; steps outermost and
    neurons innermost, so memory is read in order and the inner loop vectorises.
    """
    steps, batch, neurons = cur.shape
    u = np.zeros((batch, neurons), np.float32)
    w = np.zeros((batch, neurons), np.float32)
    reset = np.zeros((batch, neurons), np.float32)  # theta S[n-1]
    for n in range(steps):
        for i in range(batch):
            for j in range(neurons):
                x = cur[n, i, j] * v0[j]
                un = (u[i, j] + x - reset[i, j]) * d_m[j]
                wn = (w[i, j] + x) * d_s[j]
                u[i, j] = un
                w[i, j] = wn
                v = un - wn
                volts[n, i, j] = v
                spike = v >= theta
                fired[n, i, j] = spike
                reset[i, j] = theta * spike
