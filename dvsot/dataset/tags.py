"""Challenge tags per segment from the ground truth a dataset file stores: one definition, with its thresholds, for
the exports (dvsot export's gt table and toolkit layouts) and for benchmarks' attributes.

A tag is decided at the segment's end, from /segments (visibility, absent, truncation, the amodal box); a tag the
file cannot measure (no visibility, no truncation) is left out, not guessed.

- absent: nothing of the target is seen (`/segments/absent`): wholly hidden on the sensor, or off it;
- out_of_view: absent because the target has left the sensor: truncation at least `OUT_OF_VIEW_TRUNCATION`, or
  (a file without truncation) no amodal box on the sensor. LaSOT's `out_of_view` (the target wholly outside
  the frame);
- full_occlusion: absent while on the sensor (hidden by occluders), LaSOT's `full_occlusion`;
- occlusion: less than `OCCLUSION_VISIBILITY` of the target's on-sensor silhouette seen, and not out of view
  (visibility counts on-sensor pixels only, so a target off the sensor is out of view, not occluded);
- cut_by_image: more than `CUT_BY_IMAGE_TRUNCATION` of the target's whole silhouette off the sensor while part of it
  is on the sensor (GOT-10k's `cut_by_image`, KITTI's `truncated`).

GOT-10k's `cover` (0-8) is the seen share of the whole silhouette, visibility x (1 - truncation), in GOT-10k's
bins: 0 none (and every absent segment), 1 (0, 15%], 2 (15%, 30%], ... 7 (90%, 100%), 8 all of it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from dvsot.dataset.reader import Dataset

# occlusion: visible share of the on-sensor silhouette below this (0..1): GOT-10k's cover 6 or less, a tenth hidden
OCCLUSION_VISIBILITY = 0.9
# cut_by_image: share of the whole silhouette off the sensor above this (0..1); the rasterised share of a
# silhouette that touches the sensor's edge is a few pixels off 0, which is not cut
CUT_BY_IMAGE_TRUNCATION = 0.01
# out_of_view: an absent target with at least this share of its silhouette off the sensor (0..1); an absent
# target with less is on the sensor and hidden (full_occlusion)
OUT_OF_VIEW_TRUNCATION = 0.5
# GOT-10k's cover bins: upper edges of the visible shares of cover 1..6 (cover 7 up to, not at, 100%)
COVER_EDGES = (0.15, 0.30, 0.45, 0.60, 0.75, 0.90)
TAGS = ("absent", "occlusion", "full_occlusion", "out_of_view", "cut_by_image")


def tags_from_truth(xywh: np.ndarray, visibility: np.ndarray | None, absent: np.ndarray | None,
                    truncation: np.ndarray | None) -> dict[str, np.ndarray]:
    """{tag: bool (M,)} of the TAGS these per-segment arrays can decide: xywh (M, 4) amodal boxes (pixels, NaN =
    none on the sensor), visibility (M,) 0..1, absent (M,) bool, truncation (M,) 0..1; None = not in the file."""
    on_sensor = np.isfinite(np.asarray(xywh, np.float64)).all(axis=1)
    out: dict[str, np.ndarray] = {}
    trunc = None if truncation is None else np.nan_to_num(np.asarray(truncation, np.float64), nan=1.0)
    if absent is not None:
        gone = np.asarray(absent, bool)
        off = ~on_sensor if trunc is None else (trunc >= OUT_OF_VIEW_TRUNCATION) | ~on_sensor
        out["absent"] = gone.copy()
        out["out_of_view"] = gone & off
        out["full_occlusion"] = gone & ~off
        if visibility is not None:
            seen = np.nan_to_num(np.asarray(visibility, np.float64), nan=1.0)
            out["occlusion"] = (seen < OCCLUSION_VISIBILITY) & ~out["out_of_view"]
    if trunc is not None:
        cut = on_sensor & (trunc > CUT_BY_IMAGE_TRUNCATION)
        out["cut_by_image"] = cut if "out_of_view" not in out else cut & ~out["out_of_view"]
    return {k: out[k] for k in TAGS if k in out}


def cover_label(visibility: np.ndarray, absent: np.ndarray, truncation: np.ndarray | None = None) -> np.ndarray:
    """GOT-10k's cover (int (M,), 0..8) of the seen share of the whole silhouette: visibility (M,) 0..1 times
    1 - truncation (M,) where given; 0 where absent (M,) is set or nothing is seen, 8 where all of it is."""
    seen = np.nan_to_num(np.asarray(visibility, np.float64), nan=0.0)
    if truncation is not None:
        seen = seen * (1.0 - np.nan_to_num(np.asarray(truncation, np.float64), nan=1.0))
    # binned at float32, the file's precision: a stored 0.6 (0.6000000238 as a double) is 60%, cover 4
    seen = seen.astype(np.float32)
    cover = 1 + np.searchsorted(np.asarray(COVER_EDGES, np.float32), seen, side="left")  # (0, 15%] -> 1 ... -> 7
    cover = np.where(seen >= 1.0, 8, cover)
    return np.where(np.asarray(absent, bool) | (seen <= 0.0), 0, cover).astype(np.int64)


def segment_tags(ds: Dataset) -> dict[str, np.ndarray]:
    """{tag: bool per segment} of the TAGS that ds's ground truth can decide (tags_from_truth)."""
    return tags_from_truth(ds.segment_boxes(), ds.segment_visibility(), ds.segment_absent(), ds.segment_truncation())
