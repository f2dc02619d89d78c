"""Results tables in the layout of the paper's Table 2 (A and R per sequence, ARscore beneath, an "all" column).

One summary (`summarise`: a typed `Summary` of `Cell`s) feeds every format: terminal text, CSV (one row per tracker and
sequence), JSON, Markdown and LaTeX, written side by side by `write_tables`.
"""

from __future__ import annotations

import csv
import io
import json
import math
from collections.abc import Iterator, Mapping
from dataclasses import asdict, dataclass, fields
from pathlib import Path
from typing import Any

from benchmarks.evaluation.metrics import ALL, pooled, scores
from benchmarks.evaluation.protocol import SequenceResult
from benchmarks.evaluation.safe_names import latex_text, markdown_cell  # sequence and tracker names are free text


@dataclass(frozen=True)
class Cell:
    """One tracker on one sequence (or pooled over all of them): the paper's A, R, ARscore and the run's counts.

    segments_per_s counts update time only; init_s is the time spent in initialisations (SCTN's
    fine-tuning); energy: the tracker's mean energy figures, if it reports them; error: why it failed.
    """

    A: float
    R: float
    ARscore: float
    segments: int
    failures: int
    inits: int
    segments_per_s: float
    init_s: float
    energy: dict | None
    error: str | None

    def __getitem__(self, key: str) -> Any:
        """cell["A"]: a cell reads as the mapping of its fields (the tables' and the JSON's names)."""
        if key not in _CELL_FIELDS:
            raise KeyError(key)
        return getattr(self, key)

    def to_dict(self) -> dict[str, Any]:
        """The cell as a plain dict (its JSON)."""
        return asdict(self)


_CELL_FIELDS = frozenset(f.name for f in fields(Cell))


@dataclass(frozen=True)
class Summary(Mapping):
    """Benchmark results by tracker, then by sequence and the pooled column 'all': summary["sctn"]["all"].A."""

    cells: dict[str, dict[str, Cell]]

    def __getitem__(self, tracker: str) -> dict[str, Cell]:
        return self.cells[tracker]

    def __iter__(self) -> Iterator[str]:
        return iter(self.cells)

    def __len__(self) -> int:
        return len(self.cells)

    @property
    def trackers(self) -> list[str]:
        """The trackers, in the order they were run."""
        return list(self.cells)

    @property
    def sequences(self) -> list[str]:
        """The sequences in order of first appearance, then 'all'."""
        return _sequences(self)

    def to_dict(self) -> dict[str, dict[str, dict[str, Any]]]:
        """{tracker: {sequence: {field: value}}} as plain dicts (its JSON, with NaN kept)."""
        return {t: {s: c.to_dict() for s, c in per.items()} for t, per in self.cells.items()}


def summarise(results: list[SequenceResult]) -> Summary:
    """Each tracker's Cell on each sequence and pooled over the sequences it did not fail on ('all')."""
    out: dict[str, dict[str, Cell]] = {}
    for res in results:
        s = scores(res.iou)
        out.setdefault(res.tracker, {})[res.sequence] = Cell(
            A=s.accuracy, R=s.robustness, ARscore=s.arscore, segments=s.segments, failures=s.failures,
            inits=len(res.init_segments), segments_per_s=res.segments_per_s, init_s=res.init_seconds,
            energy=res.energy, error=res.error)
    for tracker, per_seq in out.items():
        ok = [r for r in results if r.tracker == tracker and r.error is None]
        s = pooled([r.iou for r in ok])
        seconds = sum(r.tracker_seconds for r in ok)
        tracked = sum(r.tracked_segments for r in ok)
        energies = [r.energy for r in ok if r.energy]
        energy = None
        if energies:
            keys = set.intersection(*(set(e) for e in energies))
            energy = {k: sum(e[k] for e in energies) / len(energies) for k in sorted(keys)}
        per_seq[ALL] = Cell(A=s.accuracy, R=s.robustness, ARscore=s.arscore, segments=s.segments,
                            failures=s.failures, inits=sum(len(r.init_segments) for r in ok),
                            segments_per_s=tracked / seconds if seconds > 0 else float("nan"),
                            init_s=sum(r.init_seconds for r in ok), energy=energy,
                            error=None if ok else "all sequences failed")
    return Summary(out)


