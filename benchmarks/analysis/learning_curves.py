"""Learning curves from checkpoints' metadata: validation loss, accuracy and ARscore against training steps, several
runs (models x seeds) in one picture, with the mean and spread of each model and the step where its validation
ARscore stops improving.

`dvsot train --model M --val-data DIR --val-every K [--val-arscore-every K2]` (M: sctn, sctn_ann or siamfc) writes
each validation into the history of the checkpoint's .json; this reads several such files and draws them:

    python -m benchmarks.analysis.learning_curves runs/curves/*.json -o docs/learning_curves.png --tolerance 0.01

Each model's runs are drawn thin, their mean over seeds thick and mean +- one standard deviation (over seeds, ddof
0) shaded, on the steps every run of that model evaluated. The plateau of an ARscore curve
(s_1, a_1) ... (s_n, a_n), in step order, is the first evaluated step s_i after which no later evaluation beats a_i
by more than the tolerance: max over j > i of a_j <= a_i + tolerance (the last evaluation always qualifies, so a
curve with an evaluation has one). It is printed per run and for each model's mean curve, and marked on the figure.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

# (history key, panel title); a panel is drawn when some run has its figure (siamfc has no firing accuracy, SCTN
# and its twin no centre error)
PANELS = (("loss", "validation loss (each model's own)"), ("accuracy", "validation firing accuracy"),
          ("centre_error_px", "validation centre error (px)"), ("arscore", "validation ARscore"))
DEFAULT_TOLERANCE = 0.01  # ARscore: gains at most this large after a step do not count as improving


def read_curves(path: str | Path) -> dict:
    """{label, model, seed, validation, and per PANELS key [(step, value)]} of one checkpoint .json (its history's
    `val`); ValueError naming the file if it holds no validation history."""
    try:
        meta = json.loads(Path(path).read_text())
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: not JSON ({exc.msg} at line {exc.lineno})") from None
    if not isinstance(meta, dict):
        raise ValueError(f"{path}: not a checkpoint's metadata (a JSON object)")
    val = (meta.get("history") or {}).get("val") or []
    if not val:
        raise ValueError(f"{path}: no validation history (train with --val-every / --val-data)")
    seen: dict[int, dict] = {}
    for v in val:  # the last step is validated twice (every K steps and at the end): keep the later entry
        if not isinstance(v, dict) or not isinstance(v.get("step"), int):
            raise ValueError(f"{path}: history.val entry without an integer step: {v!r}")
        seen[v["step"]] = v
    cfg = meta.get("train_config") or {}
    model = str(meta.get("model", "sctn"))
    seed = cfg.get("seed")
    label = f"{model} seed {seed if seed is not None else '?'} ({Path(path).stem})"
    curves = {key: [(s, float(v[key])) for s, v in sorted(seen.items()) if v.get(key) is not None]
              for key, _ in PANELS}
    return {"label": label, "model": model, "seed": seed, "validation": (meta.get("history") or {}).get("validation"),
            **curves}


def plateau(points: list[tuple[int, float]], tolerance: float = DEFAULT_TOLERANCE) -> tuple[int, float] | None:
    """(step, value) of the first evaluation after which no later one exceeds its value by more than `tolerance`
    (points in step order), or None for no points."""
    if tolerance < 0 or not math.isfinite(tolerance):
        raise ValueError(f"tolerance must be >= 0 and finite, got {tolerance}")
    values = np.array([v for _, v in points], np.float64)
    if not len(values):
        return None
    # best of the evaluations after each one (-inf after the last)
    later = np.concatenate([np.maximum.accumulate(values[::-1])[::-1][1:], [-np.inf]])
    i = int(np.flatnonzero(later <= values + tolerance)[0])
    return points[i][0], float(values[i])


def model_means(runs: list[dict], key: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(steps, mean, std over runs, ddof 0) of figure `key` on the steps at which every run has it (empty arrays if
    they share none)."""
    per_run = [dict(r[key]) for r in runs]
    common = sorted(set.intersection(*(set(p) for p in per_run))) if per_run else []
    if not common:
        return np.zeros(0, np.int64), np.zeros(0), np.zeros(0)
    values = np.array([[p[s] for s in common] for p in per_run], np.float64)
    return np.array(common), values.mean(axis=0), values.std(axis=0)


def by_model(curves: list[dict]) -> dict[str, list[dict]]:
    """The runs of each model, models in the order they first appear."""
    groups: dict[str, list[dict]] = {}
    for c in curves:
        groups.setdefault(c["model"], []).append(c)
    return groups


