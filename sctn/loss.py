"""The voltage-domain loss (paper eq. 5-6), the linear-IoU variant (eq. 12) and the basic constant-feedback loss.

The target neuron has an expected maximum voltage theta + R_s over the time window. Its feedback R_s
is exp(5 IoU) / 100 for positive samples (eq. 6; 0.3 ... 1.5 over IoU 0.7 ... 1), 4 IoU - 2.5 for the
linear variant (eq. 12), +1 for the basic loss, and -0.3 for negative samples in all three. Eq. 5
counts the error only on the wrong side of the expectation: a positive whose V_max falls short of
theta + R_s ("fails to fire") contributes theta + R_s - V_max; a negative whose V_max exceeds
theta + R_s = theta - 0.3 ("fires wrongly") contributes V_max - R_s - theta. The paper's loss is that
error of the target neuron, averaged over the samples of a batch (STCA back-propagates the residual
error itself: the output's gradient is the error's sign, scaled by 1 / batch).

Where in time the error sits (`error_steps`, STCA's rule, Gu et al. 2019, the preset's "stca"): a
sample that should fire and did not (V below theta at every step) is charged at the step of the highest
local maximum of its V (V rises into that step from the previous one, resting 0 before the window, and
does not rise after it; the last step counts when V rises into it); with no such peak, at a random step
drawn from the training generator. A sample that fired is charged at its firing step of largest V, and
one that should not fire at its step of largest V. "stca_code" is STCA as its authors' code has it, which
differs in two edge cases: a sample that should fire and has no sub-threshold peak is charged at the last
step, and a wrong firing (a neuron that should not fire reached theta) at the peak of V within its last
spike cluster (the run of firing steps, V >= theta, that ends at its last spike), not at the firing step
of largest V anywhere in the window. The named ablation "max" charges every sample at the
maximum of V over all steps, which for a neuron whose input is net negative is a quiet step where V
rests at 0 and nothing arrived: no gradient reaches any weight though the error is not zero.

Two named deviations, off by default, each with its ablation row (docs/sctn.md): `squared` squares
each sample's error before averaging (the gradient then grows with the residual), and `background`
adds the mirrored term of the background neuron (it should reach theta + 0.3 on negatives and stay
below theta - 0.3 on positives; constant feedback). Tracking reads only the target neuron.
"""

from __future__ import annotations

from typing import Literal, get_args

import numpy as np
import torch

from sctn.neurons import THETA
from sctn.params import ERROR_TIMES, ErrorTime  # noqa: F401  (ErrorTime: the setting's type, imported from here)

NEGATIVE_FEEDBACK = -0.3
LossKind = Literal["exp", "linear", "basic"]
LOSS_KINDS: tuple[str, ...] = get_args(LossKind)


def feedback(iou: torch.Tensor, positive: torch.Tensor, kind: str = "exp") -> torch.Tensor:
    """R_s per sample: eq. 6 ("exp", beta 5, gamma 100), eq. 12 ("linear", mu 4, nu 2.5) or "basic" (+1)."""
    if kind == "exp":
        pos = torch.exp(5.0 * iou) / 100.0
    elif kind == "linear":
        pos = 4.0 * iou - 2.5
    elif kind == "basic":
        pos = torch.ones_like(iou)
    else:
        raise ValueError(f"unknown loss kind {kind!r} ({', '.join(LOSS_KINDS)})")
    return torch.where(positive, pos, torch.full_like(iou, NEGATIVE_FEEDBACK))


def voltage_errors(vmax: torch.Tensor, expected: torch.Tensor, should_fire: torch.Tensor) -> torch.Tensor:
    """Eq. 5 per sample: shortfall below the expectation if it should fire, excess above it otherwise."""
    short = torch.clamp(expected - vmax, min=0.0)
    excess = torch.clamp(vmax - expected, min=0.0)
    return torch.where(should_fire, short, excess)


def voltage_loss(vmax: torch.Tensor, iou: torch.Tensor, positive: torch.Tensor, kind: str = "exp",
                 theta: float = THETA, squared: bool = False, background: bool = False) -> torch.Tensor:
    """Eq. 5 of the target neuron (vmax[:, 1]) averaged over samples; `squared` and `background` are deviations."""
    error = voltage_errors(vmax[:, 1], theta + feedback(iou, positive, kind), positive)
    if squared:
        error = error ** 2
    if background:
        r_bg = torch.where(positive, torch.full_like(iou, NEGATIVE_FEEDBACK), torch.full_like(iou, -NEGATIVE_FEEDBACK))
        e_bg = voltage_errors(vmax[:, 0], theta + r_bg, ~positive)
        error = error + (e_bg ** 2 if squared else e_bg)
    return error.mean()



