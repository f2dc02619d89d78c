"""The voltage-domain loss (paper eq. 5-6), the linear-IoU variant (eq. 12) and the basic constant-feedback loss.

The target neuron has an expected maximum voltage theta + R_s over the time window. Its feedback R_s
is exp(5 IoU) / 100 for positive samples (eq. 6; 0.3 ... 1.5 over IoU 0.7 ... 1), 4 IoU - 2.5 for the
linear variant (eq. 12), +1 for the basic loss, and -0.3 for negative samples in all three. Eq. 5
counts the error only on the wrong side of the expectation: a positive whose V_max falls short of
theta + R_s ("fails to fire") contributes theta + R_s - V_max; a negative whose V_max exceeds
theta + R_s = theta - 0.3 ("fires wrongly") contributes V_max - R_s - theta. The paper's loss is that
error of the target neuron, averaged over the samples of a batch (STCA back-propagates the residual
error itself: the output's gradient is the error's sign, scaled by 1 / batch).

Two named deviations, off by default, each with its ablation row (docs/sctn.md): `squared` squares
each sample's error before averaging (the gradient then grows with the residual), and `background`
adds the mirrored term of the background neuron (it should reach theta + 0.3 on negatives and stay
below theta - 0.3 on positives; constant feedback). Tracking reads only the target neuron.
"""

from __future__ import annotations

from typing import Literal, get_args

import torch

from sctn.neurons import THETA

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

