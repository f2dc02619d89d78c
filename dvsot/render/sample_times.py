"""Motion-bounded sample times (ESIM's adaptive sampling idea), computed from the trajectories, not from renders.

Rule: starting at t_start, the next sample time is t + dt with

    dt = max_displacement_px / v,   v = the fastest image-plane speed (px/s) of any tracked scene point,

bounded by 1/max_rate_hz <= dt <= 1/min_rate_hz; v is measured by finite differences of
`project` over 1/max_rate_hz. The step is then checked: if any point actually moved more than the
bound between the two samples (acceleration), dt shrinks in proportion and is checked again. So
between consecutive samples no tracked point moves more than `max_displacement_px`, unless the
maximum rate caps the step (then the step is 1/max_rate_hz and the bound may be exceeded). The last
sample is exactly t_end; a remainder shorter than 1 us (the file's time resolution) is merged into the
last step so that no two samples share a microsecond timestamp. Points that are NaN (behind the
camera) at either end of an interval are ignored for that interval; with a `window` (the image and a
margin, in pixels), so are points outside it at both ends. A point that is outside at one end and
inside at the other counts, so a fast object entering the view within one step still bounds it.

Shrinking the step in proportion to the overshoot (rather than halving it) gives the same guarantee
as bisection with fewer renders. The check compares positions at the two ends of an interval, so a
point that leaves and comes back within one step is not seen; with steps of at most 1/min_rate_hz
this only matters for motions faster than the sampling itself, which the minimum rate is there for.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

Window = tuple[float, float, float, float]  # x0, y0, x1, y1 in pixels


def max_displacement(a: np.ndarray, b: np.ndarray, window: Window | None = None) -> float:
    """Largest distance (pixels) between corresponding finite points, inside `window` at either end if given."""
    d = np.hypot(a[:, 0] - b[:, 0], a[:, 1] - b[:, 1])
    seen = np.isfinite(d)
    if window is not None:
        seen &= _inside(a, window) | _inside(b, window)
    d = d[seen]
    return float(d.max()) if d.size else 0.0


def _inside(p: np.ndarray, window: Window) -> np.ndarray:
    x0, y0, x1, y1 = window
    return (p[:, 0] >= x0) & (p[:, 0] <= x1) & (p[:, 1] >= y0) & (p[:, 1] <= y1)


def motion_bounded_times(project: Callable[[float], np.ndarray], t_start_s: float, t_end_s: float,
                         max_displacement_px: float = 0.75, min_rate_hz: float = 100.0,
                         max_rate_hz: float = 5000.0, window: Window | None = None) -> np.ndarray:
    """Sample times (seconds, increasing, from t_start_s to t_end_s) bounding image motion between samples."""
    if not t_end_s > t_start_s:
        raise ValueError(f"t_end_s ({t_end_s}) must be after t_start_s ({t_start_s})")
    if not max_displacement_px > 0:
        raise ValueError(f"max_displacement_px must be positive, got {max_displacement_px}")
    if not 0 < min_rate_hz <= max_rate_hz:
        raise ValueError(f"need 0 < min_rate_hz <= max_rate_hz, got {min_rate_hz} and {max_rate_hz}")
    dt_min, dt_max = 1.0 / max_rate_hz, 1.0 / min_rate_hz
    tol = max_displacement_px * (1 + 1e-9)  # float noise in `project` must not force extra samples
    times = [float(t_start_s)]
    t, p = float(t_start_s), _points(project, t_start_s)
    while t < t_end_s:
        probe = min(t + dt_min, t_end_s)
        speed = max_displacement(p, _points(project, probe), window) / (probe - t)
        dt = max_displacement_px / speed if speed > 0 else dt_max
        dt = float(np.clip(dt, dt_min, dt_max))
        while True:
            # a remainder under 1 us would round onto the same microsecond as this sample: merge it
            t_next = t_end_s if t + dt > t_end_s - _MERGE_S else t + dt
            q = _points(project, t_next)
            moved = max_displacement(p, q, window)
            if moved <= tol or dt <= dt_min:
                break
            dt = max(dt * 0.95 * max_displacement_px / moved, dt_min)
        times.append(t_next)
        t, p = t_next, q
    return np.asarray(times)


_MERGE_S = 1e-6  # the dataset's time resolution (1 us), in seconds


def with_extra_times(times: np.ndarray, extra_s: np.ndarray) -> np.ndarray:
    """Sample times (seconds) with extra instants merged in, in order; an extra instant on the same microsecond as
    a sample is that sample. Extra samples only shorten intervals, so the motion bound still holds."""
    times = np.asarray(times, dtype=np.float64)
    extra = np.asarray(extra_s, dtype=np.float64).ravel()
    if extra.size == 0:
        return times
    both = np.concatenate([times, extra[(extra >= times[0]) & (extra <= times[-1])]])
    us = np.round(both * 1e6).astype(np.int64)
    _, first = np.unique(us, return_index=True)  # in time order; the motion-bounded sample wins a shared microsecond
    return both[first]


def _points(project: Callable[[float], np.ndarray], t: float) -> np.ndarray:
    """project(t) as a float (K, 2) array, checked once per call (cheap next to a projection)."""
    a = np.asarray(project(t), dtype=np.float64)
    if a.ndim != 2 or a.shape[1] != 2:
        raise ValueError(f"project({t}) must return (K, 2) pixel positions, got shape {a.shape}")
    return a


def frames_saved_vs_fixed(times: np.ndarray, rate_hz: float = 1000.0) -> dict:
    """Rendered frames against a fixed-rate (Hz) schedule over the same span: counts and the fraction saved."""
    times = np.asarray(times, dtype=np.float64)
    span = float(times[-1] - times[0]) if times.size else 0.0
    fixed = int(np.floor(span * rate_hz + 1e-9)) + 1  # both ends included, as in motion_bounded_times
    return {"rendered": int(times.size), "fixed_rate_hz": rate_hz, "fixed_frames": fixed,
            "saved_frames": fixed - int(times.size), "saved_fraction": 1.0 - times.size / fixed}
