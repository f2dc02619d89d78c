"""The tracking protocol with re-initialisation (paper §3.2), the same for every tracker.

Which segments count (written here once, used for every tracker):

1. A sequence is cut into segments of `segment_us` (10 ms); segment i's ground truth is the target's
   box at the segment's end.
2. A segment whose ground truth is absent (NaN: target out of view) or degenerate (width or height
   below `min_box_px`, default 1 px) is skipped: not counted, nothing is asked of the tracker, and the
   tracker is initialised again on the next segment with a ground truth (and a visible target, rule 6).
3. The tracker is initialised with the ground truth on the first segment with a box and a visible
   target, and again on the next such segment after each failure. Initialisation segments are given,
   not tracked: they do not count.
4. Every other segment with a visible target counts: the tracker predicts a box; IoU with the ground
   truth; a failure when IoU < 0.5, which triggers re-initialisation on the next such segment.
5. A recording's ground truth exists only at its annotations (`Dataset.annotated`): a segment without
   an annotation matched to it (dvsot.dataset.boxes.match_annotations) is tracked (the tracker predicts on it)
   but neither scored nor able to fail; rules 2-4 apply to the matched segments, so initialisation and
   re-initialisation wait for the next matched segment with a box. A rendered file matches every segment.
6. A hidden target (`/segments/absent` = 1 with an amodal box: on the sensor, wholly covered) is never
   initialised on: (re-)initialisation waits for the next segment whose target is visible. A hidden segment
   the tracker meets while tracking is tracked and scored apart, as VOT-LT treats full occlusion: neither
   a success nor a failure, not in A, R or the success curve, its IoU with the amodal box kept in
   `SequenceResult.hidden_iou` (the `absent` column of the attribute tables). With `skip_absent` (GOT-10k's
   rule: frames with cover 0 are not scored) hidden segments are tracked and not scored at all.
   `segment_rules` gives these roles per segment, for this protocol, the one-pass one and any other.

Speed is tracker time only (init + update calls), not reading the file.
"""

from __future__ import annotations

import time
import traceback
from dataclasses import dataclass, field

import numpy as np

from benchmarks.evaluation.metrics import FAILURE_IOU
from benchmarks.trackers.base import Tracker
from dvsot.core.errors import UserError, exception_line
from dvsot.dataset import Dataset
from dvsot.dataset.boxes import iou_xywh

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
    hidden_iou: np.ndarray | None = None  # rule 6: IoU on hidden segments scored apart (NaN elsewhere); None: skipped

    @property
    def segments_per_s(self) -> float:
        """Tracked segments per second of update time (initialisations not included: init_seconds)."""
        return self.tracked_segments / self.tracker_seconds if self.tracker_seconds > 0 else float("nan")


@dataclass(frozen=True)
class SegmentRules:
    """The protocol's roles per segment (rules 2, 5 and 6), bool arrays of one length: `scored` (matched to ground
    truth), `visible` (scored, a usable box, the target not wholly hidden: may initialise, counts, may fail),
    `hidden` (scored, a usable box, the target wholly hidden), `resets` (scored without a usable box: tracking
    stops, re-initialisation waits) and `apart` (hidden segments scored apart; none with skip_absent)."""

    scored: np.ndarray
    visible: np.ndarray
    hidden: np.ndarray
    resets: np.ndarray
    apart: np.ndarray


def segment_rules(dataset: Dataset, n: int | None = None, min_box_px: float = MIN_BOX_PX,
                  skip_absent: bool = False) -> SegmentRules:
    """The roles of the first n segments of dataset under rules 2, 5 and 6 (min_box_px: pixels a side)."""
    n = dataset.num_segments if n is None else min(n, dataset.num_segments)
    gt, scored = dataset.segment_boxes()[:n], dataset.segment_scored()[:n]
    with np.errstate(invalid="ignore"):
        boxed = scored & ~np.isnan(gt).any(axis=1) & (gt[:, 2] >= min_box_px) & (gt[:, 3] >= min_box_px)
    absent = dataset.segment_absent()
    hidden = boxed & (absent[:n] if absent is not None else np.zeros(n, bool))
    return SegmentRules(scored, boxed & ~hidden, hidden, scored & ~boxed,
                        np.zeros(n, bool) if skip_absent else hidden.copy())


