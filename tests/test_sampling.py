"""Motion-bounded sample times against closed-form motion."""

import numpy as np
import pytest

from dvsot.sampling import frames_saved_vs_fixed, max_displacement, motion_bounded_times


def test_constant_speed_gives_bound_over_speed():
    v = 300.0  # px/s
    times = motion_bounded_times(lambda t: np.array([[v * t, 10.0]]), 0.0, 0.1, 0.75, 10.0, 1e5)
    np.testing.assert_allclose(np.diff(times)[:-1], 0.75 / v, rtol=1e-6)
    assert times[0] == 0.0 and times[-1] == 0.1


def test_accelerating_motion_never_exceeds_the_bound():
    proj = lambda t: np.array([[2000.0 * t * t, 0.0], [0.0, 50.0 * np.sin(30 * t)], [np.nan, np.nan]])  # noqa: E731
    times = motion_bounded_times(proj, 0.0, 0.5, 0.5, 10.0, 1e5)
    steps = [max_displacement(proj(a), proj(b)) for a, b in zip(times[:-1], times[1:])]
    assert max(steps) <= 0.5 * (1 + 1e-9) and len(times) > 100


def test_rate_limits():
    static = motion_bounded_times(lambda t: np.zeros((3, 2)), 0.0, 1.0, 0.75, 100.0, 1000.0)
    np.testing.assert_allclose(np.diff(static), 0.01)
    fast = motion_bounded_times(lambda t: np.array([[1e6 * t, 0]]), 0.0, 0.01, 0.75, 100.0, 1000.0)
    np.testing.assert_allclose(np.diff(fast), 0.001)
    saved = frames_saved_vs_fixed(static, 1000.0)
    assert saved["rendered"] == 101 and saved["fixed_frames"] == 1001


def test_bad_span():
    with pytest.raises(ValueError):
        motion_bounded_times(lambda t: np.zeros((1, 2)), 1.0, 1.0)
