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

Training runs the recurrence compiled (CLIFFunction), with its adjoint in reverse time; with
a_X = dLoss/dX, g_X the gradient arriving from the layer's outputs and H' the surrogate:

    a_S[n] = g_S[n] + d_m a_r[n+1]              (S[n] enters r[n+1])
    a_V[n] = g_V[n] + H'(V[n]) a_S[n]
    a_m[n] = V0 a_V[n] + d_m a_m[n+1],  a_s[n] = -V0 a_V[n] + d_s a_s[n+1],  a_r[n] = -theta a_V[n] + d_m a_r[n+1]
    dLoss/dI[n] = d_m a_m[n] + d_s a_s[n]
    dLoss/dd_m += a_m[n] (m[n-1] + I[n]) + a_r[n] (r[n-1] + S[n-1]),  dLoss/dd_s += a_s[n] (s[n-1] + I[n]),
    dLoss/dV0 += a_V[n] (m[n] - s[n])

The backward pass recomputes the states instead of storing them; autograd carries d_m, d_s, V0 on
to the time constants. A test holds it equal to the loop of torch ops (CLIF._forward_reference).
"""

from __future__ import annotations

import math

import numba
import numpy as np
import torch
from torch import nn
from torch.nn import functional as F

THETA = 0.5  # firing threshold (the paper's, every layer)
ALPHA_M, ALPHA_S = 4.0, 1.5  # default membrane and synaptic time constants (ms), learnable per channel


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


class CLIFFunction(torch.autograd.Function):
    """C-LIF over currents (T, B, C, ...) with per-channel (C,) d_m, d_s, V0: compiled forward and adjoint backward.

    Same arithmetic, in the same order, as CLIF._forward_reference, so spikes, voltages and the
    current's gradient are bit-identical to that loop under autograd; the gradients of d_m, d_s and
    V0 are its sums in another order (float64 accumulators).
    """

    @staticmethod
    def forward(ctx, current: torch.Tensor, d_m: torch.Tensor, d_s: torch.Tensor, v0: torch.Tensor,  # type: ignore[override]
                theta: float, width: float) -> tuple[torch.Tensor, torch.Tensor]:
        t, b, c = current.shape[:3]
        cur = current.detach().contiguous().reshape(t, b, -1).numpy()
        per = cur.shape[2] // c  # neurons per channel (pixels of a feature map, 1 in a linear layer)
        dtype = cur.dtype.type
        consts = tuple(np.ascontiguousarray(np.repeat(a.detach().numpy().astype(dtype, copy=False), per))
                       for a in (d_m, d_s, v0))
        spikes, volts = np.empty(cur.shape, dtype), np.empty(cur.shape, dtype)
        _clif_train_forward(cur, *consts, dtype(theta), spikes, volts)
        ctx.save_for_backward(current)
        ctx.consts = consts
        ctx.theta, ctx.width, ctx.shape, ctx.param_dtype = theta, width, current.shape, d_m.dtype
        ctx.set_materialize_grads(False)  # hidden layers' voltages and the last layer's spikes get no gradient
        return torch.from_numpy(spikes).view(current.shape), torch.from_numpy(volts).view(current.shape)

    @staticmethod
    @torch.autograd.function.once_differentiable
    def backward(ctx, grad_spikes: torch.Tensor | None, grad_volts: torch.Tensor | None):  # type: ignore[override]
        (current,) = ctx.saved_tensors
        consts = ctx.consts
        cur = current.detach().contiguous().reshape(current.shape[0], current.shape[1], -1).numpy()
        shape = cur.shape
        dtype = cur.dtype.type
        none = np.zeros((1, 1, 1), dtype)

        def as_array(g: torch.Tensor | None) -> np.ndarray:
            return none if g is None else np.ascontiguousarray(g.detach().reshape(shape).numpy(), dtype)

        g_cur = np.empty(shape, dtype)
        g_consts = np.zeros((3, shape[2]), np.float64)  # per neuron: d_m, d_s, V0
        _clif_train_backward(cur, as_array(grad_spikes), grad_spikes is not None, as_array(grad_volts),
                             grad_volts is not None, *consts, dtype(ctx.theta),
                             dtype(ctx.width / 2), dtype(1) / dtype(ctx.width), g_cur, g_consts)
        g_channel = torch.from_numpy(g_consts.reshape(3, ctx.shape[2], -1).sum(axis=2)).to(ctx.param_dtype)
        return torch.from_numpy(g_cur).view(ctx.shape), g_channel[0], g_channel[1], g_channel[2], None, None


class CLIF(nn.Module):
    """A layer of C-LIF neurons with learnable per-channel time constants (ms); input (T, B, C, ...) currents."""

    def __init__(self, channels: int, alpha_m: float = ALPHA_M, alpha_s: float = ALPHA_S, theta: float = THETA,
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
        d_m, d_s, v0 = self._constants((-1,))
        return CLIFFunction.apply(current, d_m, d_s, v0, self.theta, self.surrogate_width)

    def _forward_reference(self, current: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """The recurrence as a loop of torch ops under autograd (reference for CLIFFunction's gradients)."""
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


BLOCK = 2048  # neurons per tile of the backward pass: its recomputed states (3 x T x BLOCK) stay in the L2 cache


@numba.njit(cache=True)
def _clif_block(cur: np.ndarray, i: int, j0: int, j1: int, d_m: np.ndarray, d_s: np.ndarray, v0: np.ndarray,
                theta: np.floating, states: np.ndarray, last: np.ndarray, pre: np.ndarray) -> None:  # pragma: no cover
    """C-LIF of sample i, neurons j0..j1-1, over all steps of currents (T, B, M): per step n, m[n-1] + I[n],
    s[n-1] + I[n], r[n-1] + S[n-1], V[n] and S[n] into pre[0..4, n, :j1 - j0]; states (3, >= j1 - j0) and
    last (>= j1 - j0) are scratch.

    The three states and each rounding as in CLIF._forward_reference (not the fused u = V0 m - theta r of
    _clif_steps), so outputs and surrogate windows equal the reference loop's bit for bit; the forward
    and backward kernels both run this, so the backward sees exactly the forward's states. One-dimensional
    views and no branches in the inner loop, so it vectorises.
    """
    width = j1 - j0
    m, s, r = states[0, :width], states[1, :width], states[2, :width]
    m[:] = 0
    s[:] = 0
    r[:] = 0
    dm, ds, v0j = d_m[j0:j1], d_s[j0:j1], v0[j0:j1]
    for n in range(cur.shape[0]):
        x = cur[n, i, j0:j1]
        m_pre, s_pre, r_pre, volts, spikes = pre[0, n, :width], pre[1, n, :width], pre[2, n, :width], \
            pre[3, n, :width], pre[4, n, :width]
        last_n = pre[4, n - 1, :width] if n > 0 else last[:width]
        for k in range(width):
            mp = m[k] + x[k]
            sp = s[k] + x[k]
            rp = r[k] + last_n[k]
            mn = dm[k] * mp
            sn = ds[k] * sp
            rn = dm[k] * rp
            v = v0j[k] * (mn - sn) - theta * rn
            m[k] = mn
            s[k] = sn
            r[k] = rn
            m_pre[k] = mp
            s_pre[k] = sp
            r_pre[k] = rp
            volts[k] = v
            spikes[k] = v >= theta


@numba.njit(cache=True)
def _clif_train_forward(cur: np.ndarray, d_m: np.ndarray, d_s: np.ndarray, v0: np.ndarray, theta: np.floating,
                        spikes: np.ndarray, volts: np.ndarray) -> None:  # pragma: no cover - compiled
    """C-LIF over currents (T, B, M) into spikes and volts; d_m, d_s, V0 per neuron (M,). Nothing else is kept:
    the backward pass recomputes the states tile by tile (writing them out would cost more memory traffic)."""
    steps, batch, neurons = cur.shape
    tile = min(neurons, BLOCK)
    pre = np.empty((5, steps, tile), cur.dtype)
    states = np.empty((3, tile), cur.dtype)
    last = np.zeros(tile, cur.dtype)
    for i in range(batch):
        for j0 in range(0, neurons, BLOCK):
            j1 = min(j0 + BLOCK, neurons)
            _clif_block(cur, i, j0, j1, d_m, d_s, v0, theta, states, last, pre)
            for n in range(steps):
                volts[n, i, j0:j1] = pre[3, n, :j1 - j0]
                spikes[n, i, j0:j1] = pre[4, n, :j1 - j0]


@numba.njit(cache=True)
def _clif_train_backward(cur: np.ndarray, g_spikes: np.ndarray, has_g_spikes: bool, g_volts: np.ndarray,
                         has_g_volts: bool, d_m: np.ndarray, d_s: np.ndarray, v0: np.ndarray, theta: np.floating,
                         half: np.floating, inv_width: np.floating, g_cur: np.ndarray,
                         g_consts: np.ndarray) -> None:  # pragma: no cover - compiled
    """The adjoint recurrence of the forward pass in reverse time (see the module docstring), per tile of
    neurons after recomputing its states: the current's gradient into g_cur (T, B, M), the constants'
    per neuron added to g_consts (3, M: d_m, d_s, V0).

    Each product and two-term sum is the one autograd forms on the reference loop, in the same
    operand order up to commutation (exact in IEEE; a missing output gradient is a 0 added, also
    exact), so g_cur is bit-identical to it.
    """
    steps, batch, neurons = cur.shape
    zero = theta - theta  # the surrogate's 0 outside the window, in the arrays' type (a literal 0 would widen)
    tile = min(neurons, BLOCK)
    pre = np.empty((5, steps, tile), cur.dtype)
    states = np.empty((3, tile), cur.dtype)
    last = np.zeros(tile, cur.dtype)
    adjoint = np.empty((3, tile), cur.dtype)  # d_m am[n+1], d_s as[n+1], d_m ar[n+1]: what step n gets from n+1
    nothing = np.zeros(tile, cur.dtype)
    for i in range(batch):
        for j0 in range(0, neurons, BLOCK):
            j1 = min(j0 + BLOCK, neurons)
            width = j1 - j0
            _clif_block(cur, i, j0, j1, d_m, d_s, v0, theta, states, last, pre)
            cm, cs, cr = adjoint[0, :width], adjoint[1, :width], adjoint[2, :width]
            cm[:] = 0
            cs[:] = 0
            cr[:] = 0
            dm, ds, v0j = d_m[j0:j1], d_s[j0:j1], v0[j0:j1]
            gdm, gds, gv0 = g_consts[0, j0:j1], g_consts[1, j0:j1], g_consts[2, j0:j1]
            for n in range(steps - 1, -1, -1):
                gs = g_spikes[n, i, j0:j1] if has_g_spikes else nothing[:width]
                gv = g_volts[n, i, j0:j1] if has_g_volts else nothing[:width]
                out = g_cur[n, i, j0:j1]
                m_pre, s_pre, r_pre, volts = pre[0, n, :width], pre[1, n, :width], pre[2, n, :width], pre[3, n, :width]
                for k in range(width):
                    a_spike = gs[k] + cr[k]
                    a_v = gv[k] + a_spike * (inv_width if abs(volts[k] - theta) < half else zero)
                    a_r = cr[k] - a_v * theta
                    a_m = a_v * v0j[k] + cm[k]
                    a_s = cs[k] - a_v * v0j[k]
                    mp = m_pre[k]
                    sp = s_pre[k]
                    cm[k] = a_m * dm[k]
                    cs[k] = a_s * ds[k]
                    cr[k] = a_r * dm[k]
                    out[k] = cm[k] + cs[k]
                    gdm[k] += np.float64(a_m) * mp + np.float64(a_r) * r_pre[k]
                    gds[k] += np.float64(a_s) * sp
                    gv0[k] += np.float64(a_v) * (dm[k] * mp - ds[k] * sp)