def _sequences(summary: Mapping) -> list[str]:
    seqs: list[str] = []
    for per_seq in summary.values():
        seqs += [s for s in per_seq if s != ALL and s not in seqs]
    return seqs + [ALL]


def _f(v: float | None) -> str:
    return "-" if v is None or (isinstance(v, float) and math.isnan(v)) else f"{v:.3f}"


def terminal(summary: Mapping) -> str:
    """A fixed-width table: per tracker an 'A R' row and an ARscore row, plus speed and initialisation time."""
    seqs = _sequences(summary)
    name_w = max([7] + [len(markdown_cell(t)) for t in summary])
    col_w = max([13] + [len(markdown_cell(s)) for s in seqs])
    lines = [" " * name_w + " | " + " | ".join(markdown_cell(s).center(col_w) for s in seqs) + " | seg/s | init s",
             " " * name_w + " | " + " | ".join("A      R".center(col_w) for _ in seqs) + " |       |"]
    lines.append("-" * len(lines[0]))
    for tracker, per_seq in summary.items():
        ar_row, score_row = [], []
        for s in seqs:
            cell = per_seq.get(s)
            if cell is None:
                ar_row.append("".center(col_w))
                score_row.append("".center(col_w))
            elif cell["error"]:
                ar_row.append("failed".center(col_w))
                score_row.append("".center(col_w))
            else:
                ar_row.append(f"{_f(cell['A'])}  {_f(cell['R'])}".center(col_w))
                score_row.append(_f(cell["ARscore"]).center(col_w))
        speed, init = per_seq[ALL]["segments_per_s"], per_seq[ALL]["init_s"]
        lines.append(
            markdown_cell(tracker).ljust(name_w) + " | " + " | ".join(ar_row) + f" | {speed:5.1f} | {init:.1f}"
        )
        lines.append(" " * name_w + " | " + " | ".join(score_row) + " |       |")
    return "\n".join(lines)


def to_csv(summary: Mapping) -> str:
    """One row per tracker and sequence (including 'all')."""
    buf = io.StringIO()
    fields = ["tracker", "sequence", "A", "R", "ARscore", "segments", "failures", "inits", "segments_per_s",
              "init_s", "energy_pj", "error"]
    w = csv.DictWriter(buf, fieldnames=fields, lineterminator="\n")
    w.writeheader()
    for tracker, per_seq in summary.items():
        for seq in _sequences(summary):
            if seq not in per_seq:
                continue
            c = per_seq[seq]
            energy = (c["energy"] or {}).get("energy_pj")
            w.writerow({"tracker": tracker, "sequence": seq, "A": _f(c["A"]), "R": _f(c["R"]),
                        "ARscore": _f(c["ARscore"]), "segments": c["segments"], "failures": c["failures"],
                        "inits": c["inits"], "segments_per_s": f"{c['segments_per_s']:.2f}",
                        "init_s": f"{c['init_s']:.2f}",
                        "energy_pj": "" if energy is None else f"{energy:.4g}", "error": c["error"] or ""})
    return buf.getvalue()


def to_json(summary: Mapping) -> str:
    """The summary as JSON (NaN written as null)."""
    def clean(v):
        if isinstance(v, (Summary, Cell)):
            v = v.to_dict()
        if isinstance(v, float) and math.isnan(v):
            return None
        if isinstance(v, dict):
            return {k: clean(x) for k, x in v.items()}
        return v
    return json.dumps(clean(summary), indent=2)


