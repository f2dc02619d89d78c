"""Accuracy A, robustness R and ARscore (paper eq. 8-10), per sequence and pooled over sequences."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

FAILURE_IOU = 0.5  # a counted segment with IoU below this is a failure (paper §3.2)
ALL = "all"  # the name of the row that pools every sequence, in every table
BETA = 2.0  # ARscore weight: R counts beta^2 times as much as A (paper eq. 10)


def ar_score(a: float, r: float, beta: float = BETA) -> float:
    """ARscore = (1 + b^2) A R / (b^2 A + R); 0 when A and R are both 0."""
    denom = beta * beta * a + r
    return float((1 + beta * beta) * a * r / denom) if denom > 0 else 0.0


@dataclass(frozen=True)
class Scores:
    """A (mean IoU), R (success fraction), ARscore and the counts behind them."""

    accuracy: float
    robustness: float
    arscore: float
    segments: int
    failures: int


def scores(ious: np.ndarray, beta: float = BETA) -> Scores:
    """Scores of the counted segments' IoUs (NaN entries are segments that do not count)."""
    v = np.asarray(ious, dtype=np.float64)
    v = v[~np.isnan(v)]
    if v.size == 0:
        return Scores(float("nan"), float("nan"), float("nan"), 0, 0)
    a = float(v.mean())
    success = v >= FAILURE_IOU
    r = float(success.mean())
    return Scores(a, r, ar_score(a, r, beta), int(v.size), int((~success).sum()))


def pooled(per_sequence: list[np.ndarray], beta: float = BETA) -> Scores:
    """Scores over all counted segments of all sequences together (eq. 8-9 normalised by the total count)."""
    if not per_sequence:
        return scores(np.empty(0), beta)
    return scores(np.concatenate([np.asarray(s, dtype=np.float64) for s in per_sequence]), beta)
