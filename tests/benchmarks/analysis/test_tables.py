"""Tables in every format from hand-made results."""

import csv
import io
import json

import numpy as np
import pytest

from benchmarks.analysis.tables import summarise, terminal, to_csv, to_json, to_latex, to_markdown, write_tables
from benchmarks.evaluation.protocol import SequenceResult


def results():
    def r(tracker, seq, ious, error=None):
        ious = np.array(ious, float)
        return SequenceResult(tracker, seq, ious, np.zeros((len(ious), 4)), [0], 0.5, int((~np.isnan(ious)).sum()),
                              error=error)
    return [r("sctn", "city_cat", [np.nan, 0.9, 0.8]), r("sctn", "sky_cube", [np.nan, 0.4, np.nan, 0.6]),
            r("rct", "city_cat", [np.nan, 0.2, np.nan]), r("rct", "sky_cube", [np.nan], error="ValueError: x")]


def test_summary_and_all_column():
    s = summarise(results())
    assert s["sctn"]["city_cat"]["A"] == pytest.approx(0.85) and s["sctn"]["city_cat"]["R"] == 1.0
    assert s["sctn"]["all"]["A"] == pytest.approx((0.9 + 0.8 + 0.4 + 0.6) / 4)
    assert s["sctn"]["all"]["R"] == pytest.approx(3 / 4)
    assert s["rct"]["all"]["segments"] == 1 and s["rct"]["sky_cube"]["error"]


def test_every_format(tmp_path):
    s = summarise(results())
    text = terminal(s)
    assert "city_cat" in text and "failed" in text and "0.850  1.000" in text
    rows = list(csv.DictReader(io.StringIO(to_csv(s))))
    assert {(r["tracker"], r["sequence"]) for r in rows} >= {("sctn", "all"), ("rct", "sky_cube")}
    assert json.loads(to_json(s))["sctn"]["all"]["segments"] == 4
    assert "| sctn |" in to_markdown(s) and "**" in to_markdown(s)
    tex = to_latex(s)
    assert tex.startswith(r"\begin{tabular}") and r"city\_cat" in tex and tex.count(r"\\") >= 7
    paths = write_tables(s, tmp_path / "out")
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == sorted(
        ["table.txt", "results.csv", "results.json", "results.md", "results.tex"])
    assert set(paths) == {"txt", "csv", "json", "md", "tex"}
