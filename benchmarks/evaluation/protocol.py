"""The tracking protocol with re-initialisation (paper §3.2), the same for every tracker.

Which segments count (written here once, used for every tracker):

1. A sequence is cut into segments of `segment_us` (10 ms); segment i's ground truth is the target's
   box at the segment's end.
2. A segment whose ground truth is absent (NaN: target out of view) or degenerate (width or height
   below `min_box_px`, default 1 px) is skipped: not counted, nothing is asked of the tracker, and the
   tracker is initialised again on the next segment with a ground truth.
3. The tracker is initialised with the ground truth on the first segment with a box, and again on
   the segment after each failure. Initialisation segments are given, not tracked: they do not count.
4. Every other segment counts: the tracker predicts a box; IoU with the ground truth; a failure when
   IoU < 0.5, which triggers re-initialisation on the next segment.
5. A recording's ground truth exists only at its annotations (`Dataset.annotated`): a segment without
   an annotation matched to it (dvsot.dataset.boxes.match_annotations) is tracked (the tracker predicts on it)
   but neither scored nor able to fail; rules 2-4 apply to the matched segments, so initialisation and
   re-initialisation wait for the next matched segment with a box. A rendered file matches every segment.

Speed is tracker time only (init + update calls), not reading the file.
"""

from __future__ import annotations

import time
import traceback
from dataclasses import dataclass, field

import numpy as np

from benchmarks.evaluation.metrics import FAILURE_IOU
from benchmarks.trackers.base import Tracker
from dvsot.dataset.boxes import iou_xywh
from dvsot.dataset import Dataset
from dvsot.core.errors import UserError, exception_line

MIN_BOX_PX = 1.0


@dataclass
class SequenceResult:
    """Per-segment outcome of one tracker on one sequence; `iou` is NaN for segments that do not count."""

    tracker: str
    sequence: str
    iou: np.ndarray
    predictions: np.ndarray
    init_segments: list[int]
    tracker_seconds: float
    tracked_segments: int
    energy: dict | None = None
    error: str | None = None
    extra: dict = field(default_factory=dict)
    init_seconds: float = 0.0  # time in tracker.init (SCTN fine-tunes there), apart from tracker_seconds
    segment_seconds: np.ndarray | None = None  # per segment: seconds in init or update, NaN where not asked
    init_energy: dict | None = None  # mean counts of an initialisation (fine-tuning's too), as energy_per_init gives

    @property
    def segments_per_s(self) -> float:
        """Tracked segments per second of update time (initialisations not included: init_seconds)."""
        return self.tracked_segments / self.tracker_seconds if self.tracker_seconds > 0 else float("nan")


def nothing_to_score(path, max_segments: int | None = None, reinitialise: bool = True,
                     min_box_px: float = MIN_BOX_PX) -> str | None:
    """Why the protocol would score no segment of the dataset file at path (its first max_segments), or None.

    A segment is scored when it has a usable box (rules 2 and 5) and follows the segment the tracker was
    initialised on; with re-initialisation, an unusable scored segment in between starts over (rule 2).
    """
    with Dataset(path) as ds:
        n = ds.num_segments if max_segments is None else min(max_segments, ds.num_segments)
        gt, scored = ds.segment_boxes()[:n], ds.segment_scored()[:n]
    with np.errstate(invalid="ignore"):
        usable = scored & ~np.isnan(gt).any(axis=1) & (gt[:, 2] >= min_box_px) & (gt[:, 3] >= min_box_px)
    u = usable[scored]
    if (u[:-1] & u[1:]).any() if reinitialise else u.sum() >= 2:
        return None
    return (f"{path}: no segment of {n} can be scored: the protocol needs a segment with a ground-truth box at "
            f"least {min_box_px:g} px wide and high to initialise on, and one after it "
            f"({int(usable.sum())} such segments{', none two in a row' if reinitialise and usable.any() else ''})")


def run_sequence(tracker: Tracker, dataset: Dataset, tracker_name: str | None = None,
                 min_box_px: float = MIN_BOX_PX, max_segments: int | None = None,
                 reinitialise: bool = True) -> SequenceResult:
    """Run one tracker over one sequence with re-initialisation on failure; a crash is recorded, not raised.

    reinitialise=False is the one-pass protocol (benchmarks/evaluation/ope.py): one initialisation, then the
    tracker predicts every later segment, failed or without ground truth, and only boxes are scored.
    """
    name = tracker_name or getattr(tracker, "name", type(tracker).__name__)
    n = dataset.num_segments if max_segments is None else min(max_segments, dataset.num_segments)
    gt = dataset.segment_boxes()[:n]
    scored = dataset.segment_scored()[:n]
    ious = np.full(n, np.nan)
    preds = np.full((n, 4), np.nan, np.float32)
    seconds = np.full(n, np.nan)  # tracker time per segment (init or update), NaN where not asked
    inits: list[int] = []
    spent, init_spent, tracked = 0.0, 0.0, 0
    energies: list[dict] = []
    init_energies: list[dict] = []
    need_init = True
    try:
        for seg in dataset.segments(0, n):
            i = seg.index
            box = gt[i]
            has_box = bool(scored[i]) and not (np.isnan(box).any() or box[2] < min_box_px or box[3] < min_box_px)
            if need_init:
                if not has_box:  # rules 2 and 5: wait for a segment with a box
                    continue
                start = time.perf_counter()
                tracker.init(seg, box.copy(), dataset.width, dataset.height)
                seconds[i] = time.perf_counter() - start
                init_spent += seconds[i]
                inits.append(i)
                init_energy = getattr(tracker, "energy_per_init", lambda: None)()  # counting is not tracking
                if init_energy is not None:
                    init_energies.append(init_energy)
                preds[i] = box
                need_init = False
                continue
            if reinitialise and scored[i] and not has_box:  # rule 2: skipped, re-initialised at the next box
                need_init = True
                continue
            start = time.perf_counter()
            pred = np.asarray(tracker.update(seg), dtype=np.float32).reshape(4)
            seconds[i] = time.perf_counter() - start
            spent += seconds[i]
            tracked += 1
            preds[i] = pred
            if not has_box:  # rule 5 (and one-pass): tracked between annotations, not scored
                continue
            ious[i] = float(iou_xywh(pred, box)) if np.all(np.isfinite(pred)) else 0.0
            energy = tracker.energy_per_segment()  # after the timed update: counting is not tracking
            if energy:
                energies.append(energy)
            if ious[i] < FAILURE_IOU and reinitialise:
                need_init = True
    except UserError:  # a damaged data file is bad input, not a tracker failure
        raise
    except Exception as exc:  # a crashing tracker fails this sequence only
        last = traceback.extract_tb(exc.__traceback__)[-1]
        return SequenceResult(name, dataset.name, np.full(n, np.nan), preds, inits, spent, tracked,
                              error=f"{exception_line(exc)} ({last.filename.split('/')[-1]}:{last.lineno})",
                              init_seconds=init_spent, segment_seconds=seconds)
    return SequenceResult(name, dataset.name, ious, preds, inits, spent, tracked, _mean_counts(energies),
                          init_seconds=init_spent, segment_seconds=seconds, init_energy=_mean_counts(init_energies))


def _mean_counts(records: list[dict]) -> dict | None:
    """The mean of each number the records share (None for none): a tracker's counts per segment or initialisation."""
    if not records:
        return None
    keys = set.intersection(*(set(e) for e in records))
    return {k: float(np.mean([e[k] for e in records])) for k in sorted(keys)
            if all(isinstance(e[k], (int, float)) for e in records)}
