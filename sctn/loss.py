"""The voltage-domain loss (paper eq. 5-6), the linear-IoU variant (eq. 12) and the basic constant-feedback loss.

Each output neuron has an expected maximum voltage theta + R over the time window. The target
neuron's feedback R_s is exp(5 IoU) / 100 for positive samples (eq. 6; 0.3 ... 1.5 over IoU 0.7 ... 1),
4 IoU - 2.5 for the linear variant (eq. 12), +1 for the basic loss, and -0.3 for negative samples in
all three. The error is counted only on the wrong side of the expectation: a positive whose V_max
falls short of theta + R_s ("fails to fire") contributes theta + R_s - V_max; a negative whose V_max
exceeds theta + R_s = theta - 0.3 ("fires wrongly") contributes V_max - R_s - theta.

The background neuron is trained as the mirror image: it should reach theta + 0.3 on negative
samples and stay below theta - 0.3 on positive samples (constant feedback, no IoU weighting).
The loss is the mean over samples of the squared errors of both neurons (STCA back-propagates the
residual error; squaring keeps the gradient proportional to it).
"""

from __future__ import annotations

import torch

THETA = 0.5
NEGATIVE_FEEDBACK = -0.3


def feedback(iou: torch.Tensor, positive: torch.Tensor, kind: str = "exp") -> torch.Tensor:
    """R_s per sample: eq. 6 ("exp", beta 5, gamma 100), eq. 12 ("linear", mu 4, nu 2.5) or "basic" (+1)."""
    if kind == "exp":
        pos = torch.exp(5.0 * iou) / 100.0
    elif kind == "linear":
        pos = 4.0 * iou - 2.5
    elif kind == "basic":
        pos = torch.ones_like(iou)
    else:
        raise ValueError(f"unknown loss kind {kind!r} (exp, linear, basic)")
    return torch.where(positive, pos, torch.full_like(iou, NEGATIVE_FEEDBACK))


def voltage_errors(vmax: torch.Tensor, expected: torch.Tensor, should_fire: torch.Tensor) -> torch.Tensor:
    """Eq. 5 per sample: shortfall below the expectation if it should fire, excess above it otherwise."""
    short = torch.clamp(expected - vmax, min=0.0)
    excess = torch.clamp(vmax - expected, min=0.0)
    return torch.where(should_fire, short, excess)


def voltage_loss(vmax: torch.Tensor, iou: torch.Tensor, positive: torch.Tensor, kind: str = "exp",
                 theta: float = THETA) -> torch.Tensor:
    """Mean squared eq.-5 error of the target neuron (vmax[:, 1]) and the mirrored background neuron (vmax[:, 0])."""
    r_target = feedback(iou, positive, kind)
    e_target = voltage_errors(vmax[:, 1], theta + r_target, positive)
    r_bg = torch.where(positive, torch.full_like(iou, NEGATIVE_FEEDBACK), torch.full_like(iou, -NEGATIVE_FEEDBACK))
    e_bg = voltage_errors(vmax[:, 0], theta + r_bg, ~positive)
    return (e_target ** 2 + e_bg ** 2).mean()
