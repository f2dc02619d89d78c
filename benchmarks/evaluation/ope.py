"""One-pass evaluation (OPE, as OTB, GOT-10k, FE108 and VisEvent report it): success AUC and precision at 20 px.

The tracker is initialised once, on the first segment with a ground-truth box and a visible target, and
predicts every later segment with no re-initialisation (`run_sequence(..., reinitialise=False)`). Every
later segment with a box and a visible target counts (for a recording: every later segment matched to an
annotation with a box); a segment whose target is wholly hidden is scored apart (protocol rule 6: the
`absent` column of the attribute tables) or, with skip_absent, not at all; a prediction that is not finite
counts as IoU 0 and an infinite centre error.

- Success curve: the fraction of counted segments with IoU > t, for t = 0, 0.05, ..., 1 (21
  thresholds, OTB's); success AUC is its mean.
- Precision curve: the fraction with centre distance <= d pixels, d = 0 .. 50; precision is its value
  at 20 px.
Per sequence, and over all counted segments of all sequences together ("all"), as A and R are pooled.
The table, plots and files of these scores: benchmarks.analysis.ope_tables.
"""

from __future__ import annotations

import numpy as np

from benchmarks.evaluation.metrics import ALL
from benchmarks.evaluation.protocol import SequenceResult

IOU_THRESHOLDS = np.linspace(0.0, 1.0, 21)
PIXEL_THRESHOLDS = np.arange(0, 51, dtype=np.float64)
PRECISION_PX = 20


def centre_errors(pred: np.ndarray, gt: np.ndarray) -> np.ndarray:
    """Distance (pixels) between box centres, per row of (N, 4) xywh arrays; inf where the prediction is not finite."""
    p, g = np.asarray(pred, np.float64).reshape(-1, 4), np.asarray(gt, np.float64).reshape(-1, 4)
    d = np.hypot(p[:, 0] + p[:, 2] / 2 - g[:, 0] - g[:, 2] / 2, p[:, 1] + p[:, 3] / 2 - g[:, 1] - g[:, 3] / 2)
    return np.where(np.isfinite(p).all(axis=1), d, np.inf)


def success_curve(ious: np.ndarray) -> np.ndarray:
    """Fraction of IoUs above each of IOU_THRESHOLDS (NaN entries are segments that do not count)."""
    v = np.asarray(ious, np.float64)
    v = v[~np.isnan(v)]
    if v.size == 0:
        return np.full(len(IOU_THRESHOLDS), np.nan)
    return (v[None, :] > IOU_THRESHOLDS[:, None]).mean(axis=1)


def precision_curve(errors: np.ndarray) -> np.ndarray:
    """Fraction of centre errors (pixels) at or below each of PIXEL_THRESHOLDS (NaN entries do not count)."""
    v = np.asarray(errors, np.float64)
    v = v[~np.isnan(v)]
    if v.size == 0:
        return np.full(len(PIXEL_THRESHOLDS), np.nan)
    return (v[None, :] <= PIXEL_THRESHOLDS[:, None]).mean(axis=1)


def add_centre_errors(result: SequenceResult, gt: np.ndarray) -> SequenceResult:
    """Store the counted segments' centre errors (pixels, NaN elsewhere) in result.extra['centre_error'], and the
    hidden segments' scored apart (protocol rule 6) in result.extra['hidden_centre_error']."""
    gt = gt[: len(result.iou)]
    for key, iou in (("centre_error", result.iou), ("hidden_centre_error", result.hidden_iou)):
        err = np.full(len(result.iou), np.nan)
        if iou is not None:
            counted = ~np.isnan(iou)
            err[counted] = centre_errors(result.predictions[counted], gt[counted])
        result.extra[key] = err
    return result


def _scores(ious: np.ndarray, errors: np.ndarray) -> dict:
    s, p = success_curve(ious), precision_curve(errors)
    return {"AUC": float(np.mean(s)), f"P@{PRECISION_PX}": float(p[PRECISION_PX]),
            "segments": int(np.count_nonzero(~np.isnan(np.asarray(ious, np.float64)))),
            "success": s.tolist(), "precision": p.tolist()}


def summarise_ope(results: list[SequenceResult]) -> dict:
    """{tracker: {sequence or 'all': AUC, P@20, segments, the two curves}} of finished runs (failed ones: error)."""
    out: dict = {}
    for r in results:
        per = out.setdefault(r.tracker, {})
        per[r.sequence] = {"error": r.error} if r.error else _scores(r.iou, r.extra["centre_error"])
    for tracker, per in out.items():
        ok = [r for r in results if r.tracker == tracker and r.error is None]
        if ok:
            per[ALL] = _scores(np.concatenate([r.iou for r in ok]),
                               np.concatenate([r.extra["centre_error"] for r in ok]))
    return out
