"""Motion-bounded sample times against closed-form motion."""

import numpy as np
import pytest

from dvsot.render.sample_times import frames_saved_vs_fixed, max_displacement, motion_bounded_times


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


def test_static_scene_samples_at_min_rate_and_ends_exactly():
    times = motion_bounded_times(lambda t: np.array([[5.0, 5.0], [np.nan, 1.0]]), 0.25, 0.3, 0.75, 200.0, 1000.0)
    np.testing.assert_allclose(times, np.linspace(0.25, 0.3, 11))
    assert times[-1] == 0.3


def test_remainder_under_a_microsecond_is_merged():
    times = motion_bounded_times(lambda t: np.zeros((1, 2)), 0.0, 0.0100004, 0.75, 100.0, 1000.0)
    assert list(times) == [0.0, 0.0100004]
    us = np.rint(motion_bounded_times(lambda t: np.array([[1e3 * t, 0]]), 0.0, 0.0300003, 0.75) * 1e6)
    assert np.all(np.diff(us) > 0)


def test_max_rate_caps_and_min_rate_bounds_every_step():
    proj = lambda t: np.array([[3000.0 * np.sin(8 * t) ** 2, 100.0 * t]])  # noqa: E731  speed 0..~24000 px/s
    times = motion_bounded_times(proj, 0.0, 0.4, 1.0, 50.0, 2000.0)
    steps = np.diff(times)
    assert steps[:-1].min() >= 1 / 2000 * (1 - 1e-9) and steps.max() <= 1 / 50 * (1 + 1e-9)
    moved = np.array([max_displacement(proj(a), proj(b)) for a, b in zip(times[:-1], times[1:])])
    # over the bound only where the step is already at the maximum rate
    assert np.all((moved <= 1.0 + 1e-9) | np.isclose(steps, 1 / 2000))
    assert (moved > 1.0).any() and (steps > 1 / 1000).any()


def test_summary_counts_and_bad_arguments():
    s = frames_saved_vs_fixed(np.array([0.0, 0.5, 1.0]), 1000.0)
    assert s == {"rendered": 3, "fixed_rate_hz": 1000.0, "fixed_frames": 1001, "saved_frames": 998,
                 "saved_fraction": pytest.approx(1 - 3 / 1001)}
    zero = lambda t: np.zeros((1, 2))  # noqa: E731
    for kwargs in ({"max_displacement_px": 0}, {"min_rate_hz": 0}, {"min_rate_hz": 500, "max_rate_hz": 100}):
        with pytest.raises(ValueError):
            motion_bounded_times(zero, 0.0, 1.0, **kwargs)
    with pytest.raises(ValueError, match="K, 2"):
        motion_bounded_times(lambda t: np.zeros(3), 0.0, 1.0)


def test_point_entering_the_window_within_one_step_bounds_it():
    # a point racing in from far outside (8000 px/s) and a static one inside a 100 x 100 window
    proj = lambda t: np.array([[-2000.0 + 8000.0 * t, 50.0], [50.0, 50.0]])  # noqa: E731
    window = (0.0, 0.0, 100.0, 100.0)
    times = motion_bounded_times(proj, 0.0, 0.3, 0.75, 100.0, 1e5, window)
    moved = np.array([max_displacement(proj(a), proj(b), window) for a, b in zip(times[:-1], times[1:])])
    assert moved.max() <= 0.75 * (1 + 1e-9)
    inside = np.array([proj(t)[0, 0] for t in times]) >= 0.0
    entered = np.flatnonzero(inside)[0]
    assert times[entered] - times[entered - 1] <= 0.75 / 8000 * (1 + 1e-6)  # the entering step is a short one
    # while it is outside at both ends of a step, it does not count: the static point gives min-rate steps
    assert np.isclose(times[1] - times[0], 0.01)
    # once it has left (x > 100 after t = 0.2625) the steps go back to the minimum rate
    after = times[times >= 0.2625]
    np.testing.assert_allclose(np.diff(after)[:-1], 0.01)
    assert len(after) >= 3


def test_max_displacement_window_keeps_points_inside_at_either_end():
    a = np.array([[-500.0, 5.0], [5.0, 5.0], [-20.0, 5.0]])
    b = np.array([[-400.0, 5.0], [6.0, 5.0], [3.0, 5.0]])
    assert max_displacement(a, b) == 100.0
    assert max_displacement(a, b, (0.0, 0.0, 10.0, 10.0)) == 23.0  # the far point is out at both ends


def test_extra_times_are_merged_in_order_and_a_shared_microsecond_is_one_sample():
    from dvsot.render.sample_times import with_extra_times

    times = np.array([0.0, 0.01, 0.02])
    merged = with_extra_times(times, np.array([0.015, 0.0100004, 0.005, 0.03]))
    np.testing.assert_array_equal(merged, [0.0, 0.005, 0.01, 0.015, 0.02])  # outside the span: dropped
    assert with_extra_times(times, np.array([])) is times


def test_extra_times_after_the_scene_are_refused():
    from dvsot.scene import parse_scene
    from tests.synthetic import MINIMAL_SCENE

    with pytest.raises(Exception, match="extra_times_ms holds 150"):
        parse_scene(MINIMAL_SCENE + "sampling: {extra_times_ms: [50, 150]}\n")
    assert parse_scene(MINIMAL_SCENE + "sampling: {extra_times_ms: [50]}\n").sampling.extra_times_ms == [50.0]