def nothing_to_score(path, max_segments: int | None = None, reinitialise: bool = True,
                     min_box_px: float = MIN_BOX_PX) -> str | None:
    """Why the protocol would score no segment of the dataset file at path (its first max_segments), or None.

    A segment is scored when its target is visible with a usable box (rules 2, 5 and 6) and follows the segment
    the tracker was initialised on; with re-initialisation, an unusable scored segment in between starts over
    (rule 2), while a hidden one in between does not (rule 6).
    """
    with Dataset(path) as ds:
        n = ds.num_segments if max_segments is None else min(max_segments, ds.num_segments)
        rules = segment_rules(ds, n, min_box_px)
    u = rules.visible[rules.scored & ~rules.hidden]
    if (u[:-1] & u[1:]).any() if reinitialise else u.sum() >= 2:
        return None
    hidden = f", {int(rules.hidden.sum())} more with the target wholly hidden" if rules.hidden.any() else ""
    return (f"{path}: no segment of {n} can be scored: the protocol needs a segment with a visible target and a "
            f"ground-truth box at least {min_box_px:g} px wide and high to initialise on, and one after it "
            f"({int(rules.visible.sum())} such segments{hidden}"
            f"{', none two in a row' if reinitialise and rules.visible.any() else ''})")


def run_sequence(tracker: Tracker, dataset: Dataset, tracker_name: str | None = None,
                 min_box_px: float = MIN_BOX_PX, max_segments: int | None = None,
                 reinitialise: bool = True, skip_absent: bool = False) -> SequenceResult:
    """Run one tracker over one sequence with re-initialisation on failure; a crash is recorded, not raised.

    reinitialise=False is the one-pass protocol (benchmarks/evaluation/ope.py): one initialisation, then the
    tracker predicts every later segment, failed or without ground truth, and only boxes are scored.
    skip_absent=True leaves hidden segments unscored (rule 6, GOT-10k's way) instead of scoring them apart.
    """
    name = tracker_name or getattr(tracker, "name", type(tracker).__name__)
    n = dataset.num_segments if max_segments is None else min(max_segments, dataset.num_segments)
    gt = dataset.segment_boxes()[:n]
    rules = segment_rules(dataset, n, min_box_px, skip_absent)
    ious = np.full(n, np.nan)
    hidden_ious = np.full(n, np.nan)
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
            if need_init:
                if not rules.visible[i]:  # rules 2, 5 and 6: wait for a segment with a box and a visible target
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
            if reinitialise and rules.resets[i]:  # rule 2: skipped, re-initialised at the next visible box
                need_init = True
                continue
            start = time.perf_counter()
            pred = np.asarray(tracker.update(seg), dtype=np.float32).reshape(4)
            seconds[i] = time.perf_counter() - start
            spent += seconds[i]
            tracked += 1
            preds[i] = pred
            if rules.apart[i]:  # rule 6: a hidden target, scored apart, neither success nor failure
                hidden_ious[i] = float(iou_xywh(pred, box)) if np.all(np.isfinite(pred)) else 0.0
                continue
            if not rules.visible[i]:  # rules 5, 6 (skip_absent) and one-pass: tracked, not scored
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
                          init_seconds=init_spent, segment_seconds=seconds, init_energy=_mean_counts(init_energies),
                          hidden_iou=None if skip_absent else hidden_ious)


def _mean_counts(records: list[dict]) -> dict | None:
    """The mean of each number the records share (None for none): a tracker's counts per segment or initialisation."""
    if not records:
        return None
    keys = set.intersection(*(set(e) for e in records))
    return {k: float(np.mean([e[k] for e in records])) for k in sorted(keys)
            if all(isinstance(e[k], (int, float)) for e in records)}
