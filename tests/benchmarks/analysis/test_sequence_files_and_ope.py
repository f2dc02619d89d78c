"""dvsot bench's per-sequence files (OTB boxes, VOT trajectory, times) and --protocol ope, on a hand-computed case."""

from __future__ import annotations

import json

import numpy as np
import pytest

from benchmarks.evaluation.ope import centre_errors, precision_curve, success_curve
from benchmarks.trackers import register
from benchmarks.trackers.base import Tracker
from dvsot.cli import main
from dvsot.dataset import DatasetWriter
from dvsot.events import EventBatch

N = 6  # segments; the target stands still at 5,5,10,10


@register("test-script")
class Script(Tracker):
    """Predicts the initial box moved right by 2 px (IoU 80/120), by 8 px on segment 3 (IoU 20/180, a failure)."""

    def init(self, segment, box_xywh, width, height):
        self.box = box_xywh.copy()

    def update(self, segment):
        out = self.box.copy()
        out[0] += 8 if segment.index == 3 else 2
        return out


@pytest.fixture
def data(tmp_path):
    path = tmp_path / "seq.h5"
    with DatasetWriter(path, 64, 48, attrs={"split": "test"}) as w:
        t = np.arange(N) * 10_000 + 1
        w.append_events(EventBatch(np.full(N, 3, np.uint16), np.full(N, 3, np.uint16), t, np.ones(N, np.uint8)))
        w.append_boxes([0, N * 10_000], [[5, 5, 10, 10], [5, 5, 10, 10]])
        w.close(N * 10_000)
    return path


def _bench(data, out, *extra):
    return main(["bench", "--tracker", "test-script", "--data", str(data), "--out", str(out), "--jobs", "1",
                 "--quiet", *extra])


def test_otb_vot_and_time_files(data, tmp_path):
    out = tmp_path / "run"
    assert _bench(data, out) == 0
    d = out / "test-script"
    boxes = np.loadtxt(d / "seq.txt", delimiter=",")  # as got10k / pytracking read a result file
    want = np.array([[5, 5, 10, 10], [7, 5, 10, 10], [7, 5, 10, 10], [13, 5, 10, 10], [5, 5, 10, 10], [7, 5, 10, 10]])
    np.testing.assert_array_equal(boxes, want)
    # segment 0: init; 1, 2: tracked; 3: failure; 4: re-initialised; 5: tracked
    vot = (d / "baseline" / "seq" / "seq_001.txt").read_text().splitlines()
    assert vot == ["1", "7.000,5.000,10.000,10.000", "7.000,5.000,10.000,10.000", "2", "1", "7.000,5.000,10.000,10.000"]
    times = np.loadtxt(d / "times" / "seq_time.txt")
    assert times.shape == (N,) and np.isfinite(times).all() and (times >= 0).all()
    timing = (d / "timing.csv").read_text().splitlines()
    assert timing[0].startswith("sequence,segments_asked,inits") and timing[1].startswith("seq,6,2,")
    assert json.loads((out / "results.json").read_text())  # the A / R tables are still there


def test_one_pass_protocol(data, tmp_path, capsys):
    out = tmp_path / "ope"
    assert _bench(data, out, "--protocol", "ope") == 0
    summary = json.loads((out / "ope.json").read_text())["test-script"]
    # IoUs 2/3, 2/3, 1/9, 2/3, 2/3 (no re-initialisation after segment 3): success 1 for t < 1/9 (0, 0.05,
    # 0.1), 0.8 for 0.15 .. 0.65 (11 thresholds), 0 from 0.7: AUC = (3 + 11 * 0.8) / 21; centre errors 2, 2, 8, 2, 2
    assert summary["all"]["AUC"] == pytest.approx((3 + 11 * 0.8) / 21)
    assert summary["all"]["P@20"] == 1.0 and summary["seq"]["segments"] == 5
    assert summary["all"]["precision"][2] == pytest.approx(0.8) and summary["all"]["precision"][1] == 0.0
    boxes = np.loadtxt(out / "test-script" / "seq.txt", delimiter=",")
    np.testing.assert_array_equal(boxes[:, 0], [5, 7, 7, 13, 7, 7])
    assert not (out / "test-script" / "baseline").exists() and not (out / "results.json").exists()
    assert (out / "success_plot.png").stat().st_size > 0 and (out / "precision_plot.png").stat().st_size > 0
    assert "0.562 / 1.000" in capsys.readouterr().out


def test_curves_and_centre_errors():
    np.testing.assert_allclose(centre_errors([[0, 0, 2, 2], [np.nan] * 4], [[3, 4, 2, 2], [0, 0, 1, 1]]), [5, np.inf])
    s = success_curve(np.array([0.0, 0.5, 1.0, np.nan]))
    assert s[0] == pytest.approx(2 / 3) and s[10] == pytest.approx(1 / 3) and s[20] == 0.0
    p = precision_curve(np.array([0.0, 20.0, 20.5, np.inf]))
    assert p[0] == 0.25 and p[20] == 0.5 and p[50] == 0.75
