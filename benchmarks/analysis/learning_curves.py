"""Learning curves from checkpoints' metadata: validation loss, firing accuracy and ARscore against training steps.

`dvsot train --val-data DIR --val-every K [--val-arscore-every K2]` writes each validation into the history of
the checkpoint's .json; this reads several such files (seeds, models) and draws them in one picture:

    python -m benchmarks.analysis.learning_curves runs/curves/*.json -o docs/learning_curves.png
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

PANELS = (("loss", "validation loss"), ("accuracy", "validation firing accuracy"), ("arscore", "validation ARscore"))


def read_curves(path: str | Path) -> dict:
    """{label, steps, loss, accuracy, arscore: [(step, value)]} of one checkpoint .json (its history's `val`);
    ValueError naming the file if it holds no validation history."""
    meta = json.loads(Path(path).read_text())
    val = (meta.get("history") or {}).get("val") or []
    if not val:
        raise ValueError(f"{path}: no validation history (train with --val-every / --val-data)")
    seen: dict[int, dict] = {}
    for v in val:  # the last step is validated twice (every K steps and at the end): keep the later entry
        seen[int(v["step"])] = v
    cfg = meta.get("train_config") or {}
    label = f"{meta.get('model', 'sctn')} seed {cfg.get('seed', '?')} ({Path(path).stem})"
    curves = {key: [(s, float(v[key])) for s, v in sorted(seen.items()) if v.get(key) is not None]
              for key, _ in PANELS}
    return {"label": label, "validation": (meta.get("history") or {}).get("validation"), **curves}


def plot_curves(curves: list[dict], out_png: str | Path) -> Path:
    """One panel per figure of PANELS, one line per checkpoint."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from benchmarks.analysis.pictures import save_figure

    fig, axes = plt.subplots(1, len(PANELS), figsize=(5 * len(PANELS), 3.4))
    for ax, (key, title) in zip(axes, PANELS):
        for c in curves:
            if c[key]:
                steps, values = zip(*c[key])
                ax.plot(steps, values, marker="." if len(steps) < 30 else None, label=c["label"])
        ax.set_title(title)
        ax.set_xlabel("training step")
    axes[0].legend(fontsize=7)
    fig.tight_layout()
    return save_figure(fig, out_png, dpi=110)


def main(argv: list[str] | None = None) -> int:
    """Command line: checkpoint .json files -> one PNG; exit 2 with one line for a file without curves."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("files", nargs="+", help="checkpoint metadata files (<ckpt>.json)")
    p.add_argument("-o", "--output", required=True, help="PNG to write")
    a = p.parse_args(argv)
    try:
        curves = [read_curves(f) for f in a.files]
    except (OSError, ValueError) as exc:
        print(f"learning_curves: {exc}", file=sys.stderr)
        return 2
    print(plot_curves(curves, a.output))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
