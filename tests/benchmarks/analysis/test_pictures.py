"""Benchmark pictures: the IoU-over-time PNG and the tracking video."""

import numpy as np
import pytest

from benchmarks.analysis.pictures import plot_iou_over_time


def test_iou_plot_writes_a_png(tmp_path):
    rng = np.random.default_rng(0)
    first = np.r_[np.nan, rng.random(59)]          # the init segment does not count
    results = {"rct": {"seq_a": first, "seq_b": rng.random(30)},
               "csrt": {"seq_a": rng.random(60)}}  # csrt did not run on seq_b
    out = plot_iou_over_time(results, tmp_path / "sub" / "iou.png")
    data = out.read_bytes()
    assert out == tmp_path / "sub" / "iou.png"
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 10_000


def test_iou_plot_rejects_empty_results(tmp_path):
    with pytest.raises(ValueError):
        plot_iou_over_time({}, tmp_path / "x.png")
