"""Challenge attributes of each segment, measured from a file's ground truth, and scores per attribute.

Every threshold lives in `THRESHOLDS` (docs/benchmarks.md, "Scores per attribute", says what each
means). An attribute a file cannot measure (no visibility, no labels, no scene) is left out for that
file: its segments count neither as having it nor as lacking it.

- occlusion: the visible share of the target's pixels at the segment's end below `occlusion_visibility`;
- absent: nothing of the target visible at the segment's end, or outside the sensor (`/segments/absent`);
- fast_motion: the ground-truth box centre moving faster than `fast_px_per_ms` since the previous segment;
- small_target: the ground-truth box's area below `small_area_px`;
- low_event_density: events inside the ground-truth box fewer than `low_density` per pixel per millisecond;
- rotation: the target turning faster than `rotation_deg_per_s` relative to the camera (scene file);
- camera_motion: the camera moving faster than `camera_m_per_s` or turning faster than `camera_deg_per_s`
  (scene file);
- distractor_nearby: at least `distractor_share` of the events in the box grown by half its size on each
  side made by distractors (per-event labels).

The table, JSON and bar chart of the scores per attribute: benchmarks.analysis.attribute_tables.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from benchmarks.evaluation.metrics import ALL, Scores, pooled
from benchmarks.evaluation.protocol import SequenceResult
from dvsot.dataset import Dataset

ATTRIBUTES = ("occlusion", "absent", "fast_motion", "small_target", "low_event_density", "rotation",
              "camera_motion", "distractor_nearby")


@dataclass(frozen=True)
class Thresholds:
    """The attributes' cuts: visibility 0..1, px/ms, px^2, events/px/ms, deg/s, m/s, share 0..1."""

    occlusion_visibility: float = 0.5
    fast_px_per_ms: float = 0.3
    small_area_px: float = 400.0
    low_density: float = 0.01
    rotation_deg_per_s: float = 90.0
    camera_m_per_s: float = 0.1
    camera_deg_per_s: float = 5.0
    distractor_share: float = 0.1


THRESHOLDS = Thresholds()


def segment_attributes(ds: Dataset, n: int | None = None, th: Thresholds = THRESHOLDS) -> dict[str, np.ndarray]:
    """{attribute: bool per segment} for the first n segments of ds, for the attributes the file can measure."""
    n = ds.num_segments if n is None else min(n, ds.num_segments)
    box = ds.segment_boxes()[:n].astype(np.float64)
    have = np.isfinite(box).all(axis=1)
    out: dict[str, np.ndarray] = {}
    vis, absent = ds.segment_visibility(), ds.segment_absent()
    if vis is not None:
        out["occlusion"] = np.nan_to_num(vis[:n], nan=1.0) < th.occlusion_visibility
        out["absent"] = absent[:n].copy()
    centre = box[:, :2] + box[:, 2:] / 2
    step = np.full(n, np.nan)
    if n > 1:
        step[1:] = np.hypot(*(centre[1:] - centre[:-1]).T)
        step[0] = step[1]  # the first segment moves as the second does
    out["fast_motion"] = np.nan_to_num(step / (ds.segment_us / 1000.0), nan=0.0) > th.fast_px_per_ms
    out["small_target"] = have & (box[:, 2] * box[:, 3] < th.small_area_px)
    distractors = [r["id"] for r in ds.objects or () if r["role"] == "distractor"]
    density, share = _event_measures(ds, box, n, np.array(distractors, np.int64))
    out["low_event_density"] = have & (density < th.low_density)
    if ds.objects is not None:
        out["distractor_nearby"] = have & (share >= th.distractor_share)
    motion = _scene_motion(ds, n)
    if motion is not None:
        target_deg, camera_m, camera_deg = motion
        out["rotation"] = target_deg > th.rotation_deg_per_s
        out["camera_motion"] = (camera_m > th.camera_m_per_s) | (camera_deg > th.camera_deg_per_s)
    return {k: out[k] for k in ATTRIBUTES if k in out}


