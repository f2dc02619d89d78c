"""Benchmark trackers on dataset files: the paper's A / R / ARscore protocol, tables in five formats.

Examples:
  dvsot bench --tracker rct --tracker csrt                        # test split of data/dvsot21/
  dvsot bench --tracker sctn --tracker rct --data data/dvsot21 --plots
  dvsot bench --tracker kcf --data 'runs/*.h5' --split any --out runs/bench-kcf

Segments that count: see benchmarks/evaluation/protocol.py (initialisation segments and segments without
ground truth never count; a failure, IoU < 0.5, re-initialises on the next segment). --protocol ope
runs one pass without re-initialisation instead and reports success AUC and precision at 20 px
(benchmarks/evaluation/ope.py). Either way <out>/<tracker>/ gets per-sequence boxes, times and (re-initialising
protocol) VOT trajectories (benchmarks/analysis/sequence_files.py).

Before anything runs, every input is checked: flags, data files, --video names, the SCTN checkpoint
(loaded into the model), each tracker built once with its --option values, and the output paths.
--checkpoint goes to the one tracker of the run that takes a checkpoint (sctn, sctn_ann, siamfc): an
error without one or with several (give each its own with --option NAME.checkpoint=PATH); a
checkpoint of another model is refused naming the model it holds. The energy table (Table 3) is made
when any of those three runs: SCTN's rows from the run's SCTN checkpoint (or the shipped one), the ANN
rows from the run's sctn_ann and siamfc checkpoints (or the shipped ones).

Outputs are written only when every run has finished, as temp files renamed into place together
(then run.json, the manifest naming the run and each file's SHA-256), so an interrupted or killed run
or bad input never leaves a table half-written, nor new tables beside old pictures.

The command checks its flags and calls the library: benchmarks.benchmark (the runs),
benchmarks.summarise, benchmarks.analysis.energy_table and benchmarks.write_report (the outputs).

Exit status:
  0  every tracker ran on every sequence; tables written.
  1  a tracker raised on some sequence (a runtime failure): the tables are still written, with that
     cell marked "failed" and the run left out of the "all" column, and stderr gets one line per
     failure naming tracker, sequence and error.
  2  bad input: one line on stderr naming the flag or file; nothing run, nothing written.
"""

from __future__ import annotations

import argparse
import re
import sys
from dataclasses import dataclass, field
from pathlib import Path

