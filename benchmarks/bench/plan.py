"""A benchmark run checked whole before it starts (trackers, options, data, checkpoint, outputs), then run.

`run_benchmark` is `dvsot bench`: `plan_benchmark` checks every input and output, `benchmark` runs every
tracker on every sequence, and the tables, energy table and report are made from the results and written
together (benchmarks.analysis.report), only when every run has finished.

Messages name a setting by its parameter name (`trackers`, `data`, `out_dir`, `options`, ...); a command passes
{name: flag} as `labels` to have its flags named instead (dvsot.core.errors.label).
"""

from __future__ import annotations

import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from dvsot.core.errors import label

DEFAULT_DATA = "data/dvsot21"
# trackers with a `checkpoint` option
CHECKPOINT_TRACKERS = ("sctn", "sctn_ann", "siamfc", "goturn", "siamrpn", "siammask", "ocean", "automatch")


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
    max_segments: int | None = None
    protocol: str = "ar"
    tracker_modules: list[str] = field(default_factory=list)
    scheduler: str | None = None
    videos: list[str] = field(default_factory=list)
    skip_absent: bool = False  # protocol rule 6: hidden-target segments left unscored rather than scored apart
    stream: dict | None = None  # protocol "stream": latency specs, query_hz, window, predictive (check_stream)


def _options(specs: list[str], trackers: list[str], labels: Mapping[str, str] | None = None) -> dict[str, dict]:
    """{tracker: {key: value}} from TRACKER.KEY=VALUE strings (values read as YAML, as in a scene file)."""
    from dvsot.core.errors import UserError
    from dvsot.scene import yaml_value

    out: dict[str, dict] = {}
    for spec in specs:
        name, _, rest = spec.partition(".")
        key, eq, raw = rest.partition("=")
        if not (name and key and eq):
            raise UserError(f"{label('options', labels)} {spec!r}: expected TRACKER.KEY=VALUE")
        if name not in trackers:
            raise UserError(f"{label('options', labels)} {spec!r}: tracker '{name}' is not in this run")
        out.setdefault(name, {})[key] = yaml_value(raw)  # as in a scene file: false, False, 0.05, 1e-3, text
    return out


def resolve_data(specs: list[str] | None, split: str, labels: Mapping[str, str] | None = None) -> dict[str, Path]:
    """{sequence name: dataset file} to benchmark (benchmarks.find_sequences), DEFAULT_DATA if specs is None."""
    from benchmarks.evaluation.runner import find_sequences
    from dvsot.core.errors import UserError

    if specs is None:
        if not Path(DEFAULT_DATA).is_dir():
            raise UserError(f"{DEFAULT_DATA}: no default data; make it with `dvsot generate blender_scenes/*.yaml "
                            f"--out-dir {DEFAULT_DATA}` or give {label('data', labels)}")
        specs = [DEFAULT_DATA]
    return find_sequences(specs, None if split == "any" else split)


def _option_spec(tracker: str, key: str | None, specs: list[str]) -> str:
    """The TRACKER.KEY=VALUE text that set tracker.key (the last one, as it wins), or all of the tracker's."""
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


def _option_error(name: str, options: dict, exc: Exception, specs: list[str], labels: Mapping[str, str] | None):
    """The one-line UserError for a tracker that its option values did not build."""
    from benchmarks.evaluation.models import error_text
    from dvsot.core.errors import UserError

    detail = error_text(exc)
    if not options or (name in CHECKPOINT_TRACKERS and set(options) == {"checkpoint"}):
        return UserError(f"{label('trackers', labels)} {name}: cannot build the tracker ({detail})")
    key = _option_key(exc, options)
    if key is not None:
        detail = detail.removeprefix(f"field '{key}': ")
        if detail == "unknown field" or "unexpected keyword argument" in detail:
            detail = f"tracker '{name}' has no option '{key}'"
        elif "takes no arguments" in detail:
            detail = f"tracker '{name}' takes no options"
    return UserError(f"{label('options', labels)} {_option_spec(name, key, specs)}: {detail}")


def check_trackers(trackers: list[str], options: dict[str, dict], specs: list[str],
                   labels: Mapping[str, str] | None = None) -> None:
    """Build each tracker once with its options, so that a bad option fails now, not as a "failed" run."""
    from benchmarks.trackers import get_tracker
    from dvsot.core.errors import UserError

    for name in trackers:
        try:
            get_tracker(name, **options.get(name, {}))
        except UserError:
            raise
        except Exception as exc:
            raise _option_error(name, options.get(name, {}), exc, specs, labels) from None


