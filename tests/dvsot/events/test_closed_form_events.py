"""Event generator against closed-form cases: ramps, multiple crossings, refractory drops, mismatch, noise."""

from __future__ import annotations

import numpy as np
import pytest

from dvsot.core.errors import UserError
from dvsot.events import EventBatch, EventParams, EventSimulator


def log_sim(params: EventParams, width: int = 1, seed: int = 0) -> EventSimulator:
    sim = EventSimulator(width, 1, params, seed)
    sim.step(np.zeros((1, width)), 0, is_log=True)
    return sim


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_linear_ramp_of_k_thresholds_gives_k_events_at_predicted_times(sign):
    c, k, d = 0.25, 3, 0.1
    sim = log_sim(EventParams(cp=c, cn=c))
    total = sign * (k * c + d)
    ev = sim.step(np.array([[total]]), 10_000, is_log=True)
    assert len(ev) == k
    expected = [round(10_000 * j * c / (k * c + d)) for j in range(1, k + 1)]
    np.testing.assert_array_equal(ev.t, expected)
    assert np.all(ev.p == (1 if sign > 0 else 0)) and np.all(ev.signal)
    # the reference moved by k*C: a further rise of exactly the remainder d gives nothing, C - d more gives one
    assert len(sim.step(np.array([[total]]), 11_000, is_log=True)) == 0
    ev2 = sim.step(np.array([[sign * (k + 1) * c + sign * 1e-9]]), 12_000, is_log=True)
    assert len(ev2) == 1 and ev2.t[0] == 12_000


def test_separate_on_and_off_thresholds_and_two_crossings_in_one_interval():
    sim = log_sim(EventParams(cp=0.1, cn=0.3), width=2)
    ev = sim.step(np.array([[0.25, -0.65]]), 1_000, is_log=True)
    on, off = ev.select(ev.p == 1), ev.select(ev.p == 0)
    np.testing.assert_array_equal(on.t, [400, 800])  # levels 0.1, 0.2 of 0.25
    np.testing.assert_array_equal(off.t, [462, 923])  # levels 0.3, 0.6 of 0.65
    assert np.all(on.x == 0) and np.all(off.x == 1)
    assert np.all(np.diff(ev.t) >= 0)


def test_crossing_times_interpolate_from_the_previous_sample_not_the_reference():
    sim = log_sim(EventParams(cp=0.2, cn=0.2))
    assert len(sim.step(np.array([[0.15]]), 1_000, is_log=True)) == 0
    ev = sim.step(np.array([[0.35]]), 2_000, is_log=True)  # level 0.2 crossed at 1/4 of (0.15 -> 0.35)
    np.testing.assert_array_equal(ev.t, [1_250])


def test_refractory_period_drops_events_but_moves_the_reference():
    c = 0.1
    sim = log_sim(EventParams(cp=c, cn=c, refractory_us=250))
    ev = sim.step(np.array([[1.0 - 1e-9]]), 1_000, is_log=True)  # 9 crossings, 100 us apart (+ drift)
    np.testing.assert_array_equal(ev.t, [100, 400, 700])
    # the reference advanced by all 9 crossings to 0.9: falling from 1.0 to 0.75 crosses 0.8 only,
    # at (1.0 - 0.8) / (1.0 - 0.75) of the interval, far enough from the last emitted event (700 us)
    ev2 = sim.step(np.array([[0.75]]), 2_000, is_log=True)
    assert len(ev2) == 1 and ev2.p[0] == 0
    np.testing.assert_array_equal(ev2.t, [1_800])


def test_identical_frames_give_no_events():
    rng = np.random.default_rng(0)
    frame = rng.random((24, 32))
    sim = EventSimulator(32, 24, EventParams(sigma_cp=0.03, sigma_cn=0.03), seed=1)
    for t in range(0, 5_000, 1_000):
        assert len(sim.step(frame, t)) == 0