DEFAULT_DATA = "data/dvsot21"
CHECKPOINT_TRACKERS = ("sctn", "sctn_ann", "siamfc")  # trackers with a `checkpoint` option


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Flags of `dvsot bench`."""
    p.add_argument("--tracker", action="append", required=True, metavar="NAME",
                   help="tracker to run (repeatable): sctn, sctn_ann, siamfc, rct, csrt, kcf, mil or one you "
                        "registered")
    p.add_argument("--data", nargs="+", default=None,
                   help=f"dataset files, directories or globs (default: {DEFAULT_DATA})")
    p.add_argument("--split", default="test", help="split attribute to keep: train, test, or 'any' (default test)")
    p.add_argument("--out", default=None, help="directory for the tables (default runs/bench-<time>)")
    p.add_argument("--jobs", type=int, default=None, help="parallel processes (default: min(2, runs))")
    p.add_argument("--scheduler", help="local:N (a Dask LocalCluster of N processes) or tcp://HOST:PORT: one task per "
                                       "(tracker, sequence) run; the data files must be at the same paths on the workers")
    p.add_argument("--tracker-module", action="append", default=[], metavar="MODULE",
                   help="import this module first, so that the trackers it registers can be named")
    p.add_argument("--max-segments", type=int, default=None,
                   help="only the first N (>= 1) segments of each sequence")
    p.add_argument("--plots", action="store_true", help="also write iou_over_time.png")
    p.add_argument("--video", action="append", default=[], metavar="SEQUENCE",
                   help="also write <out>/<SEQUENCE>.gif: event frames with predicted and true boxes")
    p.add_argument("--checkpoint", help="checkpoint for the run's --tracker sctn, sctn_ann or siamfc (default: the "
                                        "shipped one); an error without one of them, or with several")
    p.add_argument("--no-energy", action="store_true", help="skip the energy table (made when sctn, sctn_ann or "
                                                           "siamfc runs)")
    p.add_argument("--option", action="append", default=[], metavar="TRACKER.KEY=VALUE",
                   help="constructor option of one tracker, e.g. sctn.fast=false or rct.cluster_size=0.05 "
                        "(checked before the run)")
    p.add_argument("--protocol", choices=["ar", "ope"], default="ar",
                   help="ar: the paper's A / R / ARscore with re-initialisation (default); ope: one pass, "
                        "success AUC and precision at 20 px")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


@dataclass
class Plan:
    """Everything a run needs, checked before any tracking starts."""

    trackers: list[str]
    files: list[Path]
    sequences: dict[str, Path]
    options: dict[str, dict]
    out_dir: Path
    jobs: int
    model: object | None = None  # the SCTN model of the checkpoint, for the energy table
    ann_models: dict = field(default_factory=dict)  # {"twin": ..., "siamfc": ...} for the energy table's ANN rows
    notes: tuple[str, ...] = ()  # lines printed under the energy table
    tasks: list[tuple[str, str]] = field(default_factory=list)


def _options(specs: list[str], trackers: list[str]) -> dict[str, dict]:
    """{tracker: {key: value}} from TRACKER.KEY=VALUE strings (values read as YAML, as in a scene file)."""
    from dvsot.scene import yaml_value
    from dvsot.errors import UserError

    out: dict[str, dict] = {}
    for spec in specs:
        name, _, rest = spec.partition(".")
        key, eq, raw = rest.partition("=")
        if not (name and key and eq):
            raise UserError(f"--option {spec!r}: expected TRACKER.KEY=VALUE")
        if name not in trackers:
            raise UserError(f"--option {spec!r}: tracker '{name}' is not in this run")
        out.setdefault(name, {})[key] = yaml_value(raw)  # as in a scene file: false, False, 0.05, 1e-3, text
    return out


def resolve_data(specs: list[str] | None, split: str) -> dict[str, Path]:
    """{sequence name: dataset file} to benchmark (benchmarks.find_sequences), the default data if no --data."""
    from benchmarks.evaluation.runner import find_sequences
    from dvsot.errors import UserError

    if specs is None:
        if not Path(DEFAULT_DATA).is_dir():
            raise UserError(f"{DEFAULT_DATA}: no default data; make it with "
                            f"`dvsot generate blender_scenes/*.yaml --out-dir {DEFAULT_DATA}` or pass --data")
        specs = [DEFAULT_DATA]
    return find_sequences(specs, None if split == "any" else split)


def _option_spec(tracker: str, key: str | None, specs: list[str]) -> str:
    """The --option text that set tracker.key (the last one, as it wins), or all of the tracker's."""
    mine = [s for s in specs if s.startswith(f"{tracker}.")]
    if key is not None:
        hits = [s for s in mine if s.partition(".")[2].partition("=")[0] == key]
        if hits:
            return hits[-1]
    return " ".join(mine)


def _option_key(exc: BaseException, options: dict) -> str | None:
    """The option a constructor rejected: pydantic's field, or Python's 'unexpected keyword argument'."""
    from pydantic import ValidationError

    if isinstance(exc, ValidationError) and exc.errors()[0]["loc"]:
        return str(exc.errors()[0]["loc"][0])
    m = re.search(r"unexpected keyword argument '(\w+)'", str(exc))
    if m:
        return m.group(1)
    return next(iter(options)) if len(options) == 1 else None


def _option_error(name: str, options: dict, exc: Exception, specs: list[str]):
    """The one-line UserError for a tracker that its --option values did not build."""
    from dvsot.errors import UserError

    from benchmarks.evaluation.models import error_text

    detail = error_text(exc)
    if not options or (name in CHECKPOINT_TRACKERS and set(options) == {"checkpoint"}):
        return UserError(f"--tracker {name}: cannot build the tracker ({detail})")
    key = _option_key(exc, options)
    if key is not None:
        detail = detail.removeprefix(f"field '{key}': ")
        if detail == "unknown field" or "unexpected keyword argument" in detail:
            detail = f"tracker '{name}' has no option '{key}'"
        elif "takes no arguments" in detail:
            detail = f"tracker '{name}' takes no options"
    return UserError(f"--option {_option_spec(name, key, specs)}: {detail}")


