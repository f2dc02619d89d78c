"""Scores of a streaming run (benchmarks.evaluation.stream) per tracker, latency model and sequence, pooled over
sequences ('all'), beside the latency-free reference, with each tracker's latency distribution and the scale
factor at which it falls to half its latency-free ARscore."""

from __future__ import annotations

import numpy as np

from benchmarks.evaluation.latency import FREE
from benchmarks.evaluation.metrics import ALL
from benchmarks.evaluation.stream import StreamSequence, latency_stats, stream_scores

PREDICTIVE = " (predictive)"  # the suffix of a tracker's predictive row
HALF_OF = "ARscore"  # the score whose half the half factor is found at


def _pool(runs: list, key: str) -> np.ndarray:
    return np.concatenate([getattr(r, key) for r in runs]) if runs else np.empty(0)


def half_factor(curve: list[tuple[float, float]], reference: float) -> dict:
    """The scale factor at which a score curve [(factor, score)] falls to half the reference score: linear between
    the bracketing factors; `reached` says whether it does within the factors given (else factor is None)."""
    half = reference / 2.0
    pts = sorted((f, s) for f, s in curve if np.isfinite(s))
    if not pts or not np.isfinite(reference):
        return {"factor": None, "reached": False, "half_score": half}
    if pts[0][1] <= half:
        return {"factor": pts[0][0], "reached": True, "at_or_below": True, "half_score": half}
    for (f0, s0), (f1, s1) in zip(pts, pts[1:]):
        if s1 <= half:
            return {"factor": float(f0 + (f1 - f0) * (s0 - half) / (s0 - s1)), "reached": True, "half_score": half}
    return {"factor": None, "reached": False, "half_score": half}


def summarise_stream(results: list[StreamSequence], predictive: bool = False, settings: dict | None = None) -> dict:
    """{settings, machine, rows: {row: {model: {sequence or 'all': scores, latency}}}, drop, half_factor, curves};
    a row is a tracker (and its predictive row when asked), failed runs are {'error': ...} cells."""
    rows: dict = {}
    machines = {}
    for r in results:
        if r.machine:
            machines[r.machine["node"]] = r.machine
        names = [(r.tracker, False)] + ([(r.tracker + PREDICTIVE, True)] if predictive else [])
        for row, pred in names:
            per = rows.setdefault(row, {})
            if r.error:
                per.setdefault("failed", {})[r.sequence] = {"error": r.error}
                continue
            for model, run in r.runs.items():
                iou, err = ((run.predictive_iou, run.predictive_centre_error) if pred else (run.iou, run.centre_error))
                per.setdefault(model, {})[r.sequence] = {**stream_scores(iou, err),
                                                         "latency": latency_stats(run.latency_s[1:])}
    for row, per in rows.items():
        tracker = row.removesuffix(PREDICTIVE)
        pred = row != tracker
        ok = [r for r in results if r.tracker == tracker and r.error is None]
        for model in [m for m in per if m != "failed"]:
            runs = [r.runs[model] for r in ok]
            iou = _pool(runs, "predictive_iou" if pred else "iou")
            err = _pool(runs, "predictive_centre_error" if pred else "centre_error")
            per[model][ALL] = {**stream_scores(iou, err),
                               "latency": latency_stats(np.concatenate([run.latency_s[1:] for run in runs]))}
    drop, halves, curves = {}, {}, {}
    for row, per in rows.items():
        free = per.get(FREE, {}).get(ALL)
        if free is None:
            continue
        drop[row] = {m: {k: free[k] - v[ALL][k] for k in ("ARscore", "AUC")}
                     for m, v in per.items() if m not in (FREE, "failed") and ALL in v}
        curve = [(float(m.split(":", 1)[1]), v[ALL][HALF_OF]) for m, v in per.items()
                 if m.startswith("scaled:") and ALL in v]
        if curve:
            curves[row] = sorted(curve)
            halves[row] = half_factor(curve, free[HALF_OF])
    return {"protocol": "stream", "settings": settings or {}, "machines": list(machines.values()), "rows": rows,
            "drop": drop, "half_factor": halves, "scale_curves": curves}
