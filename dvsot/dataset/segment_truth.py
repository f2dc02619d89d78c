"""The per-segment ground truth a dataset file stores under /segments, decided from the file's box track.

Segment i ends at (i + 1) * segment_us microseconds; its ground truth is the target at that end. A rendered
track is interpolated to the segment ends; annotations (a recording) are matched to them and never
interpolated (dvsot.dataset.boxes.match_annotations). Pure functions of arrays: the writer stores what they
return.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dvsot.dataset.boxes import interpolate_boxes, match_annotations
from dvsot.dataset.format import BoxTrack


@dataclass(frozen=True)
class SegmentTruth:
    """What /segments holds: t (M,) end times in microseconds; xywh, xywh_visible (M, 4) float32 pixels, NaN =
    absent; annotation (M,) the matched /boxes row or -1 (annotated files only); visibility (M,) float32 0..1 and
    absent (M,) bool (only where the track has visibility); truncation (M,) float32 0..1 (only where the track has
    truncation)."""

    t: np.ndarray
    xywh: np.ndarray
    xywh_visible: np.ndarray
    annotation: np.ndarray | None = None
    visibility: np.ndarray | None = None
    absent: np.ndarray | None = None
    truncation: np.ndarray | None = None


def segment_ends(duration_us: int, segment_us: int) -> np.ndarray:
    """The end time (microseconds, int64) of every whole segment of segment_us in a file of duration_us."""
    return (np.arange(duration_us // segment_us, dtype=np.int64) + 1) * segment_us


def matched_rows(rows: np.ndarray, match: np.ndarray) -> np.ndarray:
    """Per segment, the row (N, 4) that match names (-1 = none), float32; NaN rows where there is none."""
    nan = np.full((1, 4), np.nan, np.float32)
    # -1 indexes the appended NaN row
    return np.where((match >= 0)[:, None], np.concatenate([np.asarray(rows, np.float32), nan])[match], nan)


def interpolated_rows(t_samples: np.ndarray, rows: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """Rows (N, 4) sampled at t_samples (us) taken at the segment ends (us), linear between samples, float32; NaN
    outside the track, where a neighbouring row is NaN, and everywhere for an empty track."""
    return interpolate_boxes(t_samples, rows, ends).astype(np.float32)


def interpolated_visibility(t_samples: np.ndarray, visibility: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """A share (0..1: the visible fraction, the truncation) sampled at t_samples (us) taken at the segment ends (us),
    linear between samples, float32; NaN outside the track."""
    columns = np.repeat(np.asarray(visibility)[:, None], 4, 1)  # interpolate_boxes works on 4 columns
    return interpolate_boxes(t_samples, columns, ends)[:, 0].astype(np.float32)


def absent_at(xywh: np.ndarray, xywh_visible: np.ndarray) -> np.ndarray:
    """True per row where nothing of the target is there: its box or its visible box (M, 4) has a NaN."""
    return np.isnan(xywh_visible).any(axis=1) | np.isnan(xywh).any(axis=1)


def segment_truth(track: BoxTrack, duration_us: int, segment_us: int, annotated: bool = False) -> SegmentTruth:
    """The ground truth of every whole segment of a file of duration_us (us): the track's boxes matched to the segment
    ends if annotated, else interpolated to them; visibility and absence only where the track has visibility."""
    ends = segment_ends(duration_us, segment_us)
    match = None
    if annotated:
        match = match_annotations(track.t, segment_us, len(ends))
        xywh, visible = matched_rows(track.xywh, match), matched_rows(track.xywh_visible, match)
    else:
        xywh = interpolated_rows(track.t, track.xywh, ends)
        visible = interpolated_rows(track.t, track.xywh_visible, ends)
    def share(values: np.ndarray | None) -> np.ndarray | None:
        return None if values is None else interpolated_visibility(track.t, values, ends)

    if track.visibility is None:
        return SegmentTruth(ends, xywh, visible, match, truncation=share(track.truncation))
    return SegmentTruth(ends, xywh, visible, match, share(track.visibility), absent_at(xywh, visible),
                        share(track.truncation))
