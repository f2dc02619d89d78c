"""Scenes that validate but make no sense: refused (a look_at on its own location) or warned about (a target
never in view, or filling the whole frame, for the whole sequence). Pure numpy, no renderer."""

from __future__ import annotations

import numpy as np

from dvsot.scene.shapes import mesh_for, sample_points
from dvsot.scene.trajectory import interpolate, pose_and_scale, pose_matrix, project

CHECK_TIMES = 200  # evenly spaced times (and every keyframe time) the checks look at
_MIN_LOOK_M = 1e-6  # look_at closer than this to the location gives no direction
_FILL = 0.95  # a target box covering this share of the image "fills the frame"


def _times(keyframe_times: list[float], duration_s: float) -> np.ndarray:
    """Evenly spaced times over [0, duration_s] (seconds) plus the keyframe times inside it."""
    t = np.concatenate([np.linspace(0.0, duration_s, CHECK_TIMES), [k for k in keyframe_times if k <= duration_s]])
    return np.unique(t)


def _closest(f, a: float, b: float, steps: int = 80) -> float:
    """The t in [a, b] where f is smallest, by golden-section search (f unimodal there: near a sampled minimum)."""
    g = (np.sqrt(5) - 1) / 2
    for _ in range(steps):
        c, d = b - g * (b - a), a + g * (b - a)
        if f(c) <= f(d):
            b = d
        else:
            a = c
    return (a + b) / 2


def _track_at(keys: list, attr: str, t: float, smooth: bool) -> np.ndarray:
    """The keyframes' `attr` (location or look_at, metres) interpolated at time t (seconds), as poses are."""
    pairs = [(k.t, getattr(k, attr)) for k in keys if getattr(k, attr) is not None]
    return interpolate(np.array([p[0] for p in pairs]), np.array([p[1] for p in pairs]), t, smooth)


def look_at_problems(cfg) -> list[tuple[tuple, str]]:
    """(field location, message) for each trajectory whose look_at meets its own location at some time:
    sampled, then the closest approach refined, so a pass through the point between samples is found too."""
    out = []
    for loc, traj in [(("camera",), cfg.camera), (("target", "trajectory"), cfg.target.trajectory)] + [
            (("objects", i, "trajectory"), o.trajectory) for i, o in enumerate(cfg.objects)]:
        keys, smooth = traj.keyframes, traj.interpolation == "smooth"
        if all(k.look_at is None for k in keys):
            continue

        # this iteration's track bound as defaults: gap is a closure over the loop's variables
        def gap(t: float, keys=keys, smooth=smooth) -> float:  # metres from the location to look_at at t (s)
            return float(np.linalg.norm(_track_at(keys, "look_at", t, smooth) - _track_at(keys, "location", t, smooth)))

        times = _times([k.t for k in keys], cfg.duration_s)
        i = int(np.argmin([gap(t) for t in times]))
        t = float(times[i])
        if gap(t) >= _MIN_LOOK_M:
            t = _closest(gap, times[max(i - 1, 0)], times[min(i + 1, len(times) - 1)])
        if gap(t) < _MIN_LOOK_M:
            at_key = next((j for j, k in enumerate(keys) if abs(k.t - t) < 1e-9 and k.look_at is not None), None)
            field = loc + (("keyframes", at_key, "look_at") if at_key is not None else ())
            eye = [round(float(v), 6) for v in _track_at(keys, "location", t, smooth)]
            out.append((field, f"look_at is the {'camera' if loc == ('camera',) else 'object'}'s own location "
                               f"{eye} at t = {round(t, 6):g} s, so it looks nowhere"))
    return out


def scene_problems(cfg) -> list[tuple[tuple, str]]:
    """(field location, message) of everything refused in a scene that each field alone allows."""
    out = []
    if cfg.segment_ms > cfg.duration_s * 1000:
        out.append((("segment_ms",), f"{cfg.segment_ms:g} ms is longer than duration_s ({cfg.duration_s:g} s): "
                                     "the sequence would have no segment"))
    from dvsot.events.labels import MAX_OBJECTS

    if len(cfg.objects) > MAX_OBJECTS:  # a dry run and a scene check refuse what generate's labels cannot hold
        out.append((("objects",), f"{len(cfg.objects)} objects beside the target, at most {MAX_OBJECTS} get an id "
                                  "of their own in the per-event labels"))
    return out + look_at_problems(cfg)


def visibility_warnings(cfg) -> list[str]:
    """Warnings for a target that is never in view, or fills the frame, at every checked time (projected points)."""
    k = cfg.sensor.intrinsics()
    spec = cfg.target
    pts = sample_points(mesh_for(spec.shape, spec.mesh), cfg.sampling.points_per_object, seed=0) * spec.size_m
    shake, cam_shake = cfg.derived_seed("shake:target"), cfg.derived_seed("camera_shake")
    times = _times([], cfg.duration_s)
    seen = filled = 0
    for t in times:
        m, s = pose_and_scale(spec.trajectory, float(t), shake)
        world = (pts * s) @ m[:3, :3].T + m[:3, 3]
        cam = pose_matrix(cfg.camera, float(t), cam_shake)
        if np.all(world.min(axis=0) <= cam[:3, 3]) and np.all(cam[:3, 3] <= world.max(axis=0)):
            filled += 1  # the camera is inside the target's bounding box
            continue
        uv = project(world, cam, k)
        uv = uv[np.isfinite(uv).all(axis=1)]
        if not len(uv):
            continue
        x0, y0 = np.clip(uv.min(axis=0), 0, [k.width, k.height])
        x1, y1 = np.clip(uv.max(axis=0), 0, [k.width, k.height])
        area = (x1 - x0) * (y1 - y0)
        seen += area >= 1.0  # at least a pixel of it on the sensor
        filled += area >= _FILL * k.width * k.height
    span = f"at {len(times)} times over {cfg.duration_s:g} s"
    if not seen and not filled:
        return [f"the target is never in view ({span}: outside the image, behind the camera or under a pixel), "
                "so the file will have no ground-truth boxes"]
    if filled == len(times):
        return [f"the target fills the whole frame ({span}: its box covers over {_FILL:.0%} of the image, or the "
                "camera is inside it), so its box is the image"]
    return []
