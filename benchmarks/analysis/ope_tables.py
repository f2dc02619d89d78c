"""One-pass evaluation's outputs: the AUC / P@20 table, the success and precision plots, ope.json and ope.md.

The scores and curves come from benchmarks.evaluation.ope.summarise_ope.
"""

from __future__ import annotations

import os
from pathlib import Path

from benchmarks.analysis.tables import write_summary
from benchmarks.evaluation.metrics import ALL
from benchmarks.evaluation.ope import IOU_THRESHOLDS, PIXEL_THRESHOLDS, PRECISION_PX
from benchmarks.evaluation.safe_names import markdown_cell  # sequence and tracker names are free text


def format_ope(summary: dict) -> str:
    """A Markdown table: success AUC / precision at 20 px per tracker and sequence, then 'all'."""
    sequences: list[str] = []
    for per in summary.values():
        sequences.extend(s for s in per if s != ALL and s not in sequences)
    head = "| tracker | " + " | ".join(map(markdown_cell, sequences)) + f" | {ALL} (AUC / P@{PRECISION_PX}) |"
    lines = [head, "|---" * (len(sequences) + 2) + "|"]
    for tracker, per in summary.items():
        cells = []
        for seq in sequences + [ALL]:
            v = per.get(seq)
            if v is None:
                cells.append("")
            elif "error" in v:
                cells.append("failed")
            else:
                cells.append(f"{v['AUC']:.3f} / {v[f'P@{PRECISION_PX}']:.3f}")
        lines.append(f"| {markdown_cell(tracker)} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def plot_ope(summary: dict, out_dir: str | os.PathLike) -> list[Path]:
    """success_plot.png and precision_plot.png of every tracker's 'all' curves, written atomically."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from benchmarks.analysis.pictures import save_figure
    from benchmarks.evaluation.safe_names import plot_text

    written = []
    for name, xs, key, score, xlabel in (
            ("success_plot.png", IOU_THRESHOLDS, "success", "AUC", "overlap threshold (IoU)"),
            ("precision_plot.png", PIXEL_THRESHOLDS, "precision", f"P@{PRECISION_PX}",
             "location error threshold (px)")):
        fig, ax = plt.subplots(figsize=(5, 4))
        for tracker, per in summary.items():
            if ALL in per:
                ax.plot(xs, per[ALL][key], label=f"{plot_text(tracker)} [{per[ALL][score]:.3f}]")
        ax.set_xlabel(xlabel)
        ax.set_ylabel("success rate" if key == "success" else "precision")
        ax.set_ylim(0, 1.02)
        ax.set_title(f"one-pass evaluation: {key} ({score} in brackets)")
        ax.legend(loc="lower left" if key == "success" else "lower right", fontsize=8)
        ax.grid(alpha=0.3)
        path = Path(out_dir) / name
        path.parent.mkdir(parents=True, exist_ok=True)
        written.append(save_figure(fig, path, 120, bbox_inches="tight"))
    return written


def write_ope(summary: dict, out_dir: str | os.PathLike) -> list[Path]:
    """ope.json (scores and curves), ope.md (the table) and the two plots in out_dir."""
    return write_summary(out_dir, "ope", summary, format_ope(summary)) + plot_ope(summary, out_dir)
