"""Boxes from masks (contours, circumscribed rectangle), clipping and interpolation."""

import numpy as np
import pytest

from dvsot.dataset.boxes import box_from_mask, clip_box, interpolate_boxes, iou_xywh


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


def test_box_from_mask_ignores_holes_and_accepts_hw1_alpha():
    m = np.zeros((30, 40, 1), np.float32)
    m[5:25, 10:30] = 1.0
    m[10:20, 15:25] = 0.0  # a hole (e.g. a torus) does not change the outer rectangle
    m[0, 39] = 0.4  # below the threshold
    np.testing.assert_array_equal(box_from_mask(m), [10, 5, 20, 20])
    assert box_from_mask(m).dtype == np.float32
    with pytest.raises(ValueError):
        box_from_mask(np.zeros((2, 3, 4)))


def test_box_from_mask_touching_the_border():
    m = np.zeros((10, 12), np.uint8)
    m[0:3, 9:12] = 255
    np.testing.assert_array_equal(box_from_mask(m), [9, 0, 3, 3])


def test_clip_broadcasts_over_rows():
    out = clip_box(np.array([[-5, 10, 20, 100], [70, 10, 5, 5], [1, 2, 3, 4], [np.nan] * 4]), 64, 48)
    np.testing.assert_array_equal(out[0], [0, 10, 15, 38])
    np.testing.assert_array_equal(out[2], [1, 2, 3, 4])
    assert np.isnan(out[1]).all() and np.isnan(out[3]).all()


def test_interpolation_between_unequal_samples_and_scalar_query():
    t = np.array([0, 10, 40])
    b = np.array([[0, 0, 10, 10], [np.nan] * 4, [30, 30, 40, 40]], float)
    assert np.isnan(interpolate_boxes(t, b, 5)).all()  # one NaN neighbour is enough
    np.testing.assert_allclose(interpolate_boxes([0, 40], b[[0, 2]], 10), [[7.5, 7.5, 17.5, 17.5]])
    assert np.isnan(interpolate_boxes([], np.empty((0, 4)), [0])).all()


def test_iou_by_hand():
    a = np.array([0, 0, 10, 10])
    assert iou_xywh(a, [5, 5, 10, 10]) == pytest.approx(25 / 175)
    assert iou_xywh(a, [2, 2, 4, 4]) == pytest.approx(16 / 100)
    assert iou_xywh(a, [10, 0, 10, 10]) == 0.0  # touching edges of half-open boxes do not overlap
    assert iou_xywh(a, [np.nan] * 4) == 0.0
    np.testing.assert_allclose(iou_xywh(a[None], np.array([[0, 0, 10, 10], [0, 0, 20, 10]])), [1.0, 0.5])


def test_label_boxes_match_box_from_mask_for_every_id():
    from dvsot.dataset.boxes import label_boxes

    rng = np.random.default_rng(3)
    img = np.zeros((30, 40), np.uint8)
    img[5:9, 10:20] = 1
    img[20:29, 0:3] = 2
    img[rng.integers(0, 30, 5), rng.integers(0, 40, 5)] = 7
    ids = np.array([0, 1, 2, 7, 9])
    boxes, counts = label_boxes(img, ids)
    for j, i in enumerate(ids):
        np.testing.assert_array_equal(boxes[j], box_from_mask(img == i))
        assert counts[j] == np.count_nonzero(img == i)
    assert np.isnan(boxes[4]).all() and counts[4] == 0


def test_object_rows_give_visibility_and_truncation_per_object():
    from dvsot.dataset.boxes import object_rows, truncation_share

    img = np.zeros((10, 10), np.uint8)
    img[2:6, 2:6] = 2  # the occluder, in front of half the target
    img[2:6, 6:8] = 1
    target = np.zeros((10, 10), bool)
    target[2:6, 4:8] = True  # 16 px amodal, 8 visible
    occluder = img == 2
    rows = object_rows(img, np.array([0, 1, 2, 255]), {1: (target, 16.0, 64.0), 2: (occluder, 16.0, 16.0)})
    np.testing.assert_array_equal(rows["boxes_amodal"][1], [4, 2, 4, 4])
    np.testing.assert_array_equal(rows["boxes_visible"][1], [6, 2, 2, 4])
    assert rows["px_visible"].tolist() == [100 - 24, 8, 16, 0] and rows["px_amodal"].tolist() == [0, 16, 16, 0]
    assert rows["visibility"][1] == 0.5 and rows["visibility"][2] == 1.0
    assert rows["truncation"][1] == 0.75 and rows["truncation"][2] == 0.0
    assert np.isnan(rows["visibility"][[0, 3]]).all() and np.isnan(rows["boxes_amodal"][0]).all()
    assert truncation_share(0.0, 0.0) == 1.0 and truncation_share(5.0, 4.0) == 0.0