def to_markdown(summary: Mapping) -> str:
    """A Markdown table: each cell 'A / R / **ARscore**'."""
    seqs = _sequences(summary)
    lines = [
        "| tracker | " + " | ".join(map(markdown_cell, seqs)) + " | seg/s | init s |",
        "|---|" + "---|" * (len(seqs) + 2),
    ]
    for tracker, per_seq in summary.items():
        cells = []
        for s in seqs:
            c = per_seq.get(s)
            cells.append("" if c is None else "failed" if c["error"] else
                         f"{_f(c['A'])} / {_f(c['R'])} / **{_f(c['ARscore'])}**")
        lines.append(
            f"| {markdown_cell(tracker)} | " + " | ".join(cells) + f" | {per_seq[ALL]['segments_per_s']:.1f} | "
            f"{per_seq[ALL]['init_s']:.1f} |"
        )
    return "\n".join(lines) + (
        "\n\nEach cell: A / R / **ARscore** (b = 2). seg/s: tracked segments per second of "
        "update time; init s: seconds spent initialising (SCTN fine-tunes at each initialisation).\n"
    )


def to_latex(summary: Mapping) -> str:
    """A LaTeX tabular in the paper's layout: A and R side by side, ARscore centred beneath."""
    seqs = _sequences(summary)
    esc = latex_text
    lines = [r"\begin{tabular}{l" + "cc" * len(seqs) + "}", r"\hline",
             "Method & " + " & ".join(rf"\multicolumn{{2}}{{c}}{{{esc(s)}}}" for s in seqs) + r" \\",
             " & " + " & ".join("A & R" for _ in seqs) + r" \\", " & " + " & ".join(
                 r"\multicolumn{2}{c}{ARscore}" for _ in seqs) + r" \\", r"\hline"]
    for tracker, per_seq in summary.items():
        row1, row2 = [], []
        for s in seqs:
            c = per_seq.get(s)
            if c is None or c["error"]:
                row1.append(r"\multicolumn{2}{c}{" + ("failed" if c else "") + "}")
                row2.append(r"\multicolumn{2}{c}{}")
            else:
                row1.append(f"{_f(c['A'])} & {_f(c['R'])}")
                row2.append(rf"\multicolumn{{2}}{{c}}{{{_f(c['ARscore'])}}}")
        lines.append(esc(tracker) + " & " + " & ".join(row1) + r" \\")
        lines.append(" & " + " & ".join(row2) + r" \\")
    lines += [r"\hline", r"\end{tabular}"]
    return "\n".join(lines) + "\n"


def write_text_atomic(path: str | Path, text: str) -> Path:
    """Write text to path via a temp file and a rename, so a reader never sees half a file."""
    from dvsot.runtime.outputs import replacing

    with replacing(path) as tmp:
        tmp.write_text(text)
    return Path(path)


def write_summary(out_dir: str | Path, stem: str, summary: dict, markdown: str) -> list[Path]:
    """<stem>.json (summary, indented) and <stem>.md (markdown and a newline) in out_dir, made if missing; their
    paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    return [write_text_atomic(out / f"{stem}.json", json.dumps(summary, indent=2)),
            write_text_atomic(out / f"{stem}.md", markdown + "\n")]


TABLE_FILES = {"txt": "table.txt", "csv": "results.csv", "json": "results.json", "md": "results.md",
               "tex": "results.tex"}


def write_tables(summary: Mapping, out_dir: str | Path) -> dict[str, Path]:
    """Write results.{csv,json,md,tex} and table.txt into out_dir, each atomically; returns the paths by format."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    # every text is made before the first file is replaced: a formatting error leaves all the old tables
    texts = {"txt": terminal(summary) + "\n", "csv": to_csv(summary), "json": to_json(summary),
             "md": to_markdown(summary), "tex": to_latex(summary)}
    return {fmt: write_text_atomic(out / TABLE_FILES[fmt], text) for fmt, text in texts.items()}
