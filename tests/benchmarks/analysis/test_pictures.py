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


def test_segment_side_by_side_draws_each_file_with_its_counts(tmp_path):
    from benchmarks.analysis.pictures import plot_segment_side_by_side
    from dvsot.events import EventParams, EventSimulator
    from dvsot.pipeline.sequence import write_sequence

    t_us = np.arange(21) * 1000
    frames = [np.full((30, 40), 0.2, np.float32) for _ in t_us]
    for i, f in enumerate(frames):
        f[10:20, 5 + i:15 + i] = 0.8
    boxes = np.array([[5 + i, 10, 10, 10] for i in range(len(t_us))], np.float32)
    files = {}
    for name, noise in (("quiet", 0.0), ("noisy", 500.0)):
        sim = EventSimulator(40, 30, EventParams(shot_noise_hz=noise), 1)
        files[name], _ = write_sequence(tmp_path / f"{name}.h5", frames, t_us, sim, {"name": name, "split": "test"},
                                        10_000, boxes=lambda: (t_us, boxes, boxes))
    out = plot_segment_side_by_side(files, 1, tmp_path / "pics" / "side.png")
    data = out.read_bytes()
    assert out == tmp_path / "pics" / "side.png" and data[:8] == b"\x89PNG\r\n\x1a\n"
    with pytest.raises(ValueError, match="segment 5 out of range 0..1"):
        plot_segment_side_by_side(files, 5, tmp_path / "bad.png")
    assert not (tmp_path / "bad.png").exists()
