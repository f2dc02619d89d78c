"""Scores per challenge attribute as outputs: a Markdown table, attributes.json (with the thresholds), a bar chart.

The attributes and their scores come from benchmarks.evaluation.attributes.
"""

from __future__ import annotations

import json
import os
from dataclasses import asdict
from pathlib import Path

import numpy as np

from benchmarks.analysis.tables import write_text_atomic
from benchmarks.evaluation.attributes import ATTRIBUTES, THRESHOLDS, attribute_ope, attribute_scores
from benchmarks.evaluation.metrics import ALL, Scores
from benchmarks.evaluation.ope import PRECISION_PX
from benchmarks.evaluation.protocol import SequenceResult
from benchmarks.evaluation.safe_names import markdown_cell


def _columns(summary: dict) -> list[str]:
    names = {n for per in summary.values() for n in per}
    return [n for n in (ALL, *ATTRIBUTES) if n in names]


def _count(v, protocol: str) -> int:
    """Counted segments of one tracker's cell: each tracker has its own (re-initialisations differ)."""
    return v.segments if protocol == "ar" else v["segments"]


def _f(v: float) -> str:
    return "-" if v is None or np.isnan(v) else f"{v:.3f}"


def format_attributes(summary: dict, protocol: str = "ar") -> str:
    """A Markdown table, a row per tracker, a column per attribute beside 'all': ARscore (A / R), or AUC (P@20)
    for one-pass runs, and the tracker's own counted segments in each cell."""
    cols = _columns(summary)
    lines = ["| tracker | " + " | ".join(cols) + " |", "|---" * (len(cols) + 1) + "|"]
    for tracker, per in summary.items():
        cells = []
        for c in cols:
            v = per.get(c)
            if v is None:
                cells.append("")
            elif protocol == "ar":
                cells.append(f"**{_f(v.arscore)}** ({_f(v.accuracy)} / {_f(v.robustness)}), {_count(v, protocol)} seg")
            else:
                cells.append(f"**{_f(v['AUC'])}** ({_f(v[f'P@{PRECISION_PX}'])}), {_count(v, protocol)} seg")
        lines.append(f"| {markdown_cell(tracker)} | " + " | ".join(cells) + " |")
    what = "ARscore (A / R)" if protocol == "ar" else "success AUC (precision at 20 px)"
    return "\n".join(lines) + f"\n\nEach cell: {what} over the tracker's counted segments with the attribute, " \
                              "and how many (each tracker's own: re-initialisations differ); `absent`: the " \
                              "segments with the target wholly hidden, scored apart (not in 'all' or any other " \
                              "column; benchmarks/evaluation/protocol.py, rule 6). benchmarks/evaluation/" \
                              "attributes.py; thresholds in THRESHOLDS.\n"


def attributes_json(summary: dict, protocol: str = "ar") -> dict:
    """The summary as plain values (NaN as None), with the thresholds."""
    def clean(v):
        if isinstance(v, Scores):
            v = asdict(v)
        if isinstance(v, dict):
            return {k: clean(x) for k, x in v.items()}
        return None if isinstance(v, float) and np.isnan(v) else v
    return {"protocol": protocol, "thresholds": asdict(THRESHOLDS), "scores": clean(summary)}


def plot_attributes(summary: dict, path: str | os.PathLike, protocol: str = "ar") -> Path:
    """A bar chart: per attribute (and 'all'), each tracker's ARscore (or success AUC) with its own counted segments
    over its bar; written atomically."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from benchmarks.analysis.pictures import save_figure
    from benchmarks.evaluation.safe_names import plot_text

    cols = _columns(summary)
    fig, ax = plt.subplots(figsize=(max(5.0, 1.1 * len(cols) + 2), 4))
    width = 0.8 / max(len(summary), 1)
    for k, (tracker, per) in enumerate(summary.items()):
        values = [np.nan if c not in per else (per[c].arscore if protocol == "ar" else per[c]["AUC"]) for c in cols]
        bars = ax.bar(np.arange(len(cols)) + k * width, np.nan_to_num(values), width, label=plot_text(tracker))
        ax.bar_label(bars, labels=["" if c not in per else str(_count(per[c], protocol)) for c in cols],
                     fontsize=6, rotation=90, padding=2)
    ax.set_xticks(np.arange(len(cols)) + width * (len(summary) - 1) / 2)
    ax.set_xticklabels(cols, rotation=30, ha="right")
    ax.set_ylabel("ARscore" if protocol == "ar" else "success AUC")
    ax.set_ylim(0, 1.15)
    ax.set_title("per attribute (each tracker's counted segments over its bar)")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3, axis="y")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    return save_figure(fig, path, 120, bbox_inches="tight")


def write_attributes(results: list[SequenceResult], out_dir: str | os.PathLike, protocol: str = "ar") -> list[Path]:
    """attributes.md, attributes.json and attributes.png of a run's results in out_dir."""
    summary = attribute_scores(results) if protocol == "ar" else attribute_ope(results)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    return [write_text_atomic(out / "attributes.md", format_attributes(summary, protocol)),
            write_text_atomic(out / "attributes.json", json.dumps(attributes_json(summary, protocol), indent=2)),
            plot_attributes(summary, out / "attributes.png", protocol)]
