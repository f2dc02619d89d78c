"""A, R, ARscore against hand computation (paper eq. 8-10, b = 2), and the 'all' pooling."""

import numpy as np
import pytest

from benchmarks.evaluation.metrics import ar_score, pooled, scores
from dvsot.dataset.boxes import iou_xywh


def test_iou_by_hand():
    assert iou_xywh([0, 0, 10, 10], [5, 0, 10, 10]) == pytest.approx(50 / 150)
    assert iou_xywh([0, 0, 10, 10], [0, 0, 10, 10]) == 1.0
    assert iou_xywh([0, 0, 10, 10], [20, 20, 5, 5]) == 0.0
    assert iou_xywh([0, 0, 4, 4], [1, 1, 2, 2]) == pytest.approx(4 / 16)
    assert iou_xywh([np.nan] * 4, [0, 0, 1, 1]) == 0.0


def test_arscore_b2_by_hand():
    # (1 + 4) * 0.8 * 0.6 / (4 * 0.8 + 0.6) = 2.4 / 3.8
    assert ar_score(0.8, 0.6) == pytest.approx(2.4 / 3.8)
    assert ar_score(0.5, 0.5) == pytest.approx(0.5)
    assert ar_score(0.0, 0.0) == 0.0
    assert ar_score(0.8, 0.6, beta=1) == pytest.approx(2 * 0.48 / 1.4)
    # the paper's SCTN "all" column: A 0.773, R 0.960 -> 0.916
    assert ar_score(0.773, 0.960) == pytest.approx(0.916, abs=5e-4)


def test_scores_ignore_uncounted_and_pool_over_segments_not_sequences():
    a = np.array([np.nan, 0.9, 0.7, 0.3, np.nan, 0.8])   # 4 counted, 1 failure
    b = np.array([np.nan, 0.6, np.nan])                  # 1 counted
    sa = scores(a)
    assert (sa.segments, sa.failures) == (4, 1)
    assert sa.accuracy == pytest.approx(0.675) and sa.robustness == pytest.approx(0.75)
    al = pooled([a, b])
    assert al.segments == 5 and al.accuracy == pytest.approx((0.9 + 0.7 + 0.3 + 0.8 + 0.6) / 5)
    assert al.robustness == pytest.approx(4 / 5)
    assert al.arscore == pytest.approx(ar_score(3.3 / 5, 0.8))
    assert np.isnan(scores(np.array([np.nan])).accuracy)