def peak_steps(volts: torch.Tensor, theta: float = THETA) -> torch.Tensor:
    """Per sample and neuron of volts (N, T, K): the step of the highest local maximum of V below theta, or -1
    where V has none. A local maximum rises into its step (from resting 0 before the first) and does not rise
    into the next (the last step counts when V rises into it)."""
    v = volts.detach()
    before = torch.cat([torch.zeros_like(v[:, :1]), v[:, :-1]], dim=1)
    after = torch.cat([v[:, 1:], torch.full_like(v[:, :1], -torch.inf)], dim=1)
    peak = (v > before) & (v >= after) & (v < theta)
    score = torch.where(peak, v, torch.full_like(v, -torch.inf))
    best = score.argmax(dim=1)
    return torch.where(peak.any(dim=1), best, torch.full_like(best, -1))


def last_cluster_peaks(volts: torch.Tensor, theta: float = THETA) -> torch.Tensor:
    """Per sample and neuron of volts (N, T, K): the step of largest V within the last spike cluster (the run of
    steps with V >= theta that ends at the last such step; the first of equal maxima), or -1 where V never
    reaches theta."""
    v = volts.detach()
    fires = v >= theta
    steps = torch.arange(v.shape[1], device=v.device)[None, :, None].expand_as(v)
    last = torch.where(fires, steps, torch.full_like(steps, -1)).amax(dim=1, keepdim=True)
    gap = torch.where(~fires & (steps < last), steps, torch.full_like(steps, -1)).amax(dim=1, keepdim=True)
    in_cluster = (steps > gap) & (steps <= last)
    best = torch.where(in_cluster, v, torch.full_like(v, -torch.inf)).argmax(dim=1)
    return torch.where(last[:, 0] >= 0, best, torch.full_like(best, -1))


def error_steps(volts: torch.Tensor, should_fire: torch.Tensor, rule: str = "stca",
                rng: np.random.Generator | None = None, theta: float = THETA) -> torch.Tensor:
    """The step (N, K) where each sample's error sits, for voltages (N, T, K) and should_fire (N, K).

    "max": the step of largest V. "stca": that step too, except for a sample that should fire and never
    reached theta: the step of its highest local maximum of V (peak_steps), else a step drawn from `rng`
    (one draw per sample and neuron on every call, so the stream does not depend on the voltages).
    "stca_code": as "stca", but the last step where "stca" draws one (no rng needed), and a sample that
    should not fire and reached theta at the peak of its last spike cluster (last_cluster_peaks).
    """
    if rule not in ERROR_TIMES:
        raise ValueError(f"unknown error time {rule!r} ({', '.join(ERROR_TIMES)})")
    v = volts.detach()
    top = v.argmax(dim=1)
    if rule == "max":
        return top
    n, t, k = v.shape
    if rule == "stca_code":
        fallback = torch.full_like(top, t - 1)
    elif rng is None:
        raise ValueError("the stca error time needs a random generator for its steps without a peak")
    else:
        fallback = torch.from_numpy(rng.integers(0, t, size=(n, k))).to(top.dtype)
    peak = peak_steps(v, theta)
    fired = v.amax(dim=1) >= theta
    missed = should_fire & ~fired
    steps = torch.where(missed, torch.where(peak >= 0, peak, fallback), top)
    if rule == "stca_code":
        steps = torch.where(~should_fire & fired, last_cluster_peaks(v, theta), steps)
    return steps


def error_voltages(volts: torch.Tensor, positive: torch.Tensor, rule: str = "stca",
                   rng: np.random.Generator | None = None, theta: float = THETA) -> torch.Tensor:
    """V (N, 2) of the background and target neurons at their error steps (error_steps) for voltages (N, T, 2):
    what voltage_loss takes in place of V_max. The target should fire on positives, the background on
    negatives. "max" returns V_max itself (volts.max over steps)."""
    if rule == "max":
        return volts.max(dim=1).values
    should = torch.stack([~positive, positive], dim=1)
    steps = error_steps(volts, should, rule, rng, theta)
    return volts.gather(1, steps[:, None, :])[:, 0]