def test_per_pixel_thresholds_have_the_requested_mean_and_spread():
    sim = EventSimulator(200, 100, EventParams(cp=0.3, cn=0.2, sigma_cp=0.05, sigma_cn=0.02), seed=3)
    cp, cn = sim.thresholds
    assert cp.shape == (100, 200)
    assert abs(cp.mean() - 0.3) < 0.002 and abs(cp.std() - 0.05) < 0.002
    assert abs(cn.mean() - 0.2) < 0.002 and abs(cn.std() - 0.02) < 0.001
    clamped = EventSimulator(100, 100, EventParams(cp=0.02, sigma_cp=0.05), seed=3).thresholds[0]
    assert clamped.min() == pytest.approx(0.01)


def moving_pattern(t_s: float, h: int = 40, w: int = 50) -> np.ndarray:
    yy, xx = np.mgrid[0:h, 0:w]
    return 0.5 + 0.4 * np.sin(0.3 * (xx - 200 * t_s)) * np.cos(0.2 * yy)


def run(params: EventParams, seed: int) -> EventBatch:
    sim = EventSimulator(50, 40, params, seed)
    return EventBatch.concatenate([sim.step(moving_pattern(i * 1e-3), i * 1_000) for i in range(20)])


def test_same_seed_same_bytes_and_noise_is_flagged():
    params = EventParams(sigma_cp=0.03, sigma_cn=0.03, shot_noise_hz=5.0, leak_hz=2.0, refractory_us=100)
    a, b, c = run(params, 7), run(params, 7), run(params, 8)
    for col in ("x", "y", "t", "p", "signal"):
        assert getattr(a, col).tobytes() == getattr(b, col).tobytes()
    assert a.t.tobytes() != c.t.tobytes()
    noise = a.select(~a.signal)
    expected = (5.0 + 2.0) * 50 * 40 * 0.019
    assert 0.6 * expected < len(noise) < 1.4 * expected
    assert np.all(np.diff(a.t) >= 0)
    clean = run(EventParams(sigma_cp=0.03, sigma_cn=0.03, refractory_us=100), 7)
    assert np.all(clean.signal) and len(clean) == int(a.signal.sum())


def test_per_interval_mismatch_redraws_thresholds():
    sim = EventSimulator(30, 20, EventParams(sigma_cp=0.05, mismatch="per_interval"), seed=0)
    sim.step(np.ones((20, 30)), 0)
    first = sim.thresholds[0].copy()
    sim.step(np.ones((20, 30)), 1_000)
    assert not np.array_equal(first, sim.thresholds[0])


@pytest.mark.parametrize("frame, t, words", [
    (np.ones((3, 4)), 2_000, "shape"),
    (np.full((4, 5), np.nan), 2_000, "NaN"),
    (np.full((4, 5), np.inf), 2_000, "infinite"),
    (-np.ones((4, 5)), 2_000, "negative"),
    (np.ones((4, 5)), 1_000, "increase"),
    (np.ones((4, 5), dtype=complex), 2_000, "dtype"),
])
def test_bad_frames_are_rejected(frame, t, words):
    sim = EventSimulator(5, 4)
    sim.step(np.ones((4, 5)), 1_000)
    with pytest.raises(UserError, match=words):
        sim.step(frame, t)


def test_bad_parameters_name_the_field():
    with pytest.raises(UserError, match="'cp'"):
        EventParams.parse({"cp": -0.1}, "scene.yaml")
    with pytest.raises(UserError, match="'colour'"):
        EventParams.parse({"colour": 1}, "scene.yaml")


@pytest.mark.parametrize("field", ["cp", "cn", "sigma_cp", "sigma_cn", "min_threshold", "refractory_us", "log_eps",
                                   "shot_noise_hz", "leak_hz"])
@pytest.mark.parametrize("value", [float("inf"), float("-inf"), float("nan")])
def test_non_finite_parameters_are_rejected(field, value):
    with pytest.raises(UserError, match=f"'{field}': Input should be a finite number"):
        EventParams.parse({field: value}, "scene.yaml")
