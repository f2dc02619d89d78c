"""The per-segment ground truth (dvsot.dataset.segment_truth) on small hand-made tracks with closed-form answers."""

import numpy as np

from dvsot.dataset.format import BoxTrack
from dvsot.dataset.segment_truth import (
    absent_at,
    interpolated_rows,
    interpolated_visibility,
    matched_rows,
    segment_ends,
    segment_truth,
)

NAN4 = [np.nan] * 4


def test_segment_ends_are_the_whole_segments_end_times():
    np.testing.assert_array_equal(segment_ends(35_000, 10_000), [10_000, 20_000, 30_000])
    np.testing.assert_array_equal(segment_ends(30_000, 10_000), [10_000, 20_000, 30_000])
    assert segment_ends(9_999, 10_000).shape == (0,) and segment_ends(9_999, 10_000).dtype == np.int64


def test_matched_rows_pick_the_named_row_and_nan_for_none():
    rows = np.array([[1, 2, 3, 4], [5, 6, 7, 8]], np.float32)
    out = matched_rows(rows, np.array([1, -1, 0]))
    assert out.dtype == np.float32
    np.testing.assert_array_equal(out, [[5, 6, 7, 8], NAN4, [1, 2, 3, 4]])
    np.testing.assert_array_equal(matched_rows(np.empty((0, 4), np.float32), np.array([-1, -1])), [NAN4, NAN4])


def test_interpolated_rows_are_linear_between_samples_and_nan_outside_or_next_to_nan():
    t = np.array([0, 20_000, 30_000])
    rows = np.array([[0, 0, 10, 10], [20, 40, 10, 30], [np.nan] * 4], np.float32)
    out = interpolated_rows(t, rows, np.array([10_000, 20_000, 25_000, 40_000]))
    assert out.dtype == np.float32
    # halfway between the first two; the second exactly; next to a NaN row; beyond the last sample
    np.testing.assert_array_equal(out, [[10, 20, 10, 20], [20, 40, 10, 30], NAN4, NAN4])
    empty = interpolated_rows(np.empty(0, np.int64), np.empty((0, 4), np.float32), np.array([10_000, 20_000]))
    assert empty.shape == (2, 4) and np.isnan(empty).all()


def test_interpolated_visibility_is_linear_between_samples():
    out = interpolated_visibility(np.array([0, 20_000]), np.array([0.2, 0.6], np.float32),
                                  np.array([10_000, 20_000, 30_000]))
    assert out.dtype == np.float32
    np.testing.assert_allclose(out, [0.4, 0.6, np.nan], rtol=1e-6)


def test_absent_where_the_box_or_the_visible_box_has_a_nan():
    box = np.array([[1, 1, 2, 2], [1, 1, 2, 2], [np.nan, 1, 2, 2], NAN4], np.float32)
    visible = np.array([[1, 1, 2, 2], NAN4, [1, 1, 2, 2], NAN4], np.float32)
    np.testing.assert_array_equal(absent_at(box, visible), [False, True, True, True])


def test_a_rendered_track_is_interpolated_to_every_segment_end():
    track = BoxTrack(np.array([0, 20_000]), np.array([[0, 0, 10, 10], [20, 40, 10, 30]], np.float32),
                     np.array([[0, 0, 10, 10], NAN4], np.float32), np.array([1.0, 0.0], np.float32))
    truth = segment_truth(track, 25_000, 10_000)
    np.testing.assert_array_equal(truth.t, [10_000, 20_000])
    np.testing.assert_array_equal(truth.xywh, [[10, 20, 10, 20], [20, 40, 10, 30]])
    np.testing.assert_array_equal(truth.xywh_visible, [NAN4, NAN4])  # next to the visible box's NaN
    np.testing.assert_allclose(truth.visibility, [0.5, 0.0])
    np.testing.assert_array_equal(truth.absent, [True, True])
    assert truth.annotation is None
    # no visibility in the track: neither visibility nor absence per segment
    plain = segment_truth(BoxTrack(track.t, track.xywh, track.xywh_visible), 25_000, 10_000)
    assert plain.visibility is None and plain.absent is None
    np.testing.assert_array_equal(plain.xywh, truth.xywh)


def test_an_empty_rendered_track_leaves_every_segment_nan():
    empty = BoxTrack(np.empty(0, np.int64), np.empty((0, 4), np.float32), np.empty((0, 4), np.float32))
    truth = segment_truth(empty, 30_000, 10_000)
    assert truth.xywh.shape == truth.xywh_visible.shape == (3, 4)
    assert np.isnan(truth.xywh).all() and np.isnan(truth.xywh_visible).all()


def test_annotations_are_matched_to_the_nearest_segment_end_never_interpolated():
    # segment ends 10, 20, 30 ms: 9 ms -> end 10 (1 ms off); 21 ms and 24 ms -> end 20, the nearer (21 ms) wins;
    # nothing lies within 5 ms of 30 ms
    t = np.array([9_000, 21_000, 24_000])
    boxes = np.array([[1, 1, 4, 4], [2, 2, 4, 4], [3, 3, 4, 4]], np.float32)
    truth = segment_truth(BoxTrack(t, boxes, boxes + 1), 30_000, 10_000, annotated=True)
    np.testing.assert_array_equal(truth.annotation, [0, 1, -1])
    np.testing.assert_array_equal(truth.xywh, [[1, 1, 4, 4], [2, 2, 4, 4], NAN4])
    np.testing.assert_array_equal(truth.xywh_visible, [[2, 2, 5, 5], [3, 3, 5, 5], NAN4])
    assert truth.visibility is None and truth.absent is None
