"""Streaming evaluation's outputs: stream.json, stream.md (the table), latency_scale.png (score against latency
scale, when scaled latencies ran) and per-sequence files of every answer with its availability time.

Per tracker, sequence and latency model, `<out>/<tracker>/stream/<sequence>.<model>.csv`: one row per call,
`kind` (init or update), the window `t0_us`, `t1_us` (the instant the answer describes), `latency_s`,
`available_us` (when the answer becomes available), the answer `x,y,w,h` and the predictive answer
`px,py,pw,ph` (pixels). The summary comes from benchmarks.evaluation.stream_summary.summarise_stream.
"""

from __future__ import annotations

import csv
import io
import os
from pathlib import Path

import numpy as np

from benchmarks.analysis.tables import write_summary, write_text_atomic
from benchmarks.evaluation.latency import FREE
from benchmarks.evaluation.metrics import ALL
from benchmarks.evaluation.ope import PRECISION_PX
from benchmarks.evaluation.safe_names import file_stem, markdown_cell
from benchmarks.evaluation.stream_summary import PREDICTIVE

STREAM_FILES = ("stream.json", "stream.md")
SCALE_PLOT = "latency_scale.png"


def _ms(v: float) -> str:
    return f"{v * 1e3:.2f}" if np.isfinite(v) else "nan"


def half_text(half: dict, curve: list) -> str:
    """The half-score factor as the table and the plot's legend give it (half: stream_summary.half_factor's answer,
    curve: [(factor, ARscore)] in increasing factor): the factor, or how far the factors given reach."""
    if not half["reached"]:
        return f"not reached up to {curve[-1][0]:g}"
    return f"{half['factor']:.3g}" + (" (or below: the smallest factor)" if half.get("at_or_below") else "")


def format_stream(summary: dict) -> str:
    """Markdown: per row and latency model the pooled A, R, ARscore, AUC, P@20, the latency-free ARscore and AUC
    and the drop, and the latency distribution (ms); then per row the scale factor at which its ARscore falls to
    half the latency-free one (scaled latencies), and the machine measured on."""
    p = f"P@{PRECISION_PX}"
    lines = ["| tracker | latency | A | R | ARscore | AUC | " + p + " | free ARscore | ARscore drop | free AUC | "
             "AUC drop | latency mean / p50 / p90 / max (ms) | queries |", "|---" * 13 + "|"]
    for row, per in summary["rows"].items():
        free = per.get(FREE, {}).get(ALL)
        for model, cells in per.items():
            if model in (FREE, "failed"):
                continue
            v = cells.get(ALL)
            if v is None:
                continue
            lat = v["latency"]
            d = summary["drop"].get(row, {}).get(model, {})
            lines.append(
                f"| {markdown_cell(row)} | {model} | {v['A']:.3f} | {v['R']:.3f} | {v['ARscore']:.3f} | {v['AUC']:.3f} "
                f"| {v[p]:.3f} | {free['ARscore']:.3f} | {d.get('ARscore', float('nan')):+.3f} | {free['AUC']:.3f} | "
                f"{d.get('AUC', float('nan')):+.3f} | {_ms(lat['mean_s'])} / {_ms(lat['p50_s'])} / "
                f"{_ms(lat['p90_s'])} / {_ms(lat['max_s'])} | {v['queries']} |")
        for seq in per.get("failed", {}):
            lines.append(f"| {markdown_cell(row)} | failed on {markdown_cell(seq)} | " + " | ".join([""] * 11) + " |")
    if summary.get("half_factor"):
        lines += ["", "| tracker | scale factor at half the latency-free ARscore | half ARscore |", "|---|---|---|"]
        for row, h in summary["half_factor"].items():
            lines.append(f"| {markdown_cell(row)} | {half_text(h, summary['scale_curves'][row])} | "
                         f"{h['half_score']:.3f} |")
    s = summary.get("settings", {})
    lines += ["", f"queries at {s.get('query_hz', float('nan')):g} Hz, window '{s.get('window')}', one pass (no "
                  "re-initialisation); free: called at every segment end, answers at once"]
    for m in summary.get("machines", []):
        lines.append(f"measured on {markdown_cell(str(m['node']))}: {markdown_cell(str(m['cpu']))}, {m['threads']} "
                     f"threads (torch {m['torch_threads']})")
    return "\n".join(lines)


