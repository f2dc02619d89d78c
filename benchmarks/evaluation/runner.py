"""Running trackers on dataset files: one tracker on one file, or every tracker on every file in worker processes."""

from __future__ import annotations

import sys
from collections.abc import Iterable, Sequence
from pathlib import Path

from benchmarks.evaluation.protocol import SequenceResult

PROTOCOLS = ("ar", "ope", "stream")  # the paper's A / R with re-initialisation; one pass (OTB-style OPE); streaming



def run_one(tracker: str, path: str | Path, modules: Sequence[str] = (), max_segments: int | None = None,
            options: dict | None = None, protocol: str = "ar", skip_absent: bool = False,
            stream: dict | None = None) -> SequenceResult:
    """One tracker on one dataset file; a tracker that fails to build or crashes gives a result with `error` set;
    skip_absent leaves segments with the target wholly hidden unscored (protocol rule 6) instead of apart.

    protocol "stream" gives a benchmarks.evaluation.stream.StreamSequence instead; stream: {latency: [specs],
    query_hz, window} (benchmarks.evaluation.stream.run_sequences)."""
    if protocol == "stream":
        return _run_stream(tracker, path, modules, max_segments, options, stream or {})
    import numpy as np

    from benchmarks.evaluation.protocol import run_sequence
    from benchmarks.trackers import get_tracker, load_tracker_module
    from dvsot.core.errors import exception_line
    from dvsot.dataset import Dataset

    for m in modules:
        load_tracker_module(m)
    with Dataset(path) as ds:
        try:
            instance = get_tracker(tracker, **(options or {}))
        except Exception as exc:  # a runtime failure: benchmark() built each tracker's class up front
            n = ds.num_segments if max_segments is None else min(max_segments, ds.num_segments)
            return SequenceResult(tracker, ds.name, np.full(n, np.nan), np.full((n, 4), np.nan), [], 0.0, 0,
                                  error=exception_line(exc))
        if "torch" in sys.modules:  # a torch-based tracker: sequences run in parallel, one thread each
            sys.modules["torch"].set_num_threads(1)
        result = run_sequence(instance, ds, tracker, max_segments=max_segments, reinitialise=protocol != "ope",
                              skip_absent=skip_absent)
        if result.error is None:
            from benchmarks.evaluation.attributes import add_attributes

            add_attributes(result, ds)
        if protocol == "ope":
            from benchmarks.evaluation.ope import add_centre_errors

            add_centre_errors(result, ds.segment_boxes())
        return result


def _run_stream(tracker: str, path, modules: Sequence[str], max_segments: int | None, options: dict | None,
                stream: dict):
    """One tracker on one file under every latency model of `stream` (run_one's protocol "stream")."""
    from benchmarks.evaluation.latency import parse_latency
    from benchmarks.evaluation.stream import DEFAULT_QUERY_HZ, StreamSequence, run_sequences
    from benchmarks.trackers import get_tracker, load_tracker_module, tracker_class
    from dvsot.core.errors import exception_line
    from dvsot.dataset import Dataset

    for m in modules:
        load_tracker_module(m)
    models = [m for spec in stream.get("latency", ["measured"]) for m in parse_latency(spec)]
    opts = dict(options or {})
    if any(m.kind == "declared" for m in models):  # a declared latency needs every call's operations
        opts.update(getattr(tracker_class(tracker), "count_every_call", {}))
    with Dataset(path) as ds:
        try:
            get_tracker(tracker, **opts)
        except Exception as exc:  # a runtime failure: benchmark() built each tracker's class up front
            return StreamSequence(tracker, ds.name, error=exception_line(exc))
        if "torch" in sys.modules:  # a torch-based tracker: sequences run in parallel, one thread each
            sys.modules["torch"].set_num_threads(1)
        return run_sequences(lambda: get_tracker(tracker, **opts), ds, models, tracker,
                             stream.get("query_hz", DEFAULT_QUERY_HZ), stream.get("window", "last"), max_segments)


def find_sequences(specs: str | Path | Sequence[str | Path], split: str | None = None) -> dict[str, Path]:
    """{sequence name: dataset file} of the files, directories or globs (split None: any); each must hold
    ground truth and a name of its own (they name the tables' columns)."""
    import numpy as np

    from dvsot.core.errors import UserError
    from dvsot.dataset import Dataset, find_datasets

    out: dict[str, Path] = {}
    for f in find_datasets(specs, split=split):
        with Dataset(f) as ds:
            if ds.num_segments == 0 or np.isnan(ds.segment_boxes()).any(axis=1).all():
                raise UserError(f"{f}: sequence has no ground-truth boxes to track")
            if ds.name in out:  # two files with one name would share (and overwrite) a table column
                raise UserError(f"{f}: sequence '{ds.name}' is also in {out[ds.name]}; the tables need distinct names")
            out[ds.name] = Path(f)
    return out


def benchmark(trackers: Iterable[str], files: Iterable[str | Path], options: dict[str, dict] | None = None,
              jobs: int = 1, max_segments: int | None = None, protocol: str = "ar",
              tracker_modules: Sequence[str] = (), progress: bool = False,
              scheduler: str | None = None, skip_absent: bool = False,
              stream: dict | None = None) -> list[SequenceResult]:
    """Every tracker on every file (tracker by tracker), here (jobs 1) or in `jobs` worker processes (local:N);
    options: {tracker: {key: value}}; skip_absent as run_one takes it.

    scheduler: "local:N" or "tcp://HOST:PORT" runs one Dask task per (tracker, file) there (dvsot.runtime.dask_tasks;
    the files must be at the same paths on the workers). Unknown trackers, jobs < 1, max_segments < 1, an
    unknown protocol or a malformed scheduler raise UserError before anything runs; a tracker that crashes
    on a sequence gives that result an `error` instead of raising. stream: protocol "stream"'s settings
    {latency: [specs], query_hz, window} (its results are StreamSequence).
    """
    from tqdm import tqdm

    from benchmarks.trackers import load_tracker_module, tracker_class
    from dvsot.core.errors import UserError

    if jobs < 1:
        raise UserError(f"jobs must be >= 1, got {jobs}")
    if max_segments is not None and max_segments < 1:
        raise UserError(f"max_segments must be >= 1, got {max_segments}")
    if protocol not in PROTOCOLS:
        raise UserError(f"protocol must be one of {', '.join(PROTOCOLS)}, got {protocol!r}")
    if scheduler:
        from dvsot.runtime.dask_tasks import parse_scheduler

        parse_scheduler(scheduler)
    for m in tracker_modules:
        load_tracker_module(m)
    names = list(dict.fromkeys(trackers))
    for name in names:
        tracker_class(name)
    options = options or {}
    paths = [str(f) for f in files]
    tasks = [(t, f) for t in names for f in paths]
    results: list = [None] * len(tasks)
    bar = tqdm(total=len(tasks), unit="run", desc="bench", disable=not progress)
    if scheduler or jobs > 1:  # one Dask task per run: --jobs N is local:N (dvsot.runtime.dask_tasks)
        from dvsot.runtime.dask_tasks import map_tasks

        calls = [(t, f, list(tracker_modules), max_segments, options.get(t), protocol, skip_absent, stream)
                 for t, f in tasks]
        results = map_tasks(scheduler or f"local:{jobs}", run_one, calls, lambda k, r: bar.update(1))
    else:
        for k, (t, f) in enumerate(tasks):
            bar.set_postfix_str(f"{t} on {Path(f).stem}")
            results[k] = run_one(t, f, tracker_modules, max_segments, options.get(t), protocol, skip_absent, stream)
            bar.update(1)
    bar.close()
    return results