def check_frame_sizes(trackers: list[str], files: list[Path]) -> None:
    """UserError naming the file if a tracker with a `frame_problem(width, height)` cannot take its frames."""
    from benchmarks.trackers import tracker_class
    from dvsot.core.errors import UserError
    from dvsot.dataset import Dataset

    checks = [c.frame_problem for c in map(tracker_class, trackers) if hasattr(c, "frame_problem")]
    for f in files if checks else []:
        with Dataset(f) as ds:
            wh = (ds.width, ds.height)
        for check in checks:
            problem = check(*wh)
            if problem:
                raise UserError(f"{f}: {problem}")


# report_files' kinds, as the settings that ask for them (and what the file is, where that is not the setting's job)
_WHO_ASKS = {"tables": ("out_dir", ""), "manifest": ("out_dir", " (the run's manifest)"), "plots": ("plots", ""),
             "video": ("videos", ""), "energy": ("out_dir", " (energy table)")}


def _output_names(protocol: str, plots: bool, videos: Sequence[str], energy: bool,
                  labels: Mapping[str, str] | None = None, scale_plot: bool = False) -> dict[str, str]:
    """{file name in out_dir: the setting that asks for it}."""
    from benchmarks.analysis.report import report_files

    names = report_files(protocol, plots, list(videos), energy, scale_plot)
    return {name: label(_WHO_ASKS[kind][0], labels) + _WHO_ASKS[kind][1] for name, kind in names.items()}


def run_files(trackers: Sequence[str], sequences: dict[str, Path], protocol: str = "ar", plots: bool = False,
              videos: Sequence[str] = (), energy: bool = True, stream: dict | None = None) -> list[str]:
    """Every path (relative to out_dir) a run of these trackers on these sequences may write: the report's files
    (the energy table's only when a tracker of CHECKPOINT_TRACKERS runs) and the per-sequence files."""
    from benchmarks.analysis.sequence_files import per_sequence_files

    energy = energy and any(t in CHECKPOINT_TRACKERS for t in trackers)
    if protocol == "stream":
        from benchmarks.analysis.stream_tables import stream_files
        from benchmarks.bench.stream_options import stream_models

        models = stream_models(stream or {})
        return [*_output_names(protocol, plots, videos, energy, scale_plot=any(m.kind == "scaled" for m in models)),
                *(str(p) for p in stream_files(list(trackers), list(sequences), [m.name for m in models]))]
    return [*_output_names(protocol, plots, videos, energy),
            *(str(p) for p in per_sequence_files(list(trackers), sequences, protocol))]


def check_video(sequence: str, path: Path, labels: Mapping[str, str] | None = None) -> None:
    """UserError now if the preview of a sequence would hold more frames in memory than dvsot.core.bounds allows."""
    from benchmarks.analysis.report import VIDEO_SEGMENTS
    from dvsot.core.bounds import preview_problem
    from dvsot.core.errors import UserError
    from dvsot.dataset import Dataset

    with Dataset(path) as ds:
        problem = preview_problem(ds.width, ds.height, min(ds.num_segments, VIDEO_SEGMENTS))
    if problem:
        raise UserError(f"{label('videos', labels)} {sequence}: {path}: {problem}")


def check_outputs(out_dir: Path, names: dict[str, str], inputs: list,
                  labels: Mapping[str, str] | None = None) -> None:
    """out_dir is a directory (or will be made) and none of the files to write in it is a directory or an input."""
    from dvsot.runtime.outputs import output_dir, output_file

    output_dir(out_dir, label("out_dir", labels))
    if out_dir.is_dir():
        for name, flag in names.items():
            output_file(out_dir / name, flag, inputs)


