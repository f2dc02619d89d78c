"""Benchmark trackers on dataset files: the paper's A / R / ARscore protocol, tables in five formats.

Examples:
  dvsot bench --tracker rct --tracker csrt                        # test split of data/dvsot21/
  dvsot bench --tracker sctn --tracker rct --data data/dvsot21 --plots
  dvsot bench --tracker kcf --data 'runs/*.h5' --split any --out runs/bench-kcf

Segments that count: see benchmarks/protocol.py (initialisation segments and segments without
ground truth never count; a failure, IoU < 0.5, re-initialises on the next segment).
"""

from __future__ import annotations

import argparse

DEFAULT_DATA = "data/dvsot21"


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Flags of `dvsot bench`."""
    p.add_argument("--tracker", action="append", required=True, metavar="NAME",
                   help="tracker to run (repeatable): sctn, rct, csrt, kcf, mil or one you registered")
    p.add_argument("--data", nargs="+", default=None,
                   help=f"dataset files, directories or globs (default: {DEFAULT_DATA})")
    p.add_argument("--split", default="test", help="split attribute to keep: train, test, or 'any' (default test)")
    p.add_argument("--out", default=None, help="directory for the tables (default runs/bench-<time>)")
    p.add_argument("--jobs", type=int, default=None, help="parallel processes (default: min(2, runs))")
    p.add_argument("--tracker-module", action="append", default=[], metavar="MODULE",
                   help="import this module first, so that the trackers it registers can be named")
    p.add_argument("--max-segments", type=int, default=None, help="only the first N segments of each sequence")
    p.add_argument("--plots", action="store_true", help="also write iou_over_time.png")
    p.add_argument("--video", action="append", default=[], metavar="SEQUENCE",
                   help="also write <out>/<SEQUENCE>.gif: event frames with predicted and true boxes")
    p.add_argument("--checkpoint", help="SCTN checkpoint for --tracker sctn (default: the shipped one)")
    p.add_argument("--no-energy", action="store_true", help="skip the energy table when sctn runs")
    p.add_argument("--option", action="append", default=[], metavar="TRACKER.KEY=VALUE",
                   help="constructor option of one tracker, e.g. sctn.fast=false or rct.cluster_size=0.05")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def _run_one(tracker: str, path: str, modules: list[str], max_segments: int | None, options: dict | None = None):
    """Worker: run one tracker on one file (in a fresh process when parallel)."""
    from benchmarks.protocol import run_sequence
    from benchmarks.trackers import get_tracker, load_tracker_module
    from dvsot.dataset import Dataset

    for m in modules:
        load_tracker_module(m)
    with Dataset(path) as ds:
        try:
            instance = get_tracker(tracker, **(options or {}))
        except Exception as exc:  # construction failures fail this run only, like crashes
            from benchmarks.protocol import SequenceResult
            import numpy as np

            n = ds.num_segments
            return SequenceResult(tracker, ds.name, np.full(n, np.nan), np.full((n, 4), np.nan), [], 0.0, 0,
                                  error=f"{type(exc).__name__}: {exc}")
        return run_sequence(instance, ds, tracker, max_segments=max_segments)


def _options(specs: list[str], trackers: list[str]) -> dict[str, dict]:
    """{tracker: {key: value}} from TRACKER.KEY=VALUE strings (values parsed as JSON when they are)."""
    import json

    from dvsot.errors import UserError

    out: dict[str, dict] = {}
    for spec in specs:
        name, _, rest = spec.partition(".")
        key, eq, raw = rest.partition("=")
        if not (name and key and eq):
            raise UserError(f"--option {spec!r}: expected TRACKER.KEY=VALUE")
        if name not in trackers:
            raise UserError(f"--option {spec!r}: tracker '{name}' is not in this run")
        try:
            value = json.loads(raw)
        except json.JSONDecodeError:
            value = raw
        out.setdefault(name, {})[key] = value
    return out


def _name(path) -> str:
    from dvsot.dataset import Dataset

    with Dataset(path) as ds:
        return ds.name


def resolve_data(specs: list[str] | None, split: str) -> list:
    """The dataset files to benchmark; each must hold ground truth. Raises UserError otherwise."""
    from pathlib import Path

    import numpy as np

    from dvsot.dataset import Dataset, find_datasets
    from dvsot.errors import UserError

    if specs is None:
        if not Path(DEFAULT_DATA).is_dir():
            raise UserError(f"{DEFAULT_DATA}: no default data; make it with "
                            f"`dvsot generate blender_scenes/*.yaml --out-dir {DEFAULT_DATA}` or pass --data")
        specs = [DEFAULT_DATA]
    files = find_datasets(specs, split=None if split == "any" else split)
    for f in files:
        with Dataset(f) as ds:
            if ds.num_segments == 0 or np.isnan(ds.segment_boxes()).any(axis=1).all():
                raise UserError(f"{f}: sequence has no ground-truth boxes to track")
    return files


def run(args: argparse.Namespace) -> int:
    """Run every tracker on every sequence, print the table and write it in every format."""
    import json
    import os
    import time
    from concurrent.futures import ProcessPoolExecutor, as_completed
    from multiprocessing import get_context
    from pathlib import Path

    from tqdm import tqdm

    from benchmarks.tables import summarise, terminal, write_tables
    from benchmarks.trackers import load_tracker_module, tracker_class
    from dvsot.errors import UserError

    for m in args.tracker_module:
        load_tracker_module(m)
    trackers = list(dict.fromkeys(args.tracker))
    for name in trackers:
        tracker_class(name)
    files = resolve_data(args.data, args.split)
    if args.jobs is not None and args.jobs < 1:
        raise UserError(f"--jobs must be >= 1, got {args.jobs}")
    tasks = [(t, str(f)) for t in trackers for f in files]
    options = _options(args.option, trackers)
    if args.checkpoint:
        options.setdefault("sctn", {})["checkpoint"] = args.checkpoint
    jobs = args.jobs or min(2, os.cpu_count() or 1, len(tasks))
    out_dir = Path(args.out or f"runs/bench-{time.strftime('%Y%m%d-%H%M%S')}")
    results: list = [None] * len(tasks)
    bar = tqdm(total=len(tasks), unit="run", desc="bench", disable=args.quiet)
    if jobs == 1:
        for k, (t, f) in enumerate(tasks):
            bar.set_postfix_str(f"{t} on {Path(f).stem}")
            results[k] = _run_one(t, f, args.tracker_module, args.max_segments, options.get(t))
            bar.update(1)
    else:
        # spawn: each worker starts clean (torch and OpenCV threads do not survive fork well)
        with ProcessPoolExecutor(jobs, mp_context=get_context("spawn")) as pool:
            futures = {pool.submit(_run_one, t, f, args.tracker_module, args.max_segments, options.get(t)): k
                       for k, (t, f) in enumerate(tasks)}
            for fut in as_completed(futures):
                results[futures[fut]] = fut.result()
                bar.update(1)
    bar.close()
    summary = summarise(results)
    print(terminal(summary))
    for r in results:
        if r.error:
            print(f"failed: {r.tracker} on {r.sequence}: {r.error}")
    paths = write_tables(summary, out_dir)
    if args.plots:
        from benchmarks.pictures import plot_iou_over_time

        per = {}
        for r in results:
            per.setdefault(r.tracker, {})[r.sequence] = r.iou
        paths["png"] = plot_iou_over_time(per, out_dir / "iou_over_time.png")
    for seq in args.video:
        from dvsot.preview import write_preview

        chosen = [r for r in results if r.sequence == seq]
        if not chosen:
            raise UserError(f"--video {seq}: no such sequence in this run")
        path = next(f for f in files if _name(f) == seq)
        paths[f"gif:{seq}"] = write_preview(path, out_dir / f"{seq}.gif", {r.tracker: r.predictions for r in chosen})
    if "sctn" in trackers and not args.no_energy:
        from benchmarks.energy_table import energy_table, format_energy_table, plot_firing_rates
        from sctn.checkpoint import load_checkpoint

        table = energy_table(load_checkpoint(args.checkpoint)[0], files)
        print(format_energy_table(table))
        (out_dir / "energy.json").write_text(json.dumps(table, indent=2))
        paths["energy"] = out_dir / "energy.json"
        paths["firing"] = plot_firing_rates(table["firing"], out_dir / "firing_rate.png")
    print("written: " + ", ".join(str(p) for p in paths.values()))
    return 0
