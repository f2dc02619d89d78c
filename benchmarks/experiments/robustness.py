"""ARscore per tracker against the sensor model: one sequence's kept frames re-simulated under presets and noise rates.

    python -m benchmarks.experiments.robustness SEQUENCE.h5 FRAMES_DIR --tracker rct [--tracker sctn ...]
        [--preset ideal --preset davis346 ...] [--noise-hz 0 1 5 ...] [--out DIR] [--max-segments N] [--jobs N]

FRAMES_DIR holds the sequence's rendered luma frames (`dvsot generate SCENE --keep-frames FRAMES_DIR`: one
NNNNNN.npy per render sample, linear intensity); SEQUENCE.h5 is the file that run wrote, whose /boxes hold
the sample times and the ground truth. Each variant (every --preset, default ideal, times every
--noise-hz, the shot-noise rate in events per pixel per second that overrides the preset's; default: the
preset's own) re-simulates the frames with the sequence's event seed into OUT/NAME.h5, and every tracker
runs on every variant (AR protocol). Written to OUT (default runs/robustness-<name>): robustness.md and
robustness.csv (variant, preset, set and measured noise rate, events, A, R, ARscore per tracker) and
robustness.png (ARscore per tracker against the measured noise rate, one marker per preset).
"""

from __future__ import annotations

import argparse
import csv
import sys
import time
from pathlib import Path

import numpy as np


def resimulate(sequence: str | Path, frames_dir: str | Path, output: str | Path, values: dict) -> dict:
    """The kept frames of a sequence through the simulator with EventParams values into a new dataset file (same
    times, boxes and event seed); {events, noise_events, noise_hz (measured, per pixel per second), duration_s}."""
    from dvsot.dataset import Dataset
    from dvsot.errors import UserError
    from dvsot.events import EventParams, EventSimulator
    from dvsot.pipeline.sequence import write_sequence

    with Dataset(sequence) as ds:
        track, attrs = ds.boxes(), dict(ds.attrs)
        width, height, segment_us, duration_us = ds.width, ds.height, ds.segment_us, ds.duration_us
    files = sorted(Path(frames_dir).glob("*.npy"))
    if len(files) != len(track.t):
        raise UserError(f"{frames_dir}: {len(files)} frames (.npy), but {sequence} has {len(track.t)} render samples")
    params = EventParams.parse(values, "robustness variant")
    seed = int(attrs.get("event_seed", attrs.get("seed", 0)))
    sim = EventSimulator(width, height, params, seed)
    out_attrs = {"name": attrs.get("name", Path(sequence).stem), "split": attrs.get("split", ""),
                 "source": str(frames_dir), "simulator": params.model_dump(), "event_seed": seed,
                 "generator": "benchmarks.experiments.robustness"}
    frames = (np.load(f) for f in files)
    path, counts = write_sequence(output, frames, track.t, sim, out_attrs, segment_us, source=str(frames_dir),
                                  boxes=lambda: (track.t, track.xywh, track.xywh_visible))
    noise = 0
    with Dataset(path) as ds:
        for batch in ds.chunks():
            noise += 0 if batch.signal is None else int(np.count_nonzero(~batch.signal))
    seconds = max(int(track.t[-1]) + 1, duration_us) / 1e6
    return {"events": counts.events, "noise_events": noise, "noise_hz": noise / (width * height) / seconds,
            "duration_s": seconds}