def plan_benchmark(trackers: Sequence[str], data: Sequence[str] | None = None, split: str = "test",
                   out_dir: str | Path | None = None, jobs: int | None = None, scheduler: str | None = None,
                   tracker_modules: Sequence[str] = (), max_segments: int | None = None, plots: bool = False,
                   videos: Sequence[str] = (), checkpoint: str | None = None, energy: bool = True,
                   options: Sequence[str] = (), protocol: str = "ar", labels: Mapping[str, str] | None = None,
                   skip_absent: bool = False,
                   stream: Mapping | None = None) -> Plan:
    """Check every input and output of a run; UserError (and nothing done) on the first problem.

    stream: protocol "stream"'s settings {latency: [specs], query_hz, window, predictive} (check_stream).

    options are TRACKER.KEY=VALUE strings; messages name the settings by these parameters' names, or as
    `labels` ({name: flag}) says.
    """
    import os
    import time

    from benchmarks.evaluation.models import energy_ann_models, load_sctn_checkpoint
    from benchmarks.evaluation.safe_names import file_stem
    from benchmarks.trackers import load_tracker_module, tracker_class
    from dvsot.core.bounds import MAX_WORKERS, range_problem
    from dvsot.core.errors import UserError
    from dvsot.runtime.outputs import output_dir, run_dir

    labels = dict(labels or {})
    out_label, option_label = label("out_dir", labels), label("options", labels)
    no_energy, option_specs = not energy, list(options)
    problem = jobs is not None and range_problem(label("jobs", labels), jobs, 1, MAX_WORKERS)
    if problem:
        raise UserError(problem)
    if scheduler:
        from dvsot.runtime.dask_tasks import parse_scheduler

        parse_scheduler(scheduler, label("scheduler", labels))
    if max_segments is not None and max_segments < 1:
        raise UserError(f"{label('max_segments', labels)} must be >= 1, got {max_segments}")
    for m in tracker_modules:
        load_tracker_module(m, label("tracker_modules", labels))
    trackers = list(dict.fromkeys(trackers))
    for name in trackers:
        tracker_class(name)
    options = _options(option_specs, trackers, labels)
    from benchmarks.bench.stream_options import check_stream, stream_models

    stream = check_stream(protocol, stream, trackers, videos, labels)
    sctn = "sctn" in trackers
    energy = not no_energy and any(t in CHECKPOINT_TRACKERS for t in trackers)
    if checkpoint is not None:
        takers = [t for t in trackers if t in CHECKPOINT_TRACKERS]
        if not takers:
            raise UserError(f"{label('checkpoint', labels)} {checkpoint}: only used by {label('trackers', labels)} "
                            f"{', '.join(CHECKPOINT_TRACKERS[:-1])} or {CHECKPOINT_TRACKERS[-1]}, none of which is "
                            "in this run")
        if len(takers) > 1:
            raise UserError(f"{label('checkpoint', labels)} {checkpoint}: {', '.join(takers)} all take a checkpoint; "
                            f"give each its own with {option_label} NAME.checkpoint=PATH")
        if "checkpoint" in options.get(takers[0], {}):
            raise UserError(f"{option_label} {takers[0]}.checkpoint: give the checkpoint once, with "
                            f"{label('checkpoint', labels)}")
        options.setdefault(takers[0], {})["checkpoint"] = checkpoint
    out_dir = Path(out_dir or f"runs/bench-{time.strftime('%Y%m%d-%H%M%S')}")
    sequences = resolve_data(data, split, labels)
    files = list(sequences.values())
    from benchmarks.evaluation.protocol import nothing_to_score

    for f in files:  # else its row would be empty, at exit 0
        problem = nothing_to_score(f, max_segments, reinitialise=protocol == "ar")  # stream: one pass, as ope
        if problem:
            raise UserError(problem)
    check_frame_sizes(trackers, files)
    named: dict[str, str] = {}
    video_label = label("videos", labels)
    for seq in videos:
        from benchmarks.analysis.report import video_name

        if named.get(video_name(seq), seq) != seq:
            raise UserError(f"{video_label} {seq}: its file name {video_name(seq)} is also "
                            f"{video_label} {named[video_name(seq)]}'s")
        named[video_name(seq)] = seq
        if seq not in sequences:
            raise UserError(f"{video_label} {seq}: no such sequence in this run (sequences: {', '.join(sequences)})")
        check_video(seq, sequences[seq], labels)
    scale_plot = stream is not None and any(m.kind == "scaled" for m in stream_models(stream))
    check_outputs(out_dir, _output_names(protocol, plots, videos, energy, labels, scale_plot), files, labels)
    for name in trackers:  # <out_dir>/<tracker>/ holds the per-sequence files
        output_dir(out_dir / file_stem(name), f"{out_label} (per-sequence results)")
    # every path under out_dir, checked now; out_dir holds this run's files only (benchmarks.analysis.report)
    run_dir(out_dir, out_label, run_files(trackers, sequences, protocol, plots, videos, energy, stream))
    model = load_sctn_checkpoint(options.get("sctn", {}).get("checkpoint")) if sctn else None
    check_trackers(trackers, options, option_specs, labels)
    if energy and model is None:  # the energy table's SCTN rows without sctn in the run: the shipped checkpoint
        model = load_sctn_checkpoint(None)
    ann_models, notes = energy_ann_models(trackers, options) if energy else ({}, ())
    tasks = [(t, str(f)) for t in trackers for f in files]
    jobs = jobs or min(2, os.cpu_count() or 1, len(tasks))
    return Plan(trackers, files, sequences, options, out_dir, jobs, model, ann_models, notes, tasks, max_segments,
                protocol, list(tracker_modules), scheduler, list(videos), skip_absent, stream)


