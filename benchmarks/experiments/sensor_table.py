"""The tracker table under several sensor presets: a split's kept frames re-simulated per preset, benchmarked each.

    python -m benchmarks.experiments.sensor_table --data data/dvsot21 --frames data/frames21 --split test \\
        --preset ideal --preset davis346 --tracker rct --tracker sctn [--checkpoint CKPT] [--option T.KEY=VALUE]
        [--max-segments N] [--jobs N] [--no-energy] [--picture SEQUENCE:SEGMENT] [--out DIR] [--quiet]

Every sequence of the split in --data needs its rendered frames in FRAMES/<name>/ (`dvsot generate SCENES
--out-dir DATA --keep-frames FRAMES`: one NNNNNN.npy per render sample); a sequence without them is an error
naming it. Under each --preset (the preset's own fields, or with `as-rendered` the settings the sequence's file
records, its scene's `events:` included; always with the sequence's own event seed:
benchmarks.experiments.robustness.resimulate) a sequence's frames become OUT/<preset>/<name>.h5, and `dvsot
bench`'s run (benchmarks.bench.plan.run_benchmark, AR protocol, the same trackers and options under every
preset) writes its report into OUT/<preset>/bench/. OUT/table.md: one row per tracker, its ARscore, A and R
pooled over the split's sequences under each preset; OUT/table.csv: those rows (sequence `all`), then one per
tracker and sequence, with each preset's events and measured noise rate; with --picture NAME:K,
OUT/segment.png: segment K of sequence NAME under each preset side by side.

OUT holds one run's files (dvsot.runtime.outputs.owned_run): every input, flag and output path is checked
before any work, every file is staged and all are renamed into place together with run.json at the end, the
previous run's files that this one does not write removed in the same commit; an interrupted or failed run
leaves OUT as it was, and an OUT that holds other files is refused.

Exit status: 0; 1 if a tracker raised on some sequence (the tables are still written, its cells marked failed
and the sequence left out of its pooled row); 2 bad input: one line on stderr, nothing run, nothing written.
"""

from __future__ import annotations

import argparse
import csv
import io
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

MANIFEST = "run.json"  # the run's manifest in OUT (dvsot.runtime.outputs)
TABLE_FILES = ("table.md", "table.csv")
PICTURE_FILE = "segment.png"  # as robustness.py names its picture
BENCH_DIR = "bench"  # OUT/<preset>/bench/: `dvsot bench`'s report of that preset's files
AS_RENDERED = "as-rendered"  # the --preset word for each sequence's own simulator settings, as its file records them
METRICS = ("ARscore", "A", "R")  # a preset's columns in table.md, in this order


@dataclass
class SensorTable:
    """A finished run: each preset's benchmark run and, per preset and sequence, resimulate's figures."""

    presets: list[str]
    trackers: list[str]
    sequences: list[str]
    runs: dict = field(default_factory=dict)  # preset -> benchmarks.bench.plan.BenchmarkRun
    events: dict = field(default_factory=dict)  # preset -> sequence -> {events, noise_events, noise_hz, ...}
    out_dir: Path = Path()

    @property
    def failed(self) -> list[tuple[str, object]]:
        """(preset, result) of every run that raised, in run order."""
        return [(p, r) for p, run in self.runs.items() for r in run.failed]


def picture_spec(text: str) -> tuple[str, int]:
    """A --picture value SEQUENCE:SEGMENT (the last ':' splits, so a name may hold one): (sequence, segment)."""
    name, sep, k = text.rpartition(":")
    try:
        segment = int(k)
    except ValueError:
        segment = -1
    if not (sep and name) or segment < 0:
        raise argparse.ArgumentTypeError(f"{text!r}: expected SEQUENCE:SEGMENT, a sequence name and a segment >= 0")
    return name, segment


def preset_files(presets: Sequence[str], sequences: Sequence[str]) -> dict[str, dict[str, str]]:
    """{preset: {sequence: its file relative to OUT}}: <preset>/<name>.h5, names made safe as file names;
    UserError if two sequences would share a file."""
    from benchmarks.evaluation.safe_names import file_stem
    from dvsot.core.errors import UserError

    owner: dict[str, str] = {}
    for name in sequences:
        stem = file_stem(name)
        if stem in owner:
            raise UserError(f"sequences '{owner[stem]}' and '{name}' would write the same file {stem}.h5; rename one")
        owner[stem] = name
    return {p: {name: f"{p}/{file_stem(name)}.h5" for name in sequences} for p in presets}


