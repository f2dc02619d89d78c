"""Per-sequence result files other toolkits read: OTB/pytracking boxes, GOT-10k and VOT layouts, per-segment times.

For every tracker and sequence of a run, in `<out>/<tracker>/` (names made safe as file names):

- `<sequence>.txt`: one `x,y,w,h` line per segment (pixels, top-left corner), the OTB layout that
  got10k's ExperimentOTB and pytracking read; the ground truth at initialisation segments,
  `nan,nan,nan,nan` where the tracker was not asked (segments skipped for want of ground truth).
- `times/<sequence>_time.txt`: one line per segment, the seconds the tracker spent on it (init or
  update), `nan` where it was not asked (where got10k's ExperimentOTB looks for per-frame times).
- `<sequence>/<sequence>_001.txt` and `<sequence>/<sequence>_time.txt` (one-pass protocol only): the
  same boxes and times in GOT-10k's own layout (got10k's ExperimentGOT10k: repetition 001 of a
  deterministic tracker); a re-initialising run is not one GOT-10k evaluates.
- `baseline/<sequence>/<sequence>_001.txt` (re-initialising protocol only): the VOT toolkit's
  trajectory, one line per segment: `1` where the tracker was initialised, `2` where it failed
  (IoU < 0.5; re-initialised on the next segment), `0` where it was not asked, else `x,y,w,h`.
- `timing.csv`: per sequence, segments asked, initialisations, init and update seconds, segments/s.
"""

from __future__ import annotations

import csv
import io
from pathlib import Path

import numpy as np

from benchmarks.analysis.tables import write_text_atomic
from benchmarks.evaluation.metrics import FAILURE_IOU
from benchmarks.evaluation.protocol import SequenceResult
from benchmarks.evaluation.safe_names import file_stem


def _box(row: np.ndarray) -> str:
    return ",".join(f"{v:.3f}" if np.isfinite(v) else "nan" for v in row)


def otb_text(result: SequenceResult) -> str:
    """One x,y,w,h line per segment: the prediction, the given box at an initialisation, nan where not asked."""
    return "".join(_box(row) + "\n" for row in result.predictions)


def vot_text(result: SequenceResult) -> str:
    """The VOT trajectory: 1 at an initialisation, 2 at a failure, 0 where not asked, else the box."""
    inits = set(result.init_segments)
    lines = []
    for i, row in enumerate(result.predictions):
        if i in inits:
            lines.append("1")
        elif np.isfinite(result.iou[i]) and result.iou[i] < FAILURE_IOU:
            lines.append("2")
        elif np.isfinite(row).all():
            lines.append(_box(row))
        else:
            lines.append("0")
    return "\n".join(lines) + "\n"


def time_text(result: SequenceResult) -> str:
    """One line of tracker seconds per segment (nan where not asked)."""
    seconds = result.segment_seconds if result.segment_seconds is not None else np.full(len(result.iou), np.nan)
    return "".join((f"{s:.6f}" if np.isfinite(s) else "nan") + "\n" for s in seconds)


def result_paths(out_dir: Path, tracker: str, sequence: str, vot: bool) -> dict[str, Path]:
    """The files one tracker's run on one sequence writes, by kind: otb, time, and vot (re-initialising run)
    or got10k and got10k_time (one-pass run)."""
    d, s = Path(out_dir) / file_stem(tracker), file_stem(sequence)
    paths = {"otb": d / f"{s}.txt", "time": d / "times" / f"{s}_time.txt"}
    if vot:
        paths["vot"] = d / "baseline" / s / f"{s}_001.txt"
    else:
        paths["got10k"], paths["got10k_time"] = d / s / f"{s}_001.txt", d / s / f"{s}_time.txt"
    return paths


def per_sequence_files(trackers: list[str], sequences: dict[str, str | Path], protocol: str = "ar") -> list[Path]:
    """Every per-sequence file a run of these trackers on these sequences may write (relative to its directory);
    UserError if two runs would write one file (names that differ but are made safe to the same file name)."""
    from dvsot.core.errors import UserError

    owner: dict[Path, tuple[str, str]] = {}
    for t in trackers:
        for seq, path in sequences.items():
            for p in result_paths(Path(), t, seq, protocol != "ope").values():
                if p in owner and owner[p] != (t, seq):
                    other_t, other_seq = owner[p]
                    what = (f"sequence '{seq}' ({path}) and '{other_seq}' ({sequences[other_seq]})" if t == other_t
                            else f"trackers '{t}' and '{other_t}'")
                    raise UserError(f"{what} would write the same result file {p}; rename one")
                owner[p] = (t, seq)
        owner[Path(file_stem(t)) / "timing.csv"] = (t, "")
    return list(owner)


def write_sequence_files(results: list[SequenceResult], out_dir: str | Path, vot: bool = True) -> list[Path]:
    """Write every finished run's per-sequence files and each tracker's timing.csv (each file atomically)."""
    out_dir = Path(out_dir)
    written: list[Path] = []
    timing: dict[str, list[list]] = {}
    for r in results:
        if r.error is not None:  # a crashed run has no trajectory to give; the tables mark it failed
            continue
        paths = result_paths(out_dir, r.tracker, r.sequence, vot)
        texts = {"otb": otb_text(r), "time": time_text(r)}
        texts.update({"vot": vot_text(r)} if vot else {"got10k": texts["otb"], "got10k_time": texts["time"]})
        # a sequence named "times" has one time file in both layouts, with the same text
        for path, kind in {path: kind for kind, path in paths.items()}.items():
            if path in written:  # two sequences whose names are made safe to one file name
                raise ValueError(f"{path}: written twice in one run ({r.tracker} on {r.sequence}); names must differ")
            path.parent.mkdir(parents=True, exist_ok=True)
            written.append(write_text_atomic(path, texts[kind]))
        asked = len(r.init_segments) + r.tracked_segments
        rate = f"{r.segments_per_s:.3f}" if np.isfinite(r.segments_per_s) else "nan"
        timing.setdefault(r.tracker, [["sequence", "segments_asked", "inits", "init_s", "update_s", "segments_per_s"]]
                          ).append([r.sequence, asked, len(r.init_segments), f"{r.init_seconds:.6f}",
                                    f"{r.tracker_seconds:.6f}", rate])
    for tracker, rows in timing.items():
        text = io.StringIO()
        csv.writer(text, lineterminator="\n").writerows(rows)  # quotes a sequence name holding a comma
        written.append(write_text_atomic(out_dir / file_stem(tracker) / "timing.csv", text.getvalue()))
    return written