def check_trackers(trackers: list[str], options: dict[str, dict], specs: list[str]) -> None:
    """Build each tracker once with its options, so that a bad option fails now, not as a "failed" run."""
    from benchmarks.trackers import get_tracker
    from dvsot.errors import UserError

    for name in trackers:
        try:
            get_tracker(name, **options.get(name, {}))
        except UserError:
            raise
        except Exception as exc:
            raise _option_error(name, options.get(name, {}), exc, specs) from None


_WHO_ASKS = {"tables": "--out", "manifest": "--out (the run's manifest)", "plots": "--plots", "video": "--video",
             "energy": "--out (energy table)"}  # benchmarks.report_files' kinds, as the flags that ask for them


def _output_names(args: argparse.Namespace, energy: bool) -> dict[str, str]:
    """{file name in --out: the flag that asks for it}."""
    from benchmarks.analysis.report import report_files

    names = report_files(args.protocol, args.plots, args.video, energy)
    return {name: _WHO_ASKS[kind] for name, kind in names.items()}


def check_video(sequence: str, path: Path) -> None:
    """UserError now if the preview of a sequence would hold more frames in memory than dvsot.limits allows."""
    from benchmarks.analysis.report import VIDEO_SEGMENTS
    from dvsot.dataset import Dataset
    from dvsot.errors import UserError
    from dvsot.limits import preview_problem

    with Dataset(path) as ds:
        problem = preview_problem(ds.width, ds.height, min(ds.num_segments, VIDEO_SEGMENTS))
    if problem:
        raise UserError(f"--video {sequence}: {path}: {problem}")


def check_outputs(out_dir: Path, names: dict[str, str], inputs: list) -> None:
    """--out is a directory (or will be made) and none of the files to write in it is a directory or an input."""
    from dvsot.runtime.outputs import output_dir, output_file

    output_dir(out_dir, "--out")
    if out_dir.is_dir():
        for name, flag in names.items():
            output_file(out_dir / name, flag, inputs)