def _event_measures(ds: Dataset, box: np.ndarray, n: int, distractors: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per segment: events in the box per px per ms, and the distractors' share of the events in the grown box."""
    density, share = np.zeros(n), np.zeros(n)
    ms = ds.segment_us / 1000.0
    for i in np.flatnonzero(np.isfinite(box).all(axis=1)):
        seg = ds.segment(int(i))
        ev = seg.events
        x, y, w, h = box[i]
        ex, ey = ev.x + 0.5, ev.y + 0.5  # pixel centres
        inside = (ex >= x) & (ex < x + w) & (ey >= y) & (ey < y + h)
        density[i] = np.count_nonzero(inside) / max(w * h, 1.0) / ms
        if ev.object is not None and len(distractors):
            near = (ex >= x - w / 2) & (ex < x + 1.5 * w) & (ey >= y - h / 2) & (ey < y + 1.5 * h)
            k = np.count_nonzero(near)
            share[i] = np.count_nonzero(near & np.isin(ev.object, distractors)) / k if k else 0.0
    return density, share


def _rotation_deg(r0: np.ndarray, r1: np.ndarray) -> np.ndarray:
    """Angle (degrees) of the rotation from r0 to r1, for stacks of 3x3 rotation matrices."""
    cos = (np.einsum("nji,nji->n", r0, r1) - 1.0) / 2.0  # trace(r0^T r1)
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


def _scene_motion(ds: Dataset, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Per segment (from its start to its end): the target's rotation relative to the camera (deg/s), the camera's
    speed (m/s) and turn rate (deg/s), from the scene the file was rendered from; None without one."""
    resolved = ds.attrs.get("scene_resolved")
    if not isinstance(resolved, dict):
        return None
    from dvsot.scene import SceneConfig
    from dvsot.scene.trajectory import pose_and_scale

    try:
        cfg = SceneConfig.model_validate(resolved)
    except ValueError:  # a scene this dvsot no longer reads: the attributes that need it are left out
        return None
    seconds = ds.segment_us / 1e6
    times = np.arange(n + 1) * seconds
    cam_seed, target_seed = cfg.derived_seed("camera_shake"), cfg.derived_seed("shake:target")
    cams = np.stack([pose_and_scale(cfg.camera, float(t), cam_seed)[0] for t in times])
    targets = np.stack([pose_and_scale(cfg.target.trajectory, float(t), target_seed)[0] for t in times])
    relative = np.einsum("nji,njk->nik", cams[:, :3, :3], targets[:, :3, :3])  # camera^T target
    target_deg = _rotation_deg(relative[:-1], relative[1:]) / seconds
    camera_m = np.linalg.norm(cams[1:, :3, 3] - cams[:-1, :3, 3], axis=1) / seconds
    camera_deg = _rotation_deg(cams[:-1, :3, :3], cams[1:, :3, :3]) / seconds
    return target_deg, camera_m, camera_deg


def add_attributes(result: SequenceResult, ds: Dataset) -> SequenceResult:
    """Store the segments' attributes (bool arrays, as long as result.iou) in result.extra['attributes']."""
    result.extra["attributes"] = segment_attributes(ds, len(result.iou))
    return result


def _masks(results: list[SequenceResult]) -> dict[str, list[tuple[SequenceResult, np.ndarray]]]:
    """{'all' or attribute: [(result, mask of its segments)]} over the results that measured it."""
    out: dict[str, list] = {ALL: [(r, np.ones(len(r.iou), bool)) for r in results]}
    for name in ATTRIBUTES:
        rows = [(r, r.extra.get("attributes", {})[name]) for r in results
                if name in r.extra.get("attributes", {})]
        if rows:
            out[name] = rows
    return out


def attribute_scores(results: list[SequenceResult]) -> dict[str, dict[str, Scores]]:
    """{tracker: {'all' and each attribute: A, R, ARscore pooled over the counted segments with it}}."""
    out: dict[str, dict[str, Scores]] = {}
    for tracker in dict.fromkeys(r.tracker for r in results):
        ok = [r for r in results if r.tracker == tracker and r.error is None]
        out[tracker] = {name: pooled([np.where(m, r.iou, np.nan) for r, m in rows])
                        for name, rows in _masks(ok).items()}
    return out


def attribute_ope(results: list[SequenceResult]) -> dict[str, dict[str, dict]]:
    """{tracker: {'all' and each attribute: success AUC, precision at 20 px, counted segments}} of one-pass runs."""
    from benchmarks.evaluation.ope import PRECISION_PX, precision_curve, success_curve

    out: dict[str, dict[str, dict]] = {}
    for tracker in dict.fromkeys(r.tracker for r in results):
        ok = [r for r in results if r.tracker == tracker and r.error is None]
        per = {}
        for name, rows in _masks(ok).items():
            iou = np.concatenate([np.where(m, r.iou, np.nan) for r, m in rows]) if rows else np.empty(0)
            err = np.concatenate([np.where(m, r.extra["centre_error"], np.nan) for r, m in rows]) if rows else iou
            s = success_curve(iou)
            per[name] = {"AUC": float(np.mean(s)), f"P@{PRECISION_PX}": float(precision_curve(err)[PRECISION_PX]),
                         "segments": int(np.count_nonzero(~np.isnan(iou)))}
        out[tracker] = per
    return out
