"""Latency-aware streaming evaluation (after STARE, Zhang et al., ESOT500): the tracker runs on the stream as it
arrives, each answer arrives late by the tracker's latency, and ground truth at fixed instants scores the latest
answer available then.

Rules (one pass, as STARE: no re-initialisation):

1. Time is the stream's (microseconds). The tracker is initialised at t_init, the end of the first segment with a
   usable ground-truth box (as the one-pass protocol), on that 10 ms window; the given box is the answer available
   from t_init. The initialisation is given its time: its latency is recorded but not charged, and the first call
   starts one query period after t_init (a fine-tuning tracker, SCTN, would otherwise spend seconds of stream
   before its first answer, and the evaluation measures tracking latency).
2. Free at t, the tracker gets a window of events ending at t: the last `segment_us` (window "last", the default)
   or everything since its previous call ended (window "since"); its box, the target at t, becomes available at
   t + L. The next call starts then, but no earlier than one query period after t (a faster tracker's extra
   answers would never be scored). Calls stop at the end of the stream.
3. Ground truth is queried every 1 / query_hz after t_init (a recording: at its annotations after t_init); a query
   counts where its box is usable (finite, at least `min_box_px` wide and high) and scores the latest answer
   available at or before it: IoU and centre error.
4. Scores on the counted queries: A (mean IoU), R (share with IoU >= 0.5), ARscore (metrics.ar_score, eq. 10),
   success AUC and precision at 20 px (benchmarks.evaluation.ope); per tracker, the latencies of its calls.
5. Predictive (STARE's enhancement): each answer is extrapolated by its own latency from the tracker's last two
   answers (box + velocity x L, per coordinate); the tracker itself still gets its own boxes. It changes no call,
   so it is scored from the same run, as its own row.
6. Latency-free reference: the same tracker called at every segment end (10 ms), each answer available at once,
   scored at the same queries; the drop is the streaming score's loss against it.
7. A hidden target (the protocols' rule 6, docs/benchmarks.md): a query where the target is on the sensor but
   wholly covered (an amodal box and no visible one, in a file that records visibility) is scored apart: its IoU
   is kept in `hidden_iou` and counts in none of the scores above. Initialisation waits for a visible target.

Latency models (benchmarks.evaluation.latency): measured wall time, measured times a factor, or a declared cost
(operations the tracker counts times a hardware profile's time per operation: deterministic).
"""

from __future__ import annotations

import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from benchmarks.evaluation.instant_truth import InstantTruth, query_times, truth_at
from benchmarks.evaluation.latency import FREE, LatencyModel
from benchmarks.evaluation.metrics import FAILURE_IOU, ar_score
from benchmarks.evaluation.ope import PRECISION_PX, centre_errors, precision_curve, success_curve
from benchmarks.trackers.base import Tracker
from dvsot.core.errors import UserError, exception_line
from dvsot.dataset import Dataset, Segment
from dvsot.dataset.boxes import iou_xywh
from dvsot.dataset.format import BoxTrack

DEFAULT_QUERY_HZ = 1000.0
WINDOWS = ("last", "since")  # the events a call gets: the last segment_us, or everything since the previous call
MIN_BOX_PX = 1.0


@dataclass
class StreamRun:
    """One tracker's calls on one sequence under one latency model (its name), and its answers scored at the queries.

    Per call, the initialisation first: window (C, 2) t0_us, t1_us (the instant the answer describes), latency_s
    (C,), available_us (C,), boxes and predicted (the extrapolated answers) (C, 4) xywh pixels. Per query:
    query_us (Q,), iou and centre_error of the plain answers (NaN where a query does not count), predictive_iou
    and predictive_centre_error of the extrapolated ones.
    """

    latency: str
    window: np.ndarray
    latency_s: np.ndarray
    available_us: np.ndarray
    boxes: np.ndarray
    predicted: np.ndarray
    query_us: np.ndarray
    iou: np.ndarray
    centre_error: np.ndarray
    predictive_iou: np.ndarray
    predictive_centre_error: np.ndarray
    hidden_iou: np.ndarray | None = None  # per query: IoU where the target is wholly hidden (rule 7), else NaN


@dataclass
class StreamSequence:
    """Every latency model's run of one tracker on one sequence (keyed by model name, FREE included)."""

    tracker: str
    sequence: str
    runs: dict[str, StreamRun] = field(default_factory=dict)
    machine: dict | None = None
    error: str | None = None


def _window(dataset: Dataset, index: int, t0_us: int, t1_us: int) -> Segment:
    """The events of [t0_us, t1_us) as a Segment; its box is NaN: a streaming call is never shown ground truth."""
    events = dataset.events(int(t0_us), int(t1_us))
    return Segment(index, int(t0_us), int(t1_us), events, np.full(4, np.nan, np.float32))