def kept_frame_dirs(sequences: dict[str, Path], frames: str | Path) -> dict[str, Path]:
    """{sequence: FRAMES/<name>} (dvsot generate --keep-frames' layout for several scenes), each holding one
    frame per render sample; UserError naming the sequences without frames, or the first whose count is off."""
    from benchmarks.experiments.robustness import kept_frames
    from dvsot.core.errors import UserError

    frames = Path(frames)
    if not frames.is_dir():
        raise UserError(f"--frames {frames}: no such directory")
    dirs = {name: frames / name for name in sequences}
    missing = [name for name, d in dirs.items() if not d.is_dir()]
    if missing:
        listed = ", ".join(f"'{n}' ({sequences[n]})" for n in missing[:3]) + (" ..." if len(missing) > 3 else "")
        raise UserError(f"--frames {frames}: no kept frames for {len(missing)} sequence(s) of the run: {listed}; "
                        f"`dvsot generate SCENES --keep-frames {frames}` keeps them in {frames}/<name>/")
    for name, d in dirs.items():
        kept_frames(sequences[name], d)
    return dirs


def recorded_settings(sequence: str | Path) -> dict:
    """The simulator settings a dataset file was made with (its `simulator` attribute: EventParams' fields, thresholds
    in log units, rates in Hz, times in microseconds); UserError naming the file if it records none."""
    from dvsot.core.errors import UserError
    from dvsot.dataset import Dataset
    from dvsot.events import EventParams

    with Dataset(sequence) as ds:
        settings = ds.attrs.get("simulator")
    if not isinstance(settings, dict):
        raise UserError(f"{sequence}: --preset {AS_RENDERED}: the file records no simulator settings (attribute "
                        f"'simulator'); name a preset instead")
    EventParams.parse(settings, f"{sequence}: simulator")
    return dict(settings)


def run(trackers: Sequence[str], presets: Sequence[str], frames: str | Path, out_dir: str | Path,
        data: Sequence[str] | None = None, split: str = "test", checkpoint: str | None = None,
        options: Sequence[str] = (), max_segments: int | None = None, jobs: int | None = None, energy: bool = True,
        picture: tuple[str, int] | None = None, progress: bool = False) -> SensorTable:
    """The whole table into out_dir as one run (see the module docstring); UserError before any work on bad input."""
    from benchmarks.bench.plan import plan_benchmark, resolve_data, run_benchmark, run_files
    from benchmarks.experiments.robustness import check_segment, resimulate
    from benchmarks.experiments.robustness import picture as draw_picture
    from dvsot.core.errors import UserError
    from dvsot.events import EventParams
    from dvsot.runtime.outputs import owned_run, readable

    out = Path(out_dir)
    presets = list(dict.fromkeys(presets))
    if not presets:
        raise UserError("--preset: give at least one sensor preset")
    for p in presets:
        if p != AS_RENDERED:
            EventParams.parse({"preset": p}, f"--preset {p}")
    sequences = resolve_data(data, split)
    recorded = {name: recorded_settings(source) for name, source in sequences.items()} if AS_RENDERED in presets else {}
    dirs = kept_frame_dirs(sequences, frames)
    files = preset_files(presets, list(sequences))
    if picture is not None:
        name, segment = picture
        if name not in sequences:
            raise UserError(f"--picture {name}:{segment}: no sequence '{name}' in this run "
                            f"(sequences: {', '.join(sequences)})")
        check_segment(sequences[name], segment, "--picture")
    bench_files = run_files(trackers, sequences, energy=energy)
    writes = [f for per in files.values() for f in per.values()]
    writes += [f"{p}/{BENCH_DIR}/{f}" for p in presets for f in bench_files]
    writes += [*TABLE_FILES, *([PICTURE_FILE] if picture is not None else []), MANIFEST]
    table = SensorTable(presets, list(dict.fromkeys(trackers)), list(sequences), out_dir=out)
    with owned_run(out, "--out", writes, MANIFEST):
        # every tracker, option and checkpoint checked on the split's own files before any re-simulation
        plan_benchmark(trackers, [str(f) for f in sequences.values()], "any", out / presets[0] / BENCH_DIR, jobs,
                       max_segments=max_segments, checkpoint=checkpoint, energy=energy, options=options)
        for p in presets:
            (out / p).mkdir(parents=True, exist_ok=True)
            table.events[p] = {}
            for name, source in sequences.items():
                values = recorded[name] if p == AS_RENDERED else {"preset": p}
                table.events[p][name] = resimulate(source, dirs[name], out / files[p][name], values)
                if progress:
                    print(f"sensor_table: {p}: {name}: {table.events[p][name]['events']:,} events",
                          file=sys.stderr, flush=True)
        for p in presets:
            table.runs[p] = run_benchmark(trackers, [str(readable(out / f)) for f in files[p].values()], "any",
                                          out / p / BENCH_DIR, jobs, max_segments=max_segments,
                                          checkpoint=checkpoint, energy=energy, options=options, progress=progress)
        write_tables(table, out, describe(table, data, split, frames, max_segments))
        if picture is not None:
            name, segment = picture
            draw_picture({p: readable(out / files[p][name]) for p in presets}, segment, out / PICTURE_FILE,
                         f"{name}, segment {segment}")
    return table


