"""Challenge attributes of each segment, measured from a file's ground truth in image terms, and scores per attribute.

`segment_measures(ds, n)` gives each segment's raw measures and `segment_attributes(ds, n)` the attributes,
{name: bool per segment}, cut by `THRESHOLDS` (docs/benchmarks.md, "Scores per attribute", gives each cut's
rationale). Every measure is in image terms at the file's own resolution, scaled where a pixel count would
depend on it (to 640x480, `REFERENCE_PX`), so one scene rendered at two resolutions is tagged alike. An
attribute a file cannot measure (no visibility, no truncation, no labels, no scene) is left out for that
file: its segments count neither as having it nor as lacking it.

The names (what exports and tables call them):

- occlusion: the visible share of the target's on-sensor pixels at the segment's end below `occlusion_visibility`;
- absent: nothing of the target visible at the segment's end, or outside the sensor (`/segments/absent`);
- out_of_view: at least `out_of_view_truncation` of the target's whole silhouette off the sensor (LaSOT's
  out_of_view; `/segments/truncation`);
- cut_by_image: any of the target's silhouette off the sensor (truncation above `CUT_BY_IMAGE_TRUNCATION`, 0.01,
  dvsot.dataset.tags: GOT-10k's cut_by_image);
- fast_motion: the ground-truth box centre moving more than `fast_sizes_per_segment` target sizes (the square root
  of the box's area) since the previous segment;
- small_target: the ground-truth box's area, scaled to a 640x480 sensor, below `small_area_px`;
- low_event_density: events inside the ground-truth box fewer than `low_density` per pixel per millisecond;
- rotation: the target's projected orientation turning faster than `rotation_deg_per_s` (scene file);
- camera_motion: the background's image moving faster than `camera_px_per_ms` at 640x480 (scene file);
- distractor_nearby: at least `distractor_share` of the events in the box grown by half its size on each
  side made by distractors (per-event labels).

The table, JSON and bar chart of the scores per attribute: benchmarks.analysis.attribute_tables.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from benchmarks.evaluation.metrics import ALL, Scores, pooled
from benchmarks.evaluation.protocol import SequenceResult
from dvsot.dataset import Dataset
from dvsot.dataset.tags import CUT_BY_IMAGE_TRUNCATION, OCCLUSION_VISIBILITY, OUT_OF_VIEW_TRUNCATION

ATTRIBUTES = ("occlusion", "absent", "out_of_view", "cut_by_image", "fast_motion", "small_target",
              "low_event_density", "rotation", "camera_motion", "distractor_nearby")
REFERENCE_PX = (640, 480)  # pixel speeds are given at this sensor size (DVSOT21's) and scaled from the file's


@dataclass(frozen=True)
class Thresholds:
    """The attributes' cuts: visibility and truncation 0..1, target sizes per segment, px^2 at 640x480, events/px/ms,
    deg/s of projected orientation, px/ms at 640x480, share of events 0..1."""

    occlusion_visibility: float = OCCLUSION_VISIBILITY  # the exports' tags use the same cuts (dvsot.dataset.tags)
    out_of_view_truncation: float = OUT_OF_VIEW_TRUNCATION
    cut_by_image_truncation: float = CUT_BY_IMAGE_TRUNCATION  # a silhouette touching the edge rasterises a few px off
    fast_sizes_per_segment: float = 0.05
    small_area_px: float = 400.0
    low_density: float = 0.01
    rotation_deg_per_s: float = 45.0
    camera_px_per_ms: float = 0.1
    distractor_share: float = 0.1


THRESHOLDS = Thresholds()


def segment_measures(ds: Dataset, n: int | None = None) -> dict[str, np.ndarray]:
    """{measure: float per segment} for the first n segments of ds, for what the file can measure: visibility and
    truncation (0..1), absent (0/1), motion (target sizes per segment), area_share (box area / sensor area),
    density (events/px/ms), distractor_share (0..1), rotation (deg/s) and camera (background px/ms at 640x480)."""
    n = ds.num_segments if n is None else min(n, ds.num_segments)
    box = ds.segment_boxes()[:n].astype(np.float64)
    out: dict[str, np.ndarray] = {}
    vis, absent, trunc = ds.segment_visibility(), ds.segment_absent(), ds.segment_truncation()
    if vis is not None:
        out["visibility"] = vis[:n].astype(np.float64)
        out["absent"] = absent[:n].astype(np.float64)
    if trunc is not None:
        out["truncation"] = trunc[:n].astype(np.float64)
    centre = box[:, :2] + box[:, 2:] / 2
    step = np.full(n, np.nan)
    if n > 1:
        step[1:] = np.hypot(*(centre[1:] - centre[:-1]).T)
        step[0] = step[1]  # the first segment moves as the second does
    with np.errstate(invalid="ignore", divide="ignore"):
        out["motion"] = step / np.sqrt(box[:, 2] * box[:, 3])
    out["area_share"] = box[:, 2] * box[:, 3] / (ds.width * ds.height)
    distractors = [r["id"] for r in ds.objects or () if r["role"] == "distractor"]
    density, share = _event_measures(ds, box, n, np.array(distractors, np.int64))
    out["density"] = density
    if ds.objects is not None:
        out["distractor_share"] = share
    motion = _scene_motion(ds, n)
    if motion is not None:
        out["rotation"], out["camera"] = motion
    return out


def segment_attributes(ds: Dataset, n: int | None = None, th: Thresholds = THRESHOLDS) -> dict[str, np.ndarray]:
    """{attribute: bool per segment} for the first n segments of ds, for the attributes the file can measure
    (names and meanings: this module's docstring, in ATTRIBUTES' order)."""
    m = segment_measures(ds, n)
    have = np.isfinite(m["area_share"])  # a segment with a ground-truth box
    out: dict[str, np.ndarray] = {}
    if "visibility" in m:
        out["occlusion"] = np.nan_to_num(m["visibility"], nan=1.0) < th.occlusion_visibility
        out["absent"] = m["absent"] > 0
    if "truncation" in m:
        trunc = np.nan_to_num(m["truncation"], nan=1.0)  # NaN: outside the track, wholly off the sensor
        out["out_of_view"] = trunc >= th.out_of_view_truncation
        out["cut_by_image"] = trunc > th.cut_by_image_truncation
    out["fast_motion"] = np.nan_to_num(m["motion"], nan=0.0) > th.fast_sizes_per_segment
    out["small_target"] = have & (m["area_share"] * (REFERENCE_PX[0] * REFERENCE_PX[1]) < th.small_area_px)
    out["low_event_density"] = have & (m["density"] < th.low_density)
    if "distractor_share" in m:
        out["distractor_nearby"] = have & (m["distractor_share"] >= th.distractor_share)
    if "rotation" in m:
        out["rotation"] = m["rotation"] > th.rotation_deg_per_s
        out["camera_motion"] = m["camera"] > th.camera_px_per_ms
    return {k: out[k] for k in ATTRIBUTES if k in out}


def _event_measures(ds: Dataset, box: np.ndarray, n: int, distractors: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per segment: events in the box per px per ms, and the distractors' share of the events in the grown box."""
    density, share = np.zeros(n), np.zeros(n)
    ms = ds.segment_us / 1000.0
    for i in np.flatnonzero(np.isfinite(box).all(axis=1)):
        ev = ds.events(int(i) * ds.segment_us, (int(i) + 1) * ds.segment_us)
        x, y, w, h = box[i]
        ex, ey = ev.x + 0.5, ev.y + 0.5  # pixel centres
        inside = (ex >= x) & (ex < x + w) & (ey >= y) & (ey < y + h)
        density[i] = np.count_nonzero(inside) / max(w * h, 1.0) / ms
        if ev.object is not None and len(distractors):
            near = (ex >= x - w / 2) & (ex < x + 1.5 * w) & (ey >= y - h / 2) & (ey < y + 1.5 * h)
            k = np.count_nonzero(near)
            share[i] = np.count_nonzero(near & np.isin(ev.object, distractors)) / k if k else 0.0
    return density, share


