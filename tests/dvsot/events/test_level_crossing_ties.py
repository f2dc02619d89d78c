"""Exact ties in level-crossing counting, the first interval's multi-crossing times, and the compiled
kernel against a straightforward per-pixel loop over levels (ESIM's, with dvsot's tie rule)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dvsot.events import EventBatch, EventParams, EventSimulator
from dvsot.events.kernel import REFRACTORY_SLACK_US, TIE_TOL


def dn(values) -> np.ndarray:
    """8-bit values as the linear frames dvsot.events.frame_sources makes of them (float32 I / 255)."""
    return np.asarray(values, np.float32).reshape(1, -1) / np.float32(255.0)


def counts_per_pixel(batch: EventBatch, width: int) -> np.ndarray:
    return np.bincount(batch.x.astype(np.int64), minlength=width)


def test_8bit_pixels_up_and_back_down_fire_the_same_number_of_levels_every_time():
    # 256 pixels, each between its own pair of 8-bit values; the return to the first value lands on
    # the level the pixel first fired from, so every leg crosses the same number of levels
    rng = np.random.default_rng(1)
    lo = rng.integers(0, 128, 256)
    hi = np.minimum(lo + rng.integers(20, 128, 256), 255)
    sim = EventSimulator(256, 1, EventParams(cp=0.2, cn=0.2))
    sim.step(dn(lo), 0)
    la, lb = np.log(dn(lo)[0].astype(np.float64) + 1e-3), np.log(dn(hi)[0].astype(np.float64) + 1e-3)
    k = np.floor((lb - la) / 0.2).astype(np.int64)  # no pair sits within 1e-6 of a whole level here
    assert np.all(np.abs((lb - la) / 0.2 - np.round((lb - la) / 0.2)) > 1e-6) and k.sum() > 500
    for cycle in range(60):
        up = sim.step(dn(hi), (2 * cycle + 1) * 1_000)
        down = sim.step(dn(lo), (2 * cycle + 2) * 1_000)
        np.testing.assert_array_equal(counts_per_pixel(up, 256), k)
        np.testing.assert_array_equal(counts_per_pixel(down, 256), k)
        assert np.all(up.p == 1) and np.all(down.p == 0)
        # the last level down is the first frame's value itself: crossed at the end of the interval
        assert np.isin(np.flatnonzero(k), down.x[down.t == (2 * cycle + 2) * 1_000]).all()


def test_log_samples_on_levels_cross_exactly_as_many_levels_as_they_move():
    # random walks over whole levels base + m*C (log input, arbitrary base and C per pixel): each step
    # from level m to m' crosses |m' - m| levels; exact arithmetic puts every sample on a level
    rng = np.random.default_rng(2)
    w, steps = 400, 200
    base = rng.uniform(-7.0, 0.0, w)
    c = rng.uniform(0.05, 0.5, w)
    m = np.cumsum(rng.integers(-3, 4, (steps, w)), axis=0)
    m[0] = 0
    sim = EventSimulator(w, 1, EventParams(cp=0.2, cn=0.2, sigma_cp=0.1, sigma_cn=0.1, min_threshold=0.05))
    sim._set_thresholds(c, c)  # per-pixel thresholds of our choosing (equal for ON and OFF)
    for i in range(steps):
        frame = (base + m[i] * c).reshape(1, w)
        ev = sim.step(frame, i * 1_000, is_log=True)
        if i == 0:
            continue
        np.testing.assert_array_equal(counts_per_pixel(ev, w), np.abs(m[i] - m[i - 1]))
        moved = m[i] != m[i - 1]
        # the last level crossed is the sample itself: at the end of the interval
        ends = np.zeros(w, bool)
        ends[ev.x[ev.t == i * 1_000]] = True
        np.testing.assert_array_equal(ends, moved)


def test_closed_form_ramps_with_exact_returns():
    c, d, base, T = 0.2, 0.05, -1.37, 1_000
    sim = EventSimulator(1, 1, EventParams(cp=c, cn=c))
    peaks = [base, base + 3 * c + d, base, base - (2 * c + d), base, base + 3 * c + d, base]
    times = []
    for i, level in enumerate(peaks):
        times.append(sim.step(np.array([[level]]), i * T, is_log=True).t.tolist())
    h_up, h_down = 3 * c + d, 2 * c + d
    up = [round(T * j * c / h_up) for j in (1, 2, 3)]
    back_down = [T + round(T * (h_up - j * c) / h_up) for j in (2, 1, 0)]  # levels 2C, C and the base
    down = [2 * T + round(T * j * c / h_down) for j in (1, 2)]
    back_up = [3 * T + round(T * (h_down - j * c) / h_down) for j in (1, 0)]  # levels -C and the base
    assert times[1] == up and times[2] == back_down and times[3] == down and times[4] == back_up
    assert times[5] == [4 * T + t for t in up] and times[6] == [5 * T + t - T for t in back_down]
    assert back_down[-1] == 2 * T and back_up[-1] == 4 * T  # the returns land on the end of the interval


def test_first_interval_multi_crossing_times_are_exact():
    # 50 -> 200 DN in 1 ms: levels of log(I + 1e-3) 0.2 apart from the first frame's value
    sim = EventSimulator(1, 1, EventParams(cp=0.2, cn=0.2))
    sim.step(dn([50]), 0)
    ev = sim.step(dn([200]), 1_000)
    l0, l1 = (math.log(float(np.float32(v) / np.float32(255.0)) + 1e-3) for v in (50, 200))
    n = math.floor((l1 - l0) / 0.2)
    assert n == 6 and ev.t.tolist()[:3] == [145, 289, 434]
    assert ev.t.tolist() == [round(1_000 * j * 0.2 / (l1 - l0)) for j in range(1, n + 1)]


def reference_events(frames: list[np.ndarray], times: list[int], sim: EventSimulator, is_log: bool,
                     thresholds: list[tuple[np.ndarray, np.ndarray]]) -> list[tuple[int, int, int, int]]:
    """ESIM's per-pixel loop, one level at a time, with dvsot's tie rule; (t, x, y, p) in dvsot's order."""
    p = sim.params
    logs = [np.asarray(f, np.float64).ravel() if is_log else np.log(np.asarray(f, np.float64).ravel() + p.log_eps)
            for f in frames]
    base, last = logs[0].copy(), logs[0].copy()
    off = np.zeros_like(base)
    last_event = np.full(base.size, -np.inf)
    out = []
    for j in range(1, len(frames)):
        t0, t1, L1 = times[j - 1], times[j], logs[j]
        cp, cn = (a.ravel() for a in thresholds[j - 1])
        interval = []
        for i in range(base.size):
            s = 1.0 if L1[i] >= last[i] else -1.0
            c = cp[i] if s > 0 else cn[i]
            u0, u1 = s * ((last[i] - base[i]) - off[i]), s * ((L1[i] - base[i]) - off[i])
            k, fired = 1.0, 0.0
            while k <= u1 / c + TIE_TOL:  # level k is reached by L1
                if k > u0 / c + TIE_TOL:  # ... and was not reached by L0
                    fired = k
                    dt = min(max((k * c - u0) * ((t1 - t0) / (u1 - u0)), 0.0), float(t1 - t0))
                    t_abs = t0 + dt
                    if p.refractory_us <= 0 or t_abs - last_event[i] >= p.refractory_us - REFRACTORY_SLACK_US:
                        last_event[i] = t_abs
                        interval.append((t0 + int(np.rint(dt)), i, len(interval), int(s > 0)))
                k += 1.0
            if fired:
                off[i] += s * fired * c
        last = L1
        out += [(t, i % sim.width, i // sim.width, pol) for t, i, _, pol in sorted(interval)]
    return out


@pytest.mark.parametrize("case", ["8bit", "8bit_refractory_mismatch", "float_per_interval"])
def test_kernel_equals_a_per_pixel_reference_loop_on_random_input(case):
    rng = np.random.default_rng({"8bit": 3, "8bit_refractory_mismatch": 4, "float_per_interval": 5}[case])
    w, h, n = 12, 10, 30
    if case.startswith("8bit"):  # few distinct values: pixels return exactly to earlier values all the time
        palette = np.array([3, 40, 41, 90, 200, 255], np.float32) / np.float32(255.0)
        frames = [palette[rng.integers(0, palette.size, (h, w))] for _ in range(n)]
    else:
        frames = [rng.uniform(0.0, 1.0, (h, w)) for _ in range(n)]
    times = np.cumsum(rng.integers(1, 3_000, n)).tolist()
    params = {"8bit": EventParams(),
              "8bit_refractory_mismatch": EventParams(sigma_cp=0.05, sigma_cn=0.03, refractory_us=400),
              "float_per_interval": EventParams(cp=0.15, cn=0.25, sigma_cp=0.05, sigma_cn=0.05,
                                                mismatch="per_interval", refractory_us=150)}[case]
    sim = EventSimulator(w, h, params, seed=9)
    batches, thresholds = [], []
    for f, t in zip(frames, times):
        batches.append(sim.step(f, t))
        thresholds.append(tuple(a.copy() for a in sim.thresholds))  # those the step just used
    got = EventBatch.concatenate(batches)
    want = reference_events(frames, times, sim, False, thresholds[1:])
    assert len(want) > 500
    assert list(zip(got.t.tolist(), got.x.tolist(), got.y.tolist(), got.p.tolist())) == want
    again = EventSimulator(w, h, params, seed=9)
    repeat = EventBatch.concatenate([again.step(f, t) for f, t in zip(frames, times)])
    for col in ("x", "y", "t", "p", "signal"):
        assert getattr(repeat, col).tobytes() == getattr(got, col).tobytes()


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_log_frames_with_nan_or_inf_are_refused_before_anything_changes(bad):
    sim = EventSimulator(3, 2, EventParams())
    sim.step(np.zeros((2, 3)), 0, is_log=True)
    frame = np.full((2, 3), 1.0)
    frame[1, 2] = bad
    with pytest.raises(Exception, match="NaN or infinite"):
        sim.step(frame, 1_000, is_log=True, copy=False)
    assert len(sim.step(np.full((2, 3), 1.0), 1_000, is_log=True)) == 6 * 5  # levels 0.2 .. 1.0, state untouched
    with pytest.raises(Exception, match="NaN or infinite"):
        EventSimulator(3, 2).step(np.full((2, 3), bad), 0, is_log=True)