def describe(table: SensorTable, data: Sequence[str] | None, split: str, frames: str | Path,
             max_segments: int | None) -> str:
    """table.md's line under its title: what was re-simulated from where and how it was scored."""
    from benchmarks.bench.plan import DEFAULT_DATA

    where = " ".join(str(d) for d in data) if data else DEFAULT_DATA
    first = f"; the first {max_segments} segments of each" if max_segments is not None else ""
    return (f"The {split} split of {where}: {len(table.sequences)} sequences, their kept frames ({frames}) "
            f"re-simulated under each preset with the sequence's own event seed{first}. A, R and ARscore: "
            f"the AR protocol, pooled over the sequences (`dvsot bench`'s `all` column; each preset's report in "
            f"<preset>/{BENCH_DIR}/).")


def table_rows(table: SensorTable) -> list[dict]:
    """table.csv's rows: each tracker pooled (sequence `all`), then each tracker on each sequence; per preset A, R,
    ARscore, segments, failures, error, the events and the measured noise rate (events per pixel per second;
    `all`: the sum of the events, the mean of the sequences' rates)."""
    import numpy as np

    from benchmarks.evaluation.metrics import ALL

    rows = []
    for sequence in [ALL, *table.sequences]:
        for t in table.trackers:
            row: dict = {"tracker": t, "sequence": sequence}
            for p in table.presets:
                cell = table.runs[p].summary[t][sequence]
                row.update({f"{p}_{k}": round(float(cell[k]), 4) for k in ("A", "R", "ARscore")})
                row.update({f"{p}_segments": cell.segments, f"{p}_failures": cell.failures,
                            f"{p}_error": cell.error or ""})
                stats = table.events[p]
                if sequence == ALL:
                    row[f"{p}_events"] = sum(s["events"] for s in stats.values())
                    row[f"{p}_noise_hz"] = round(float(np.mean([s["noise_hz"] for s in stats.values()])), 4)
                else:
                    row[f"{p}_events"] = stats[sequence]["events"]
                    row[f"{p}_noise_hz"] = round(stats[sequence]["noise_hz"], 4)
            rows.append(row)
    return rows


