"""The streaming table and latency_scale.png give each row's scale factor at half its latency-free ARscore."""

from __future__ import annotations

import matplotlib.pyplot as plt
import pytest

from benchmarks.analysis.stream_tables import format_stream, half_text, scale_figure
from benchmarks.evaluation.stream_summary import half_factor

FREE_SCORE = {"fast": 0.8, "slow": 0.9}
CURVES = {"fast": [(1.0, 0.8), (2.0, 0.6), (4.0, 0.2)], "slow": [(1.0, 0.9), (8.0, 0.6)]}


def cell(arscore: float) -> dict:
    latency = {"mean_s": 0.01, "p50_s": 0.01, "p90_s": 0.01, "max_s": 0.01, "calls": 5}
    return {"all": {"A": arscore, "R": arscore, "ARscore": arscore, "AUC": arscore, "P@20": 1.0, "queries": 9,
                    "latency": latency}}


def summary() -> dict:
    rows = {r: {"free": cell(FREE_SCORE[r]), **{f"scaled:{f:g}": cell(s) for f, s in c}} for r, c in CURVES.items()}
    return {"rows": rows, "drop": {}, "scale_curves": CURVES, "settings": {"query_hz": 1000.0, "window": "last"},
            "half_factor": {r: half_factor(c, FREE_SCORE[r]) for r, c in CURVES.items()}}


def test_the_table_gives_the_interpolated_half_factor_or_how_far_the_factors_reach():
    # fast: half of 0.8 is 0.4, between 0.6 at x2 and 0.2 at x4: 2 + 2 (0.6 - 0.4) / (0.6 - 0.2) = 3
    text = format_stream(summary())
    assert "| fast | 3 | 0.400 |" in text
    assert "| slow | not reached up to 8 | 0.450 |" in text
    assert half_text({"factor": 0.5, "reached": True, "at_or_below": True}, [(0.5, 0.1)]) == \
        "0.5 (or below: the smallest factor)"


def test_the_plot_marks_each_half_point_and_names_its_factor():
    fig = scale_figure(summary())
    try:
        ax = fig.axes[0]
        crosses = [(list(ln.get_xdata()), list(ln.get_ydata())) for ln in ax.lines if ln.get_marker() == "x"]
        assert len(crosses) == 1 and crosses[0][0] == pytest.approx([3.0]) and crosses[0][1] == pytest.approx([0.4])
        labels = [t.get_text() for t in ax.get_legend().get_texts()]
        assert labels == ["fast (half at x3)", "slow (half not reached up to 8)"]
    finally:
        plt.close(fig)


def test_a_predictive_row_shares_its_trackers_colour_dashed_and_the_axis_names_the_factors():
    s = summary()
    s["scale_curves"]["fast (predictive)"] = [(1.0, 0.7), (2.0, 0.65), (4.0, 0.5)]
    s["rows"]["fast (predictive)"] = s["rows"]["fast"]
    s["half_factor"]["fast (predictive)"] = half_factor(s["scale_curves"]["fast (predictive)"], 0.8)
    fig = scale_figure(s)
    try:
        ax = fig.axes[0]
        curves = {ln.get_label(): ln for ln in ax.lines if not ln.get_label().startswith("_")}
        plain, pred = curves["fast (half at x3)"], curves["fast (predictive) (half not reached up to 4)"]
        assert plain.get_color() == pred.get_color() != curves["slow (half not reached up to 8)"].get_color()
        assert plain.get_linestyle() == "-" and pred.get_linestyle() == "--"
        assert [t for t in ax.get_xticks()] == pytest.approx([1.0, 2.0, 4.0, 8.0])
    finally:
        plt.close(fig)
