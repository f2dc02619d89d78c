"""Table 2 rows over training seeds: several `dvsot bench` outputs of one tracker, each from another seed, as one
row of mean ± standard deviation per sequence and pooled.

Each group is a label and the bench output directories of its seeds (each holding the `results.csv` that `dvsot
bench` writes); every directory of a group must hold one tracker and the same sequences, so the mean is over like
runs. The standard deviation is over seeds with ddof 0, as in the ablation table:

    python -m benchmarks.analysis.seed_table "sctn, 5 epochs=runs/t2/bench_test/sctn_s*" \\
        "sctn_ann, 5 epochs=runs/t2/bench_test/sctn_ann_s*" [--csv table.csv] [--paper]
"""

from __future__ import annotations

import argparse
import csv
import glob
import io
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from benchmarks.analysis import paper
from benchmarks.analysis.tables import TABLE_FILES, write_text_atomic
from benchmarks.evaluation.metrics import ALL

METRICS = ("A", "R", "ARscore")


@dataclass(frozen=True)
class SeedRow:
    """One group's figures: per sequence and for ALL, per metric, (mean, std) over its seeds."""

    label: str
    tracker: str
    seeds: int
    cells: dict[str, dict[str, tuple[float, float]]]


def read_results(run_dir: str | Path) -> tuple[str, dict[str, dict[str, float]]]:
    """(tracker, {sequence: {A, R, ARscore}}) of one bench output directory's results.csv; ValueError naming the
    file when it is missing, holds several trackers, a failed sequence or no pooled row."""
    path = Path(run_dir) / TABLE_FILES["csv"]
    if not path.is_file():
        raise ValueError(f"{path}: no results.csv (not a dvsot bench output directory)")
    with path.open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    trackers = {r["tracker"] for r in rows}
    if len(trackers) != 1:
        raise ValueError(f"{path}: holds {len(trackers)} trackers ({', '.join(sorted(trackers))}); one per directory")
    failed = [r["sequence"] for r in rows if r.get("error")]
    if failed:
        raise ValueError(f"{path}: sequences that failed: {', '.join(failed)}")
    cells = {r["sequence"]: {m: float(r[m]) for m in METRICS} for r in rows}
    if ALL not in cells:
        raise ValueError(f"{path}: no '{ALL}' row")
    return trackers.pop(), cells


def seed_row(label: str, run_dirs: list[str | Path]) -> SeedRow:
    """The mean ± std over the runs of one group; ValueError when the runs differ in tracker or sequences."""
    if not run_dirs:
        raise ValueError(f"{label}: no bench output directory")
    runs = [(d, *read_results(d)) for d in run_dirs]
    first_dir, tracker, first = runs[0]
    for d, t, cells in runs[1:]:
        if t != tracker:
            raise ValueError(f"{label}: {d} holds tracker {t}, {first_dir} holds {tracker}")
        if set(cells) != set(first):
            raise ValueError(f"{label}: {d} and {first_dir} hold different sequences")
    table = {seq: {m: (float(np.mean([c[seq][m] for _, _, c in runs])), float(np.std([c[seq][m] for _, _, c in runs])))
                   for m in METRICS}
             for seq in first}
    return SeedRow(label, tracker, len(runs), table)


def sequence_order(rows: list[SeedRow]) -> list[str]:
    """The sequences of the first row in name order, ALL last."""
    return sorted(s for s in rows[0].cells if s != ALL) + [ALL]


def paper_cells(tracker: str, seqs: list[str]) -> list[str] | None:
    """The paper's Table 2 figures of `tracker` as table cells (ARscore per sequence, A / R / ARscore pooled), or
    None when the paper has no such row or not every sequence of the table."""
    row = paper.TABLE2.get(tracker)
    if row is None or any(s not in row for s in seqs):
        return None
    a, r, ar = row[ALL]
    return [f"{row[s][2]:.3f}" for s in seqs] + [f"{a:.3f} / {r:.3f} / **{ar:.3f}**"]


def to_markdown(rows: list[SeedRow], with_paper: bool = False) -> str:
    """A Markdown table: ARscore per sequence, then A / R / ARscore pooled, each mean ± std over seeds; with_paper
    puts the paper's Table 2 row under the first row of each tracker the paper reports, on the same sequences."""
    seqs = [s for s in sequence_order(rows) if s != ALL]
    head = ["tracker", "seeds", *seqs, "all (A / R / ARscore)"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]

    def pm(cell: tuple[float, float]) -> str:
        return f"{cell[0]:.3f} ± {cell[1]:.3f}"

    shown: set[str] = set()
    for r in rows:
        pooled = r.cells[ALL]
        cells = [r.label, str(r.seeds), *(pm(r.cells[s]["ARscore"]) for s in seqs),
                 f"{pm(pooled['A'])} / {pm(pooled['R'])} / **{pm(pooled['ARscore'])}**"]
        lines.append("| " + " | ".join(cells) + " |")
        published = paper_cells(r.tracker, seqs) if with_paper and r.tracker not in shown else None
        if published:
            shown.add(r.tracker)
            lines.append("| " + " | ".join([f"{r.tracker}, paper", "-", *published]) + " |")
    return "\n".join(lines) + "\n"


def to_csv(rows: list[SeedRow]) -> str:
    """One line per group, sequence and metric: label, tracker, seeds, sequence, metric, mean, std."""
    buf = io.StringIO()
    out = csv.writer(buf, lineterminator="\n")
    out.writerow(["label", "tracker", "seeds", "sequence", "metric", "mean", "std"])
    for r in rows:
        for seq in sequence_order(rows):
            for m in METRICS:
                mean, std = r.cells[seq][m]
                out.writerow([r.label, r.tracker, r.seeds, seq, m, f"{mean:.4f}", f"{std:.4f}"])
    return buf.getvalue()


def parse_group(text: str) -> tuple[str, list[str]]:
    """'LABEL=GLOB[,GLOB...]' -> (label, sorted matching directories); ValueError when malformed or matching none."""
    label, sep, patterns = text.rpartition("=")
    if not sep or not label.strip() or not patterns.strip():
        raise ValueError(f"group {text!r}: expected LABEL=DIR_OR_GLOB[,DIR_OR_GLOB...]")
    dirs = sorted({d for p in patterns.split(",") for d in glob.glob(p.strip())})
    if not dirs:
        raise ValueError(f"group {label!r}: {patterns!r} matches no directory")
    return label.strip(), dirs


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("groups", nargs="+", metavar="LABEL=DIRS",
                   help="a row's label and its seeds' bench output directories (comma-separated globs)")
    p.add_argument("--csv", type=Path, help="also write the figures as CSV here")
    p.add_argument("--paper", action="store_true",
                   help="put the paper's Table 2 row under each tracker it reports (benchmarks/analysis/paper.py)")
    args = p.parse_args(argv)
    try:
        rows = [seed_row(*parse_group(g)) for g in args.groups]
        seqs = [set(r.cells) for r in rows]
        if any(s != seqs[0] for s in seqs[1:]):
            raise ValueError("the groups hold different sequences; give one table per set of sequences")
    except ValueError as exc:
        print(f"seed_table: {exc}", file=sys.stderr)
        return 2
    print(to_markdown(rows, with_paper=args.paper), end="")
    if args.csv:
        write_text_atomic(args.csv, to_csv(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
