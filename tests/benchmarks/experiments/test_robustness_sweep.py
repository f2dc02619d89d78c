"""benchmarks.experiments.robustness: kept frames re-simulated under presets and noise rates, tracked, tabled and plotted."""

from __future__ import annotations

import csv

import numpy as np
import pytest

from dvsot.events import EventParams, EventSimulator
from dvsot.pipeline.sequence import write_sequence


def kept_sequence(tmp_path, width=96, height=72, n=41):
    """A bright square crossing a textured wall at 1 kHz: its frames kept as .npy and its dataset file."""
    frames_dir = tmp_path / "frames"
    frames_dir.mkdir()
    yy, xx = np.mgrid[0:height, 0:width].astype(np.float32)
    wall = 0.2 + 0.05 * np.sin(0.5 * xx) * np.cos(0.4 * yy)
    t_us = np.arange(n) * 1000
    boxes = []
    frames = []
    for i in range(n):
        x, y = 10 + 0.6 * i, 20 + 0.2 * i
        f = wall.copy()
        xi, yi = int(x), int(y)
        f[yi:yi + 16, xi:xi + 16] = 0.8 + 0.1 * np.sin(xx[yi:yi + 16, xi:xi + 16])
        np.save(frames_dir / f"{i:06d}.npy", f)
        frames.append(f)
        boxes.append([xi, yi, 16, 16])
    boxes = np.array(boxes, np.float32)
    sim = EventSimulator(width, height, EventParams(), 3)
    path, _ = write_sequence(tmp_path / "seq.h5", frames, t_us, sim, {"name": "seq", "split": "test",
                                                                      "event_seed": 3}, 10_000,
                             boxes=lambda: (t_us, boxes, boxes))
    return path, frames_dir


def test_sweep_tables_arscore_per_tracker_against_the_noise_rate(tmp_path):
    from benchmarks.experiments.robustness import resimulate, sweep, write_outputs

    seq, frames = kept_sequence(tmp_path)
    # the ideal preset re-simulates the sequence's own events
    resimulate(seq, frames, tmp_path / "again.h5", {"preset": "ideal"})
    from dvsot.dataset import Dataset
    from dvsot.events.batch import EventBatch

    with Dataset(seq) as a, Dataset(tmp_path / "again.h5") as b:
        ea, eb = EventBatch.concatenate(list(a.chunks())), EventBatch.concatenate(list(b.chunks()))
    assert np.array_equal(ea.t, eb.t) and np.array_equal(ea.x, eb.x) and np.array_equal(ea.p, eb.p)

    rows = sweep(seq, frames, ["rct"], ["ideal", "noisy"], [200.0], tmp_path / "out", max_segments=4)
    assert [r["variant"] for r in rows] == ["ideal_noise200", "noisy_noise200"]
    assert rows[0]["measured_noise_hz"] == pytest.approx(200, rel=0.1) and rows[0]["set_shot_noise_hz"] == 200
    assert all(0 <= r["rct_ARscore"] <= 1 for r in rows)
    write_outputs(rows, ["rct"], tmp_path / "out", "seq")
    with open(tmp_path / "out" / "robustness.csv") as f:
        assert len(list(csv.DictReader(f))) == 2
    assert "rct ARscore" in (tmp_path / "out" / "robustness.md").read_text()
    assert (tmp_path / "out" / "robustness.png").stat().st_size > 1000


def test_frames_that_do_not_match_the_sequence_are_refused(tmp_path):
    from benchmarks.experiments.robustness import resimulate
    from dvsot.errors import UserError

    seq, frames = kept_sequence(tmp_path, n=12)
    (frames / "000011.npy").unlink()
    with pytest.raises(UserError, match=r"11 frames \(\.npy\), but .* has 12 render samples"):
        resimulate(seq, frames, tmp_path / "x.h5", {"preset": "davis346"})
    assert not (tmp_path / "x.h5").exists()
