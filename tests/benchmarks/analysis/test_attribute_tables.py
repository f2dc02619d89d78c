"""Scores per attribute as outputs (benchmarks/analysis/attribute_tables.py): the table, attributes.json, the
bench report's attribute files."""

from __future__ import annotations

import json

import numpy as np

from benchmarks.analysis.attribute_tables import format_attributes, write_attributes
from benchmarks.evaluation.attributes import THRESHOLDS, attribute_scores
from benchmarks.evaluation.protocol import SequenceResult


def _result(tracker, seq, iou, tags, centre=None):
    r = SequenceResult(tracker, seq, np.asarray(iou, float), np.zeros((len(iou), 4), np.float32), [0], 1.0, len(iou))
    r.extra["attributes"] = {k: np.asarray(v, bool) for k, v in tags.items()}
    if centre is not None:
        r.extra["centre_error"] = np.asarray(centre, float)
    return r


def test_the_table_counts_each_attributes_segments():
    a = _result("t", "a", [np.nan, 0.8, 0.2, 0.6], {"occlusion": [0, 0, 1, 1], "small_target": [1, 1, 1, 1]})
    b = _result("t", "b", [np.nan, 0.4, 1.0], {"small_target": [0, 0, 1]})  # no visibility: no occlusion tag
    scores = attribute_scores([a, b])
    table = format_attributes(scores)
    assert table.startswith("| tracker | all | occlusion | small_target |")
    s = scores["t"]["occlusion"]  # A 0.4, R 0.5 (tests/benchmarks/evaluation/test_segment_attributes.py)
    assert f"| **{s.arscore:.3f}** (0.400 / 0.500), 2 seg |" in table and "(0.650 / 0.750), 4 seg |" in table


def test_one_pass_attribute_files(tmp_path):
    a = _result("t", "a", [np.nan, 0.8, 0.2, 0.6], {"occlusion": [0, 0, 1, 1]}, centre=[np.nan, 1, 30, 5])
    paths = write_attributes([a], tmp_path, protocol="ope")
    assert [p.name for p in paths] == ["attributes.md", "attributes.json", "attributes.png"]
    data = json.loads((tmp_path / "attributes.json").read_text())
    assert data["thresholds"]["occlusion_visibility"] == THRESHOLDS.occlusion_visibility
    assert data["scores"]["t"]["occlusion"]["segments"] == 2


def test_bench_report_holds_the_attribute_files(tmp_path):
    from benchmarks.analysis.report import report_files, write_report
    from benchmarks.analysis.tables import summarise

    results = [_result("t", "a", [np.nan, 0.8, 0.2, 0.6], {"occlusion": [0, 0, 1, 1]})]
    paths = write_report(tmp_path, summarise(results), results)
    for name in ("attributes.md", "attributes.json", "attributes.png"):
        assert (tmp_path / name).is_file() and report_files()[name] == "tables"
    assert "(0.400 / 0.500), 2 seg |" in (tmp_path / "attributes.md").read_text()
    assert json.loads((tmp_path / "run.json").read_text()) and paths["manifest"]


class _Scripted:
    """The ground truth, shifted off the target (IoU 0) on the segments in `miss`."""

    def __init__(self, gt, miss):
        self.gt, self.miss = gt, set(miss)

    def init(self, segment, box_xywh, width, height):
        pass

    def update(self, segment):
        box = self.gt[segment.index].copy()
        box[0] += box[2] if segment.index in self.miss else 0.0
        return box

    def energy_per_segment(self):
        return None


def test_two_trackers_that_reinitialise_differently_each_show_their_own_counts(tmp_path):
    from benchmarks.analysis.attribute_tables import plot_attributes
    from benchmarks.evaluation.attributes import add_attributes
    from benchmarks.evaluation.protocol import run_sequence
    from dvsot.dataset import Dataset, DatasetWriter

    n = 12  # segment i ends at row i + 1; the target 70 % hidden over segments 4..7
    visibility = np.ones(n + 1)
    visibility[5:9] = 0.3
    with DatasetWriter(tmp_path / "s.h5", 100, 100, 10_000, {"name": "s"}) as w:
        w.append_boxes(np.arange(n + 1) * 10_000, np.tile([10.0, 10.0, 20.0, 20.0], (n + 1, 1)), None, visibility)
        w.close(n * 10_000 + 1)
    results = []
    with Dataset(tmp_path / "s.h5") as ds:
        for name, miss in (("steady", []), ("slips", [3])):  # slips fails on 3 and is re-initialised on 4
            results.append(add_attributes(run_sequence(_Scripted(ds.segment_boxes(), miss), ds, name), ds))
    assert results[0].init_segments == [0] and results[1].init_segments == [0, 4]
    scores = attribute_scores(results)
    assert scores["steady"]["occlusion"].segments == 4 and scores["slips"]["occlusion"].segments == 3
    assert scores["steady"]["all"].segments == 11 and scores["slips"]["all"].segments == 10
    table = format_attributes(scores)
    assert "| steady | **1.000** (1.000 / 1.000), 11 seg | **1.000** (1.000 / 1.000), 4 seg |" in table
    assert "| slips | " in table and "), 10 seg |" in table and "), 3 seg |" in table
    import matplotlib.axes

    labels = []
    real = matplotlib.axes.Axes.bar_label
    matplotlib.axes.Axes.bar_label = lambda self, bars, labels_=None, **kw: labels.append(kw.get("labels"))
    try:
        plot_attributes(scores, tmp_path / "a.png")
    finally:
        matplotlib.axes.Axes.bar_label = real
    # all, occlusion, absent, fast_motion, small_target, low_event_density (no events): each tracker's own counts
    assert labels == [["11", "4", "0", "0", "0", "11"], ["10", "3", "0", "0", "0", "10"]]
    assert (tmp_path / "a.png").stat().st_size > 0