def plateaus(curves: list[dict], tolerance: float = DEFAULT_TOLERANCE) -> dict:
    """The ARscore plateaus: {"runs": [{label, model, seed, step, arscore, best_step, best}], "models": {model:
    {runs, step, arscore (of the mean curve), run_steps: [...], mean_run_step, common_steps}}}; step None where a run
    (or a model's mean curve) has no ARscore evaluation."""
    runs = []
    for c in curves:
        p = plateau(c["arscore"], tolerance)
        best = max(c["arscore"], key=lambda sv: sv[1]) if c["arscore"] else (None, None)
        runs.append({"label": c["label"], "model": c["model"], "seed": c["seed"], "step": p[0] if p else None,
                     "arscore": p[1] if p else None, "best_step": best[0], "best": best[1]})
    models = {}
    for model, group in by_model(curves).items():
        steps, mean, _ = model_means(group, "arscore")
        p = plateau(list(zip(steps.tolist(), mean.tolist())), tolerance)
        run_steps = [r["step"] for r in runs if r["model"] == model and r["step"] is not None]
        models[model] = {"runs": len(group), "step": p[0] if p else None, "arscore": p[1] if p else None,
                         "run_steps": run_steps, "mean_run_step": float(np.mean(run_steps)) if run_steps else None,
                         "common_steps": len(steps)}
    return {"tolerance": tolerance, "runs": runs, "models": models}


def plot_curves(curves: list[dict], out_png: str | Path, tolerance: float = DEFAULT_TOLERANCE) -> Path:
    """One panel per figure of PANELS that some run has: each run thin, each model's mean thick with mean +- std
    shaded; on the ARscore panel a dashed line at each model's plateau."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from benchmarks.analysis.pictures import save_figure

    panels = [(key, title) for key, title in PANELS if any(c[key] for c in curves)]
    fig, axes = plt.subplots(1, len(panels), figsize=(5 * len(panels), 3.6), squeeze=False)
    groups = by_model(curves)
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    found = plateaus(curves, tolerance)["models"]
    for ax, (key, title) in zip(axes[0], panels):
        for m, (model, runs) in enumerate(groups.items()):
            colour = colours[m % len(colours)]
            for c in runs:
                if c[key]:
                    steps, values = zip(*c[key])
                    ax.plot(steps, values, color=colour, alpha=0.35, linewidth=0.8)
            steps, mean, std = model_means(runs, key)
            if len(steps):
                ax.plot(steps, mean, color=colour, linewidth=2, marker="." if len(steps) < 30 else None,
                        label=f"{model} (mean of {len(runs)})")
                ax.fill_between(steps, mean - std, mean + std, color=colour, alpha=0.15, linewidth=0)
            if key == "arscore" and found[model]["step"] is not None:
                ax.axvline(found[model]["step"], color=colour, linestyle="--", linewidth=1)
        ax.set_title(title + (f" (- - plateau, tolerance {tolerance:g})" if key == "arscore" else ""), fontsize=9)
        ax.set_xlabel("training step")
    axes[0][0].legend(fontsize=7)
    fig.tight_layout()
    return save_figure(fig, out_png, dpi=110)


def format_plateaus(found: dict) -> str:
    """The plateaus as a markdown table: one row per model (its mean curve, and the mean of its runs'), then runs."""
    def cell(v, fmt: str) -> str:
        return "-" if v is None else format(v, fmt)

    lines = [f"ARscore plateau (first evaluated step no later evaluation beats by more than {found['tolerance']:g})",
             "| model / run | runs | plateau step | ARscore there | runs' plateau steps (mean) | best ARscore (step) |",
             "|---|---|---|---|---|---|"]
    for model, m in found["models"].items():
        note = "" if m["runs"] < 2 or m["common_steps"] else " (no step common to its runs)"
        lines.append(f"| {model}: mean curve{note} | {m['runs']} | {cell(m['step'], 'd')} "
                     f"| {cell(m['arscore'], '.3f')} | {', '.join(map(str, m['run_steps'])) or '-'} "
                     f"({cell(m['mean_run_step'], '.0f')}) | |")
    for r in found["runs"]:
        best = "-" if r["best"] is None else f"{r['best']:.3f} ({r['best_step']})"
        lines.append(f"| {r['label']} | 1 | {cell(r['step'], 'd')} | {cell(r['arscore'], '.3f')} | | {best} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """Command line: checkpoint .json files -> one PNG and the plateau table; exit 2 with one line for bad input."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("files", nargs="+", help="checkpoint metadata files (<ckpt>.json), any models and seeds")
    p.add_argument("-o", "--output", required=True, help="PNG to write")
    p.add_argument("--tolerance", type=float, default=DEFAULT_TOLERANCE,
                   help=f"ARscore gain that still counts as no improvement (default {DEFAULT_TOLERANCE})")
    a = p.parse_args(argv)
    if not (a.tolerance >= 0 and math.isfinite(a.tolerance)):
        print(f"learning_curves: --tolerance must be >= 0 and finite, got {a.tolerance}", file=sys.stderr)
        return 2
    try:
        curves = [read_curves(f) for f in a.files]
    except (OSError, ValueError) as exc:
        print(f"learning_curves: {exc}", file=sys.stderr)
        return 2
    print(format_plateaus(plateaus(curves, a.tolerance)))
    print(plot_curves(curves, a.output, a.tolerance))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