def _first_box(dataset: Dataset, n_segments: int, min_box_px: float) -> tuple[int, np.ndarray] | None:
    """(segment index, box) of the first scored segment with a usable box and a visible target (rule 7), or None."""
    gt, scored = dataset.segment_boxes()[:n_segments], dataset.segment_scored()[:n_segments]
    absent = dataset.segment_absent()
    seen = np.ones(len(gt), bool) if absent is None else ~np.asarray(absent[:n_segments], bool)
    with np.errstate(invalid="ignore"):
        ok = scored & seen & np.isfinite(gt).all(axis=1) & (gt[:, 2] >= min_box_px) & (gt[:, 3] >= min_box_px)
    hits = np.flatnonzero(ok)
    return (int(hits[0]), gt[hits[0]].copy()) if hits.size else None


def _calls(tracker: Tracker, dataset: Dataset, model: LatencyModel, first: int, box: np.ndarray, end_us: int,
           window: str, min_step_us: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Run the tracker on the stream: windows (C, 2) us, latencies (C,) s, availability (C,) us, boxes (C, 4)."""
    seg_us = dataset.segment_us
    t = (first + 1) * seg_us
    windows, latencies, available, boxes = [], [], [], []
    start = time.perf_counter()
    tracker.init(_window(dataset, 0, t - seg_us, t), box.copy(), dataset.width, dataset.height)
    latency = model.latency_s(time.perf_counter() - start, tracker, init=True)
    windows.append((t - seg_us, t))
    latencies.append(latency)
    available.append(t)  # the given box is known at once; only the tracker's next call waits for L_init
    boxes.append(np.asarray(box, np.float64))
    last_end = t
    t_free = t + min_step_us  # rule 1: the initialisation's latency is recorded, not charged
    k = 1
    while t_free <= end_us:
        t0 = t_free - seg_us if window == "last" else last_end
        segment = _window(dataset, k, max(t0, 0), t_free)
        start = time.perf_counter()
        pred = np.asarray(tracker.update(segment), dtype=np.float64).reshape(4)
        latency = model.latency_s(time.perf_counter() - start, tracker, init=False)
        windows.append((segment.t0_us, t_free))
        latencies.append(latency)
        available.append(t_free + _us(latency))
        boxes.append(pred)
        last_end = t_free
        t_free = t_free + max(_us(latency), min_step_us)
        k += 1
    return (np.asarray(windows, np.int64), np.asarray(latencies, np.float64), np.asarray(available, np.int64),
            np.asarray(boxes, np.float64))


def _us(seconds: float) -> int:
    """Seconds as whole microseconds, rounded up: an answer is never available before its latency has passed."""
    return int(np.ceil(seconds * 1e6 - 1e-6))


def extrapolate(boxes: np.ndarray, times_us: np.ndarray, latency_s: np.ndarray) -> np.ndarray:
    """Each box (C, 4) moved on by its latency at the velocity of it and the one before (boxes at times_us, the
    instants they describe); the first, and any after a non-finite one, stays as it is."""
    out = boxes.copy()
    if len(boxes) < 2:
        return out
    dt = np.diff(times_us.astype(np.float64))[:, None]
    velocity = np.divide(boxes[1:] - boxes[:-1], dt, out=np.zeros_like(boxes[1:]), where=dt > 0)
    moved = boxes[1:] + velocity * (latency_s[1:, None] * 1e6)
    out[1:] = np.where(np.isfinite(moved).all(axis=1, keepdims=True), moved, boxes[1:])
    return out


def latest_available(available_us: np.ndarray, query_us: np.ndarray) -> np.ndarray:
    """Per query (us), the index of the latest call whose answer is available at or before it (-1: none yet);
    answers are in call order, and a call's answer describes a later instant than any earlier call's."""
    # availability need not be monotone (a fast call after a slow one): the running latest call among those out
    order = np.argsort(available_us, kind="stable")
    best = np.maximum.accumulate(order)  # among answers available by then, the one of the latest call
    pos = np.searchsorted(available_us[order], query_us, side="right") - 1
    return np.where(pos >= 0, best[np.clip(pos, 0, None)], -1)


def score_queries(boxes: np.ndarray, available_us: np.ndarray, query_us: np.ndarray,
                  truth: np.ndarray, min_box_px: float = MIN_BOX_PX) -> tuple[np.ndarray, np.ndarray]:
    """(IoU, centre error) per query of the latest available answer against the truth (Q, 4); NaN where the truth
    is not usable; a query before any answer, or with a non-finite answer, counts as IoU 0 and infinite error."""
    idx = latest_available(available_us, query_us)
    with np.errstate(invalid="ignore"):
        usable = np.isfinite(truth).all(axis=1) & (truth[:, 2] >= min_box_px) & (truth[:, 3] >= min_box_px)
    pred = np.where((idx >= 0)[:, None], boxes[np.clip(idx, 0, None)], np.nan)
    finite = np.isfinite(pred).all(axis=1)
    iou = np.where(finite, iou_xywh(np.where(finite[:, None], pred, 0.0), truth), 0.0)
    err = centre_errors(pred, np.nan_to_num(truth))
    return np.where(usable, iou, np.nan), np.where(usable, err, np.nan)


def run_stream(tracker: Tracker, dataset: Dataset, model: LatencyModel, query_hz: float = DEFAULT_QUERY_HZ,
               window: str = "last", max_segments: int | None = None, min_box_px: float = MIN_BOX_PX) -> StreamRun:
    """One tracker on one sequence under one latency model; errors raise (run_sequences records them)."""
    if window not in WINDOWS:
        raise UserError(f"stream window must be one of {', '.join(WINDOWS)}, got {window!r}")
    n = dataset.num_segments if max_segments is None else min(max_segments, dataset.num_segments)
    found = _first_box(dataset, n, min_box_px)
    if found is None:
        raise UserError(f"{dataset.path}: no segment with a usable ground-truth box to initialise on")
    first, box = found
    end_us = n * dataset.segment_us
    step_us = max(1, int(round(1e6 / query_hz)))
    if model.kind == FREE:  # the latency-free reference: a call at every segment end, each answer at once
        window, step_us = "last", dataset.segment_us
    windows, latency, available, boxes = _calls(tracker, dataset, model, first, box, end_us, window, step_us)
    track = dataset.boxes()
    queries = query_times(track, windows[0, 1], end_us, query_hz, dataset.annotated)
    instant = truth_at(track, queries)
    truth = instant.xywh
    hidden = hidden_queries(track, instant)
    iou, err = score_queries(boxes, available, queries, truth, min_box_px)
    hidden_iou = np.where(hidden, iou, np.nan)
    iou, err = np.where(hidden, np.nan, iou), np.where(hidden, np.nan, err)
    predicted = extrapolate(boxes, windows[:, 1], latency)
    predicted[0] = boxes[0]  # the given box is not a tracker's answer
    p_iou, p_err = score_queries(predicted, available, queries, truth, min_box_px)
    p_iou, p_err = np.where(hidden, np.nan, p_iou), np.where(hidden, np.nan, p_err)
    return StreamRun(model.name, windows, latency, available, boxes, predicted, queries, iou, err, p_iou, p_err,
                     hidden_iou)


def hidden_queries(track: BoxTrack, instant: InstantTruth) -> np.ndarray:
    """bool (Q,): queries where the target is on the sensor and wholly covered (rule 7); none for a file that
    records no visibility (a recording's visible box is not known)."""
    if track.visibility is None:
        return np.zeros(len(instant.t), bool)
    on_sensor = np.isfinite(instant.xywh).all(axis=1)
    return on_sensor & ~np.isfinite(instant.xywh_visible).all(axis=1)


def run_sequences(tracker_factory: Callable[[], Tracker], dataset: Dataset, models: list[LatencyModel], name: str,
                  query_hz: float = DEFAULT_QUERY_HZ, window: str = "last",
                  max_segments: int | None = None) -> StreamSequence:
    """Every latency model's run of a fresh tracker on one sequence, the latency-free reference first; a crash is
    recorded (error), not raised; bad data raises."""
    from benchmarks.evaluation.latency import free_model, machine

    out = StreamSequence(name, dataset.name)
    if any(m.kind in ("measured", "scaled") for m in models):
        out.machine = machine()
    try:
        for model in [free_model(), *models]:
            out.runs[model.name] = run_stream(tracker_factory(), dataset, model, query_hz, window, max_segments)
    except UserError:
        raise
    except Exception as exc:  # a crashing tracker fails this sequence only
        last = traceback.extract_tb(exc.__traceback__)[-1]
        out.error = f"{exception_line(exc)} ({last.filename.split('/')[-1]}:{last.lineno})"
    return out


def stream_scores(iou: np.ndarray, centre_error: np.ndarray) -> dict:
    """A, R, ARscore, success AUC, precision at 20 px and the count of the counted queries (NaN entries skipped)."""
    v = np.asarray(iou, np.float64)
    counted = ~np.isnan(v)
    if not counted.any():
        return {"A": float("nan"), "R": float("nan"), "ARscore": float("nan"), "AUC": float("nan"),
                f"P@{PRECISION_PX}": float("nan"), "queries": 0}
    a, r = float(v[counted].mean()), float((v[counted] >= FAILURE_IOU).mean())
    return {"A": a, "R": r, "ARscore": ar_score(a, r), "AUC": float(np.mean(success_curve(v))),
            f"P@{PRECISION_PX}": float(precision_curve(centre_error)[PRECISION_PX]), "queries": int(counted.sum())}


def latency_stats(latency_s: np.ndarray) -> dict:
    """Mean, median, 90th percentile and maximum (seconds) of the update calls' latencies, and their count."""
    v = np.asarray(latency_s, np.float64)
    if v.size == 0:
        return {"mean_s": float("nan"), "p50_s": float("nan"), "p90_s": float("nan"), "max_s": float("nan"), "calls": 0}
    return {"mean_s": float(v.mean()), "p50_s": float(np.percentile(v, 50)), "p90_s": float(np.percentile(v, 90)),
            "max_s": float(v.max()), "calls": int(v.size)}
