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


def _iou_by_hand(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """IoU of xywh rows, written apart from dvsot.dataset.boxes: corners, overlap, union; a non-finite row scores 0."""
    lo, hi = np.maximum(a[:, :2], b[:, :2]), np.minimum(a[:, :2] + a[:, 2:], b[:, :2] + b[:, 2:])
    inter = np.prod(np.clip(hi - lo, 0, None), axis=1)
    union = np.prod(a[:, 2:], axis=1) + np.prod(b[:, 2:], axis=1) - inter
    return np.nan_to_num(inter / union, nan=0.0)


def _auc_by_counting(ious: np.ndarray) -> float:
    """Success AUC without a curve: an IoU u clears the thresholds k/20 < u, ceil(20 u) of the 21, averaged."""
    cleared = np.where(ious > 0, np.minimum(np.ceil(20 * ious), 21), 0)
    return float(np.mean(cleared / 21))


def test_got10k_layout_reproduces_the_pooled_auc(data, tmp_path):
    from benchmarks.evaluation.protocol import MIN_BOX_PX
    from dvsot.dataset import Dataset

    late = tmp_path / "late.h5"  # ten segments, the target's box known from 15 ms: segment 0 has none
    with DatasetWriter(late, 64, 48, attrs={"split": "test"}) as w:
        t = np.arange(10) * 10_000 + 1
        w.append_events(EventBatch(np.full(10, 3, np.uint16), np.full(10, 3, np.uint16), t, np.ones(10, np.uint8)))
        w.append_boxes([15_000, 100_000], [[5, 5, 10, 10], [5, 5, 10, 10]])
        w.close(100_000)
    out = tmp_path / "ope"
    assert main(["bench", "--tracker", "test-script", "--data", str(tmp_path), "--out", str(out),
                 "--jobs", "1", "--quiet", "--protocol", "ope"]) == 0
    d = out / "test-script"
    pooled, per_sequence = [], []
    for path in (data, late):
        seq = path.stem
        pred = np.loadtxt(d / seq / f"{seq}_001.txt", delimiter=",")  # GOT-10k's layout, as got10k reads it
        assert (d / seq / f"{seq}_time.txt").read_text() == (d / "times" / f"{seq}_time.txt").read_text()
        np.testing.assert_array_equal(pred, np.loadtxt(d / f"{seq}.txt", delimiter=","), strict=True)
        with Dataset(path) as ds:
            gt, scored = ds.segment_boxes(), ds.segment_scored()
        init = int(np.flatnonzero(np.isfinite(pred).all(axis=1))[0])  # the first box given: not scored
        ok = scored & np.isfinite(gt).all(axis=1) & (gt[:, 2:] >= MIN_BOX_PX).all(axis=1)
        ok[: init + 1] = False
        ious = _iou_by_hand(pred[ok], gt[ok])
        pooled.append(ious)
        per_sequence.append(_auc_by_counting(ious))
    assert [len(v) for v in pooled] == [5, 8]  # late.h5: init on segment 1, scored from 2
    summary = json.loads((out / "ope.json").read_text())["test-script"]
    assert summary["all"]["AUC"] == pytest.approx(_auc_by_counting(np.concatenate(pooled)), abs=1e-12)
    assert summary["seq"]["AUC"] == pytest.approx(per_sequence[0], abs=1e-12)
    assert summary["late"]["AUC"] == pytest.approx(per_sequence[1], abs=1e-12)
    # got10k's report averages the sequences' curves: each sequence weighs the same, whatever its length
    assert np.mean(per_sequence) != pytest.approx(summary["all"]["AUC"], abs=1e-4)