def format_table(table: SensorTable, description: str) -> str:
    """table.md: one row per tracker, ARscore, A and R pooled over the sequences under each preset."""
    import numpy as np

    from benchmarks.evaluation.metrics import ALL
    from benchmarks.evaluation.safe_names import markdown_cell

    head = ["tracker"] + [f"{p} {m}" for p in table.presets for m in METRICS]
    lines = ["# Trackers under the sensor presets", "", description, "",
             "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    notes = []
    for t in table.trackers:
        cells = [markdown_cell(t)]
        for p in table.presets:
            cell = table.runs[p].summary[t][ALL]
            cells += ["failed"] * len(METRICS) if cell.error else [f"{cell[m]:.3f}" for m in METRICS]
            failed = [s for s in table.sequences if table.runs[p].summary[t][s].error]
            if failed and not cell.error:
                notes.append(f"{t} under {p}: failed on {', '.join(failed)}, left out of its row (table.csv)")
        lines.append("| " + " | ".join(cells) + " |")
    lines.append("")
    lines.append("Events of all sequences (measured noise, events per pixel per second, the sequences' mean): "
                 + "; ".join(f"{p} {sum(s['events'] for s in table.events[p].values()):,} "
                             f"({float(np.mean([s['noise_hz'] for s in table.events[p].values()])):.3g})"
                             for p in table.presets) + ".")
    lines += [f"- {markdown_cell(n)}" for n in notes]
    return "\n".join(lines) + "\n"


def write_tables(table: SensorTable, out_dir: Path, description: str) -> None:
    """table.md and table.csv in out_dir (staged in the open run)."""
    from dvsot.runtime.outputs import replacing

    rows = table_rows(table)
    buf = io.StringIO()
    w = csv.DictWriter(buf, list(rows[0]))
    w.writeheader()
    w.writerows(rows)
    with replacing(Path(out_dir) / "table.csv") as tmp:
        Path(tmp).write_text(buf.getvalue())
    with replacing(Path(out_dir) / "table.md") as tmp:
        Path(tmp).write_text(format_table(table, description))


def main(argv: list[str] | None = None) -> int:
    """Command line: 0, or 1 if a tracker raised on some sequence under some preset."""
    from benchmarks.bench.plan import DEFAULT_DATA
    from dvsot.events.presets import PRESETS

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", nargs="+", default=None,
                        help=f"dataset files, directories or globs (default: {DEFAULT_DATA})")
    parser.add_argument("--frames", required=True, help="the kept frames: FRAMES/<sequence name>/NNNNNN.npy")
    parser.add_argument("--split", default="test", help="split attribute to keep: train, test, or 'any' (default test)")
    parser.add_argument("--preset", action="append", required=True, choices=[*PRESETS, AS_RENDERED],
                        help=f"sensor preset (repeatable); {AS_RENDERED}: each file's own simulator settings")
    parser.add_argument("--tracker", action="append", required=True, metavar="NAME", help="tracker (repeatable)")
    parser.add_argument("--checkpoint", help="checkpoint of the run's sctn, sctn_ann or siamfc (as `dvsot bench`)")
    parser.add_argument("--option", action="append", default=[], metavar="TRACKER.KEY=VALUE",
                        help="constructor option of one tracker (as `dvsot bench`)")
    parser.add_argument("--max-segments", type=int, help="only the first N (>= 1) segments of each sequence")
    parser.add_argument("--jobs", type=int, help="parallel tracking processes (default: `dvsot bench`'s)")
    parser.add_argument("--no-energy", action="store_true", help="skip each preset's energy table")
    parser.add_argument("--picture", type=picture_spec, metavar="SEQUENCE:SEGMENT",
                        help="also write segment.png: that segment under each preset side by side")
    parser.add_argument("--out", help="output directory (default runs/sensor-table-<time>)")
    parser.add_argument("--quiet", action="store_true", help="no progress")
    args = parser.parse_args(argv)
    from dvsot.core.errors import RunError, UserError

    out = Path(args.out or f"runs/sensor-table-{time.strftime('%Y%m%d-%H%M%S')}")
    try:
        table = run(args.tracker, args.preset, args.frames, out, args.data, args.split, args.checkpoint, args.option,
                    args.max_segments, args.jobs, not args.no_energy, args.picture, progress=not args.quiet)
    except UserError as exc:  # one line, exit 2, as dvsot's commands do
        print(f"benchmarks.experiments.sensor_table: {exc}", file=sys.stderr)
        return 2
    except RunError as exc:
        print(f"benchmarks.experiments.sensor_table: {exc}", file=sys.stderr)
        return 1
    print((out / "table.md").read_text())
    print(f"written: {out}")
    for preset, r in table.failed:
        print(f"benchmarks.experiments.sensor_table: failed: {r.tracker} on {r.sequence} under {preset}: {r.error}",
              file=sys.stderr)
    return 1 if table.failed else 0


if __name__ == "__main__":
    raise SystemExit(main())