def sweep(sequence: str | Path, frames_dir: str | Path, trackers: list[str], presets: list[str],
          noise_hz: list[float] | None, out_dir: str | Path, max_segments: int | None = None,
          jobs: int = 1) -> list[dict]:
    """Every (preset, noise rate) variant re-simulated and tracked; one row per variant (see the module docstring)."""
    from benchmarks.evaluation.metrics import scores
    from benchmarks.evaluation.runner import benchmark

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    rows = []
    for preset in presets:
        for rate in (noise_hz if noise_hz else [None]):
            name = preset if rate is None else f"{preset}_noise{rate:g}"
            values = {"preset": preset} if rate is None else {"preset": preset, "shot_noise_hz": rate}
            stats = resimulate(sequence, frames_dir, out_dir / f"{name}.h5", values)
            from dvsot.events import EventParams

            row = {"variant": name, "preset": preset, "set_shot_noise_hz": EventParams(**values).shot_noise_hz,
                   "measured_noise_hz": round(stats["noise_hz"], 4), "events": stats["events"]}
            for result in benchmark(trackers, [out_dir / f"{name}.h5"], jobs=jobs, max_segments=max_segments):
                s = scores(result.iou)
                row[f"{result.tracker}_A"], row[f"{result.tracker}_R"] = round(s.accuracy, 4), round(s.robustness, 4)
                row[f"{result.tracker}_ARscore"] = round(s.arscore, 4)
                if result.error:
                    row[f"{result.tracker}_error"] = result.error
            rows.append(row)
    return rows


def write_outputs(rows: list[dict], trackers: list[str], out_dir: Path, title: str) -> None:
    """robustness.csv, robustness.md and robustness.png in out_dir."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    keys = list(dict.fromkeys(k for row in rows for k in row))
    with open(out_dir / "robustness.csv", "w", newline="") as f:
        w = csv.DictWriter(f, keys)
        w.writeheader()
        w.writerows(rows)
    head = ["variant", "set shot noise, Hz", "measured noise, Hz/px", "events"] + [f"{t} ARscore" for t in trackers]
    lines = [f"# Robustness: {title}", "", "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for row in rows:
        cells = [row["variant"], f"{row['set_shot_noise_hz']:g}", f"{row['measured_noise_hz']:g}",
                 f"{row['events']:,}"] + [f"{row.get(f'{t}_ARscore', float('nan')):.3f}" for t in trackers]
        lines.append("| " + " | ".join(cells) + " |")
    (out_dir / "robustness.md").write_text("\n".join(lines) + "\n")
    fig, ax = plt.subplots(figsize=(6, 4))
    markers = dict(zip(dict.fromkeys(r["preset"] for r in rows), "osD^v<>ph*"))
    for t in trackers:
        for preset, marker in markers.items():
            pts = sorted((r["measured_noise_hz"], r.get(f"{t}_ARscore", np.nan)) for r in rows if r["preset"] == preset)
            ax.plot([p[0] for p in pts], [p[1] for p in pts], marker=marker, label=f"{t} ({preset})")
    ax.set_xlabel("noise events per pixel per second (measured)")
    ax.set_ylabel("ARscore")
    ax.set_title(title)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out_dir / "robustness.png", dpi=120)
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("sequence", help="the dataset file `dvsot generate --keep-frames` wrote")
    parser.add_argument("frames", help="the kept frames directory (NNNNNN.npy per render sample)")
    parser.add_argument("--tracker", action="append", required=True)
    parser.add_argument("--preset", action="append", default=[], help="sensor preset (repeatable; default ideal)")
    parser.add_argument("--noise-hz", type=float, nargs="+", help="shot-noise rates, events per pixel per second")
    parser.add_argument("--out", help="output directory (default runs/robustness-<name>-<time>)")
    parser.add_argument("--max-segments", type=int)
    parser.add_argument("--jobs", type=int, default=1)
    args = parser.parse_args()
    from dvsot.errors import UserError

    try:
        out = Path(args.out or f"runs/robustness-{Path(args.sequence).stem}-{time.strftime('%Y%m%d-%H%M%S')}")
        rows = sweep(args.sequence, args.frames, args.tracker, args.preset or ["ideal"], args.noise_hz, out,
                     args.max_segments, args.jobs)
        write_outputs(rows, args.tracker, out, Path(args.sequence).stem)
    except UserError as exc:  # one line, exit 2, as dvsot's commands do
        print(f"benchmarks.experiments.robustness: {exc}", file=sys.stderr)
        raise SystemExit(2) from None
    print((out / "robustness.md").read_text())


if __name__ == "__main__":
    main()