def plan(args: argparse.Namespace) -> Plan:
    """Check every input and output of the run; UserError (and nothing done) on the first problem."""
    import os
    import time

    from benchmarks.evaluation.models import energy_ann_models, load_sctn_checkpoint
    from benchmarks.trackers import load_tracker_module, tracker_class
    from dvsot.errors import UserError
    from benchmarks.analysis.sequence_files import per_sequence_files
    from dvsot.dataset.safe_names import file_stem
    from dvsot.runtime.outputs import output_dir, run_dir
    from dvsot.limits import MAX_WORKERS, range_problem

    problem = args.jobs is not None and range_problem("--jobs", args.jobs, 1, MAX_WORKERS)
    if problem:
        raise UserError(problem)
    if args.scheduler:
        from dvsot.pipeline.scene_runner import parse_scheduler

        parse_scheduler(args.scheduler, "--scheduler")
    if args.max_segments is not None and args.max_segments < 1:
        raise UserError(f"--max-segments must be >= 1, got {args.max_segments}")
    for m in args.tracker_module:
        load_tracker_module(m, "--tracker-module")
    trackers = list(dict.fromkeys(args.tracker))
    for name in trackers:
        tracker_class(name)
    options = _options(args.option, trackers)
    sctn = "sctn" in trackers
    energy = not args.no_energy and any(t in CHECKPOINT_TRACKERS for t in trackers)
    if args.checkpoint is not None:
        takers = [t for t in trackers if t in CHECKPOINT_TRACKERS]
        if not takers:
            raise UserError(f"--checkpoint {args.checkpoint}: only used by --tracker sctn, sctn_ann or siamfc, "
                            "none of which is in this run")
        if len(takers) > 1:
            raise UserError(f"--checkpoint {args.checkpoint}: {', '.join(takers)} all take a checkpoint; give each "
                            "its own with --option NAME.checkpoint=PATH")
        if "checkpoint" in options.get(takers[0], {}):
            raise UserError(f"--option {takers[0]}.checkpoint: give the checkpoint once, with --checkpoint")
        options.setdefault(takers[0], {})["checkpoint"] = args.checkpoint
    out_dir = Path(args.out or f"runs/bench-{time.strftime('%Y%m%d-%H%M%S')}")
    sequences = resolve_data(args.data, args.split)
    files = list(sequences.values())
    from benchmarks.evaluation.protocol import nothing_to_score

    for f in files:  # else its row would be empty, at exit 0
        problem = nothing_to_score(f, args.max_segments, reinitialise=args.protocol == "ar")
        if problem:
            raise UserError(problem)
    videos: dict[str, str] = {}
    for seq in args.video:
        from benchmarks.analysis.report import video_name

        if videos.get(video_name(seq), seq) != seq:
            raise UserError(f"--video {seq}: its file name {video_name(seq)} is also --video {videos[video_name(seq)]}'s")
        videos[video_name(seq)] = seq
        if seq not in sequences:
            raise UserError(f"--video {seq}: no such sequence in this run (sequences: {', '.join(sequences)})")
        check_video(seq, sequences[seq])
    check_outputs(out_dir, _output_names(args, energy), files)
    for name in trackers:  # <out>/<tracker>/ holds the per-sequence files
        output_dir(out_dir / file_stem(name), "--out (per-sequence results)")
    # every path under --out, checked now; --out holds this run's files only (benchmarks.analysis.report)
    run_dir(out_dir, "--out", [*_output_names(args, energy), *per_sequence_files(trackers, sequences, args.protocol)])
    model = load_sctn_checkpoint(options.get("sctn", {}).get("checkpoint")) if sctn else None
    check_trackers(trackers, options, args.option)
    if energy and model is None:  # the energy table's SCTN rows without sctn in the run: the shipped checkpoint
        model = load_sctn_checkpoint(None)
    ann_models, notes = energy_ann_models(trackers, options) if energy else ({}, ())
    tasks = [(t, str(f)) for t in trackers for f in files]
    jobs = args.jobs or min(2, os.cpu_count() or 1, len(tasks))
    return Plan(trackers, files, sequences, options, out_dir, jobs, model, ann_models, notes, tasks)


def track(p: Plan, args: argparse.Namespace) -> list:
    """Run every task of the plan (in parallel processes when jobs > 1); results in task order."""
    from benchmarks.evaluation.runner import benchmark

    return benchmark(p.trackers, p.files, p.options, p.jobs, args.max_segments, args.protocol, args.tracker_module,
                     progress=not args.quiet, scheduler=args.scheduler)


def run(args: argparse.Namespace) -> int:
    """Check everything, run every tracker on every sequence, then print and write the tables (exit 1 on failures)."""
    from benchmarks.analysis.report import write_report
    from benchmarks.analysis.tables import summarise, terminal

    p = plan(args)
    results = track(p, args)
    if args.protocol == "ope":
        from benchmarks.evaluation.ope import format_ope, summarise_ope

        summary = summarise_ope(results)
    else:
        summary = summarise(results)
    energy = None
    if p.model is not None and not args.no_energy:
        from benchmarks.analysis.energy_table import energy_table

        # computed before writing: a crash here leaves --out as it was
        energy = energy_table(p.model, p.files, **p.ann_models, notes=p.notes)
    print(format_ope(summary) if args.protocol == "ope" else terminal(summary))
    from benchmarks.evaluation.attributes import attribute_ope, attribute_scores, format_attributes

    print("\nper attribute:\n" + format_attributes(
        attribute_ope(results) if args.protocol == "ope" else attribute_scores(results), args.protocol))
    if energy is not None:
        from benchmarks.analysis.energy_table import format_energy_table

        print(format_energy_table(energy))
    paths = write_report(p.out_dir, summary, results, protocol=args.protocol, plots=args.plots,
                         videos={seq: p.sequences[seq] for seq in args.video}, energy=energy)
    print("written: " + ", ".join(str(x) for x in paths.values()))
    failed = [r for r in results if r.error]
    for r in failed:
        print(f"dvsot bench: failed: {r.tracker} on {r.sequence}: {r.error}", file=sys.stderr)
    return 1 if failed else 0
