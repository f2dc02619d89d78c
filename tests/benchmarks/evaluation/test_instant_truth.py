"""Ground truth at query instants: linear between samples, the queries of a rendered file and of a recording."""

import numpy as np
import pytest

from benchmarks.evaluation.instant_truth import interpolation_bound_px, query_times, truth_at
from dvsot.dataset.format import BoxTrack


def track():
    t = np.array([0, 1000, 3000, 4000], np.int64)
    xywh = np.array([[0, 0, 10, 10], [2, 1, 10, 12], [6, 1, 10, 12], [np.nan] * 4], np.float32)
    return BoxTrack(t, xywh, xywh - np.array([0, 0, 1, 1], np.float32))


def test_boxes_are_linear_between_samples_and_nan_next_to_an_absent_one():
    truth = truth_at(track(), np.array([500, 2000, 3000, 3500, 5000]))
    np.testing.assert_allclose(truth.xywh[:3], [[1, 0.5, 10, 11], [4, 1, 10, 12], [6, 1, 10, 12]])
    np.testing.assert_allclose(truth.xywh_visible[1], [4, 1, 9, 11])
    assert np.isnan(truth.xywh[3:]).all()  # next to an absent sample, and after the track


def test_query_times_of_a_rendered_file_and_a_recording():
    np.testing.assert_array_equal(query_times(track(), 1000, 3000, 1000.0), [2000, 3000])
    np.testing.assert_array_equal(query_times(track(), 0, 1000, 3000.0), [333, 667, 1000])
    np.testing.assert_array_equal(query_times(track(), 0, 3000, 1000.0, annotated=True), [1000, 3000])
    with pytest.raises(ValueError, match="query rate"):
        query_times(track(), 0, 1000, 2e6)


def test_the_bound_is_the_motion_bound_plus_a_pixel_per_edge():
    assert interpolation_bound_px(0.75) == (1.75, 3.5)