def track(p: Plan, progress: bool = True) -> list:
    """Run every task of the plan (in parallel processes when jobs > 1); results in task order."""
    from benchmarks.evaluation.runner import benchmark

    return benchmark(p.trackers, p.files, p.options, p.jobs, p.max_segments, p.protocol, p.tracker_modules,
                     progress=progress, scheduler=p.scheduler, skip_absent=p.skip_absent,
                     stream=p.stream)


@dataclass
class BenchmarkRun:
    """A finished run: its plan, results in task order, tables, energy table (or None) and written files."""

    plan: Plan
    results: list
    summary: object
    energy: object | None = None
    paths: dict = field(default_factory=dict)

    @property
    def failed(self) -> list:
        """The results of runs that raised (a runtime failure), in task order."""
        return [r for r in self.results if r.error]


def tables_text(run: BenchmarkRun) -> str:
    """The run's tables as printed on a terminal: the protocol's table, per attribute, the energy table."""
    from benchmarks.analysis.attribute_tables import format_attributes
    from benchmarks.analysis.tables import terminal
    from benchmarks.evaluation.attributes import attribute_ope, attribute_scores

    protocol = run.plan.protocol
    if protocol == "stream":
        from benchmarks.analysis.stream_tables import format_stream

        parts = [format_stream(run.summary)]
        if run.energy is not None:
            from benchmarks.analysis.energy_table import format_energy_table

            parts.append(format_energy_table(run.energy))
        return "\n".join(parts)
    if protocol == "ope":
        from benchmarks.analysis.ope_tables import format_ope

        parts = [format_ope(run.summary)]
    else:
        parts = [terminal(run.summary)]
    parts.append("\nper attribute:\n" + format_attributes(
        attribute_ope(run.results) if protocol == "ope" else attribute_scores(run.results), protocol))
    if run.energy is not None:
        from benchmarks.analysis.energy_table import format_energy_table

        parts.append(format_energy_table(run.energy))
    return "\n".join(parts)


def run_benchmark(trackers: Sequence[str], data: Sequence[str] | None = None, split: str = "test",
                  out_dir: str | Path | None = None, jobs: int | None = None, scheduler: str | None = None,
                  tracker_modules: Sequence[str] = (), max_segments: int | None = None, plots: bool = False,
                  videos: Sequence[str] = (), checkpoint: str | None = None, energy: bool = True,
                  options: Sequence[str] = (), protocol: str = "ar", progress: bool = True,
                  show: Callable[[BenchmarkRun], None] | None = None,
                  labels: Mapping[str, str] | None = None, skip_absent: bool = False,
                  stream: Mapping | None = None) -> BenchmarkRun:
    """Check everything (plan_benchmark), run every tracker on every sequence, make and write the tables.

    `show` gets the finished run before any file is written (its `paths` still empty); a tracker that
    raises on a sequence is a result with `error` set (`BenchmarkRun.failed`), the tables still written;
    `labels` as plan_benchmark takes them.
    """
    from benchmarks.analysis.report import write_report
    from benchmarks.analysis.tables import summarise

    p = plan_benchmark(trackers, data, split, out_dir, jobs, scheduler, tracker_modules, max_segments, plots, videos,
                       checkpoint, energy, options, protocol, labels, skip_absent, stream)
    results = track(p, progress)
    if protocol == "stream":
        from benchmarks.evaluation.stream_summary import summarise_stream

        summary = summarise_stream(results, p.stream["predictive"], p.stream)
    elif protocol == "ope":
        from benchmarks.evaluation.ope import summarise_ope

        summary = summarise_ope(results)
    else:
        summary = summarise(results)
    table = None
    if p.model is not None and energy:
        from benchmarks.analysis.energy_table import energy_as_run_rows, energy_table

        # computed before writing: a crash here leaves out as it was
        table = energy_table(p.model, p.files, **p.ann_models, notes=p.notes)
        table["as_run"] = energy_as_run_rows(results)  # the trackers as this run ran them (sctn.energy_run)
    run = BenchmarkRun(p, results, summary, table)
    if show is not None:
        show(run)
    run.paths = write_report(p.out_dir, summary, results, protocol=protocol, plots=plots,
                             videos={seq: p.sequences[seq] for seq in videos}, energy=table)
    return run
