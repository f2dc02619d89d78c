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
    assert "| t |" in table and "occlusion (2 seg)" in table and "small_target (4 seg)" in table
    s = scores["t"]["occlusion"]  # A 0.4, R 0.5 (tests/benchmarks/evaluation/test_segment_attributes.py)
    assert f"| **{s.arscore:.3f}** (0.400 / 0.500) |" in table


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
    assert "occlusion (2 seg)" in (tmp_path / "attributes.md").read_text()
    assert json.loads((tmp_path / "run.json").read_text()) and paths["manifest"]
