"""Boxes from masks (contours, circumscribed rectangle), clipping and interpolation."""

import numpy as np

from dvsot.boxes import box_from_mask, clip_box, interpolate_boxes


def test_box_of_a_known_rectangle_and_of_two_blobs():
    m = np.zeros((48, 64), bool)
    m[10:20, 5:30] = True
    np.testing.assert_array_equal(box_from_mask(m), [5, 10, 25, 10])
    m[40:44, 50:60] = True
    np.testing.assert_array_equal(box_from_mask(m), [5, 10, 55, 34])
    assert np.all(np.isnan(box_from_mask(np.zeros((8, 8)))))
    alpha = np.zeros((8, 8), np.float32)
    alpha[2, 3] = 0.7
    np.testing.assert_array_equal(box_from_mask(alpha), [3, 2, 1, 1])


def test_clip():
    np.testing.assert_array_equal(clip_box([-5, 10, 20, 100], 64, 48), [0, 10, 15, 38])
    assert np.all(np.isnan(clip_box([70, 10, 5, 5], 64, 48)))


def test_interpolation_with_nan_neighbours_and_outside():
    t = np.array([0, 100, 200])
    b = np.array([[0, 0, 10, 10], [10, 20, 10, 10], [np.nan] * 4], float)
    out = interpolate_boxes(t, b, [0, 50, 100, 150, 250, -1])
    np.testing.assert_allclose(out[0], [0, 0, 10, 10])
    np.testing.assert_allclose(out[1], [5, 10, 10, 10])
    np.testing.assert_allclose(out[2], [10, 20, 10, 10])
    assert np.all(np.isnan(out[3])) and np.all(np.isnan(out[4])) and np.all(np.isnan(out[5]))