def _target_points(target) -> np.ndarray:
    """Up to 256 of the target's unit-size mesh vertices (object coordinates, metres before size_m), or a cube's
    corners where its mesh file cannot be read here."""
    from dvsot.core.errors import UserError
    from dvsot.scene.shapes import mesh_for

    try:
        v = np.asarray(mesh_for(target.shape, target.mesh)[0], np.float64)
    except (UserError, OSError, ValueError, KeyError):
        v = np.array([[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)])
    return v[:: max(1, len(v) // 256)] * target.size_m


def _project(points: np.ndarray, cams: np.ndarray, k) -> np.ndarray:
    """Pixel positions (T, P, 2) of world points (T, P, 3), each row seen from its camera pose (T, 4, 4, Blender
    camera axes); NaN behind the camera (dvsot.scene.trajectory.project, for a pose per row)."""
    q = np.einsum("tpi,tij->tpj", points - cams[:, None, :3, 3], cams[:, :3, :3])  # x right, y up, -z forward
    depth = -q[..., 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        out = np.stack([k.cx + k.fx * q[..., 0] / depth, k.cy - k.fx * q[..., 1] / depth], axis=-1)
    out[depth <= 1e-6] = np.nan
    return out


def _projected_turn(points: np.ndarray, poses: np.ndarray, cams: np.ndarray, k) -> np.ndarray:
    """Per step t -> t+1, the target's projected orientation change (radians): the mean image displacement of its
    points about their projected centre, over their mean distance from it (an in-plane turn by a reads a)."""
    world = np.einsum("pj,tij->tpi", points, poses[:, :3, :3]) + poses[:, None, :3, 3]
    q = _project(world, cams, k) - _project(poses[:, None, :3, 3], cams, k)  # (times, points, 2) about the centre
    with np.errstate(invalid="ignore", divide="ignore"), warnings.catch_warnings():  # behind the camera: 0
        warnings.simplefilter("ignore", RuntimeWarning)
        radius = np.nanmean(np.hypot(q[..., 0], q[..., 1]), axis=1)
        moved = np.nanmean(np.linalg.norm(q[1:] - q[:-1], axis=2), axis=1)
        return np.nan_to_num(moved / np.maximum(radius[:-1], 1e-9), nan=0.0)


def _background_motion(cfg, cams: np.ndarray, k) -> np.ndarray:
    """Per step t -> t+1, the median image motion (pixels) of the background seen through a 16 x 12 grid of pixels:
    each ray's hit on the background plane (or its direction, for the environment or a ray past the plane) seen
    again from the next camera pose."""
    from dvsot.scene.schema import Trajectory
    from dvsot.scene.trajectory import pose_and_scale

    u, v = np.meshgrid((np.arange(16) + 0.5) * k.width / 16, (np.arange(12) + 0.5) * k.height / 12)
    before = np.stack([u.ravel(), v.ravel()], axis=1)
    rays_cam = np.stack([(before[:, 0] - k.cx) / k.fx, -(before[:, 1] - k.cy) / k.fx, -np.ones(len(before))], axis=1)
    c0, c1 = cams[:-1], cams[1:]
    rays = np.einsum("gj,tij->tgi", rays_cam, c0[:, :3, :3])  # (steps, rays, 3) in the world
    origin = c0[:, None, :3, 3]
    far = np.ones(rays.shape[:2], bool)
    points = np.zeros_like(rays)
    if cfg.background.kind == "plane":
        spec = {"keyframes": [{"t": 0, "location": list(cfg.background.location),
                               "rotation_deg": list(cfg.background.rotation_deg)}]}
        plane = pose_and_scale(Trajectory.model_validate(spec), 0.0)[0]
        normal, centre = plane[:3, 2], plane[:3, 3]
        with np.errstate(divide="ignore", invalid="ignore"):
            s = ((centre - origin) @ normal) / (rays @ normal)
            hit = origin + s[..., None] * rays
            on = (s > 0) & np.all(np.abs((hit - centre) @ plane[:3, :2]) <= cfg.background.size_m / 2, axis=-1)
        points[on], far = hit[on], ~on
    # a ray past the plane sees the environment at infinity: its direction alone, from the next camera's place
    points = np.where(far[..., None], c1[:, None, :3, 3] + rays * 1e6, points)
    moved = np.linalg.norm(_project(points, c1, k) - before[None], axis=-1)
    with warnings.catch_warnings():  # a step with every ray behind the camera: no motion measured, 0
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.nan_to_num(np.nanmedian(np.where(np.isfinite(moved), moved, np.nan), axis=1), nan=0.0)


def _scene_motion(ds: Dataset, n: int) -> tuple[np.ndarray, np.ndarray] | None:
    """Per segment (from its start to its end): the target's projected orientation change (deg/s) and the
    background's image motion (px/ms at 640x480), from the scene the file was rendered from; None without one."""
    resolved = ds.attrs.get("scene_resolved")
    if not isinstance(resolved, dict):
        return None
    from dvsot.scene import SceneConfig
    from dvsot.scene.trajectory import pose_and_scale

    try:
        cfg = SceneConfig.model_validate(resolved)
    except ValueError:  # a scene this dvsot no longer reads: the attributes that need it are left out
        return None
    k = cfg.sensor.intrinsics()
    seconds = ds.segment_us / 1e6
    times = np.arange(n + 1) * seconds
    cam_seed, target_seed = cfg.derived_seed("camera_shake"), cfg.derived_seed("shake:target")
    cams = np.stack([pose_and_scale(cfg.camera, float(t), cam_seed)[0] for t in times])
    poses = []
    for t in times:
        pose, scale = pose_and_scale(cfg.target.trajectory, float(t), target_seed)
        pose = pose.copy()
        pose[:3, :3] = pose[:3, :3] * scale
        poses.append(pose)
    turn = np.degrees(_projected_turn(_target_points(cfg.target), np.stack(poses), cams, k)) / seconds
    scale = np.hypot(*REFERENCE_PX) / np.hypot(k.width, k.height)
    camera = _background_motion(cfg, cams, k) * scale / (seconds * 1000.0)
    return turn, camera
def add_attributes(result: SequenceResult, ds: Dataset) -> SequenceResult:
    """Store the segments' attributes (bool arrays, as long as result.iou) in result.extra['attributes']."""
    result.extra["attributes"] = segment_attributes(ds, len(result.iou))
    return result


def _scored(results: list[SequenceResult], error: str | None = None) -> dict[str, list[np.ndarray]]:
    """{'all' or attribute: per result that measured it, its IoUs (or the extra[error] values) on the segments with
    it, NaN elsewhere}. The `absent` column holds the hidden segments scored apart (protocol rule 6); it is left
    out when every result skipped them (skip_absent)."""
    def values(r: SequenceResult, hidden: bool = False) -> np.ndarray:
        if error is None:
            return r.hidden_iou if hidden else r.iou
        return r.extra.get(f"hidden_{error}", np.full(len(r.iou), np.nan)) if hidden else r.extra[error]

    out: dict[str, list[np.ndarray]] = {ALL: [values(r) for r in results]}
    for name in ATTRIBUTES:
        rows = [r for r in results if name in r.extra.get("attributes", {})]
        if name == "absent":
            rows = [r for r in rows if r.hidden_iou is not None]
            if rows:
                out[name] = [np.where(r.extra["attributes"][name], values(r, True), np.nan) for r in rows]
        elif rows:
            out[name] = [np.where(r.extra["attributes"][name], values(r), np.nan) for r in rows]
    return out


def attribute_scores(results: list[SequenceResult]) -> dict[str, dict[str, Scores]]:
    """{tracker: {'all' and each attribute: A, R, ARscore pooled over the tracker's counted segments with it}};
    `absent`: over its hidden segments, scored apart (protocol rule 6)."""
    out: dict[str, dict[str, Scores]] = {}
    for tracker in dict.fromkeys(r.tracker for r in results):
        ok = [r for r in results if r.tracker == tracker and r.error is None]
        out[tracker] = {name: pooled(rows) for name, rows in _scored(ok).items()}
    return out


def attribute_ope(results: list[SequenceResult]) -> dict[str, dict[str, dict]]:
    """{tracker: {'all' and each attribute: success AUC, precision at 20 px, the tracker's counted segments}} of
    one-pass runs; `absent`: over its hidden segments, scored apart (protocol rule 6)."""
    from benchmarks.evaluation.ope import PRECISION_PX, precision_curve, success_curve

    out: dict[str, dict[str, dict]] = {}
    for tracker in dict.fromkeys(r.tracker for r in results):
        ok = [r for r in results if r.tracker == tracker and r.error is None]
        errors = _scored(ok, "centre_error")
        per = {}
        for name, rows in _scored(ok).items():
            iou = np.concatenate(rows) if rows else np.empty(0)
            err = np.concatenate(errors[name]) if rows else iou
            s = success_curve(iou)
            per[name] = {"AUC": float(np.mean(s)), f"P@{PRECISION_PX}": float(precision_curve(err)[PRECISION_PX]),
                         "segments": int(np.count_nonzero(~np.isnan(iou)))}
        out[tracker] = per
    return out
