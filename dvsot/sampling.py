"""Motion-bounded sample times (ESIM's adaptive sampling idea), computed from the trajectories, not from renders.

Rule: starting at t_start, the next sample time is t + dt with

    dt = max_displacement_px / v,   v = the fastest image-plane speed (px/s) of any tracked scene point,

bounded by 1/max_rate_hz <= dt <= 1/min_rate_hz; v is measured by finite differences of
`project` over 1/max_rate_hz. The step is then checked: if any point actually moved more than the
bound between the two samples (acceleration), dt shrinks in proportion and is checked again. So
between consecutive samples no tracked point moves more than `max_displacement_px`, unless the
maximum rate caps the step (then the step is 1/max_rate_hz and the summary reports it). The last
sample is exactly t_end. Points that are NaN (behind the camera) at either end are ignored.
"""

from __future__ import annotations

from typing import Callable

import numpy as np


def max_displacement(a: np.ndarray, b: np.ndarray) -> float:
    """Largest Euclidean distance (pixels) between corresponding points visible in both arrays."""
    d = np.hypot(a[:, 0] - b[:, 0], a[:, 1] - b[:, 1])
    d = d[np.isfinite(d)]
    return float(d.max()) if d.size else 0.0


def motion_bounded_times(project: Callable[[float], np.ndarray], t_start_s: float, t_end_s: float,
                         max_displacement_px: float = 0.75, min_rate_hz: float = 100.0,
                         max_rate_hz: float = 5000.0) -> np.ndarray:
    """Sample times (seconds, increasing, from t_start_s to t_end_s) bounding image motion between samples."""
    if t_end_s <= t_start_s:
        raise ValueError("t_end_s must be after t_start_s")
    dt_min, dt_max = 1.0 / max_rate_hz, 1.0 / min_rate_hz
    times = [t_start_s]
    t, p = t_start_s, project(t_start_s)
    while t < t_end_s:
        probe = min(t + dt_min, t_end_s)
        speed = max_displacement(p, project(probe)) / (probe - t)
        dt = max_displacement_px / speed if speed > 0 else dt_max
        dt = float(np.clip(dt, dt_min, dt_max))
        while True:
            t_next = min(t + dt, t_end_s)
            q = project(t_next)
            moved = max_displacement(p, q)
            if moved <= max_displacement_px * (1 + 1e-9) or dt <= dt_min:
                break
            dt = max(dt * 0.95 * max_displacement_px / moved, dt_min)
        times.append(t_next)
        t, p = t_next, q
    return np.asarray(times)


def frames_saved_vs_fixed(times: np.ndarray, rate_hz: float = 1000.0) -> dict:
    """Rendered frames against a fixed-rate schedule over the same span."""
    span = float(times[-1] - times[0])
    fixed = int(np.floor(span * rate_hz)) + 1
    return {"rendered": int(len(times)), "fixed_rate_hz": rate_hz, "fixed_frames": fixed,
            "saved_fraction": 1.0 - len(times) / fixed if fixed else 0.0}