def scale_figure(summary: dict):
    """The figure of latency_scale.png: per row the pooled ARscore against the latency scale factor (log axis), a
    cross where it falls to half its latency-free score (the factor in the legend), that score dotted; a tracker's
    predictive row shares its colour, dashed."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import FixedLocator, NullLocator, ScalarFormatter

    from benchmarks.evaluation.safe_names import plot_text

    curves = summary["scale_curves"]
    trackers = list(dict.fromkeys(row.removesuffix(PREDICTIVE) for row in curves))
    palette = plt.get_cmap("tab10" if len(trackers) <= 10 else "tab20")
    colour = {t: palette(i % palette.N) for i, t in enumerate(trackers)}
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    halves = summary.get("half_factor", {})
    factors: set[float] = set()
    for row, curve in curves.items():
        f, s = zip(*curve)
        factors.update(f)
        tracker = row.removesuffix(PREDICTIVE)
        predictive = row != tracker
        h = halves.get(row)
        label = plot_text(row) + (f" (half at x{half_text(h, curve)})" if h and h["reached"] else
                                  f" (half {half_text(h, curve)})" if h else "")
        ax.plot(f, s, marker="s" if predictive else "o", ms=4, ls="--" if predictive else "-", lw=1.2,
                color=colour[tracker], label=label)
        if not predictive:
            ax.axhline(summary["rows"][row][FREE][ALL]["ARscore"], color=colour[tracker], ls=":", lw=0.8)
        if h and h["reached"]:
            ax.plot([h["factor"]], [h["half_score"]], marker="x", ms=9, mew=2, ls="none", color=colour[tracker])
    ax.set_xscale("log", base=2)
    ax.xaxis.set_major_locator(FixedLocator(sorted(factors)))
    ax.xaxis.set_major_formatter(ScalarFormatter())
    ax.xaxis.set_minor_locator(NullLocator())
    ax.set_xlabel("latency scale factor (x measured)")
    ax.set_ylabel("streaming ARscore")
    ax.set_ylim(0, 1.02)
    ax.set_title("score against latency (dotted: latency-free; x: half the latency-free score;\n"
                 "dashed: predictive)", fontsize=10)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0)
    ax.grid(alpha=0.3)
    return fig


def plot_latency_scale(summary: dict, path: str | os.PathLike) -> Path:
    """latency_scale.png (scale_figure) written atomically to path."""
    from benchmarks.analysis.pictures import save_figure

    fig = scale_figure(summary)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    return save_figure(fig, path, 120, bbox_inches="tight")


def write_stream(summary: dict, out_dir: str | os.PathLike) -> list[Path]:
    """stream.json, stream.md and (when scaled latencies ran) latency_scale.png in out_dir."""
    paths = write_summary(out_dir, "stream", summary, format_stream(summary))
    if summary.get("scale_curves"):
        paths.append(plot_latency_scale(summary, Path(out_dir) / SCALE_PLOT))
    return paths


def stream_path(tracker: str, sequence: str, model: str) -> Path:
    """The per-sequence file of one tracker, sequence and latency model, relative to the run's directory."""
    return Path(file_stem(tracker)) / "stream" / f"{file_stem(sequence)}.{file_stem(model.replace(':', '-'))}.csv"


def stream_files(trackers: list[str], sequences: list[str], models: list[str]) -> list[Path]:
    """Every per-sequence file a streaming run may write (relative to its directory), the latency-free one too."""
    return [stream_path(t, s, m) for t in trackers for s in sequences for m in [FREE, *models]]


def calls_text(run) -> str:
    """One CSV row per call of a StreamRun: kind, window, latency, availability, answer and predictive answer."""
    text = io.StringIO()
    w = csv.writer(text, lineterminator="\n")
    w.writerow(["kind", "t0_us", "t1_us", "latency_s", "available_us", "x", "y", "w", "h", "px", "py", "pw", "ph"])
    for k in range(len(run.latency_s)):
        w.writerow(["init" if k == 0 else "update", int(run.window[k, 0]), int(run.window[k, 1]),
                    repr(float(run.latency_s[k])), int(run.available_us[k]),
                    *(f"{v:.3f}" for v in run.boxes[k]), *(f"{v:.3f}" for v in run.predicted[k])])
    return text.getvalue()


def write_stream_files(results: list, out_dir: str | os.PathLike) -> list[Path]:
    """Every finished run's per-sequence call files (each atomically)."""
    written = []
    for r in results:
        if r.error is not None:
            continue
        for model, run in r.runs.items():
            path = Path(out_dir) / stream_path(r.tracker, r.sequence, model)
            path.parent.mkdir(parents=True, exist_ok=True)
            written.append(write_text_atomic(path, calls_text(run)))
    return written
