"""Benchmark trackers on dataset files: the paper's A / R / ARscore protocol, tables in five formats.

Examples:
  dvsot bench --tracker rct --tracker csrt                        # test split of data/dvsot21/
  dvsot bench --tracker sctn --tracker rct --data data/dvsot21 --plots
  dvsot bench --tracker kcf --data 'runs/*.h5' --split any --out runs/bench-kcf

Segments that count: see benchmarks/evaluation/protocol.py (initialisation segments and segments without
ground truth never count; a failure, IoU < 0.5, re-initialises on the next segment). --protocol ope
runs one pass without re-initialisation instead and reports success AUC and precision at 20 px
(benchmarks/evaluation/ope.py). Either way <out>/<tracker>/ gets per-sequence boxes, times and (re-initialising
protocol) VOT trajectories (benchmarks/analysis/sequence_files.py). --protocol stream scores each tracker on
the stream as it arrives, its answers late by its latency (--latency, --query-hz, --stream-window, --predictive;
benchmarks/evaluation/stream.py, docs/benchmarks.md).

Before anything runs, every input is checked: flags, data files, --video names, the SCTN checkpoint
(loaded into the model), each tracker built once with its --option values, and the output paths.
--checkpoint goes to the one tracker of the run that takes a checkpoint (benchmarks.bench.plan.CHECKPOINT_TRACKERS;
each ships one, used when none is given): an error without one or with several (give each its own with
--option NAME.checkpoint=PATH); a checkpoint of another model is refused naming the model it holds. The
energy table (Table 3) is made when any of those runs: SCTN's rows from the run's SCTN checkpoint (or the
shipped one), the ANN rows from the run's sctn_ann and siamfc checkpoints (or the shipped ones).

Outputs are written only when every run has finished, as temp files renamed into place together
(then run.json, the manifest naming the run and each file's SHA-256), so an interrupted or killed run
or bad input never leaves a table half-written, nor new tables beside old pictures.

The command parses its flags and calls the library: benchmarks.run_benchmark (the checks, the runs,
the tables and the outputs; benchmarks/bench/plan.py), its messages naming these flags (FLAGS).

Exit status:
  0  every tracker ran on every sequence; tables written.
  1  a tracker raised on some sequence (a runtime failure): the tables are still written, with that
     cell marked "failed" and the run left out of the "all" column, and stderr gets one line per
     failure naming tracker, sequence and error.
  2  bad input: one line on stderr naming the flag or file; nothing run, nothing written.
"""

from __future__ import annotations

import argparse
import sys

from benchmarks.bench.plan import CHECKPOINT_TRACKERS, DEFAULT_DATA
from benchmarks.trackers import BUILTIN

# run_benchmark's parameters as the flags that set them, for its messages (dvsot.core.errors.label)
FLAGS = {"trackers": "--tracker", "data": "--data", "out_dir": "--out", "jobs": "--jobs", "scheduler": "--scheduler",
         "tracker_modules": "--tracker-module", "max_segments": "--max-segments", "plots": "--plots",
         "videos": "--video", "checkpoint": "--checkpoint", "options": "--option", "protocol": "--protocol",
         "latency": "--latency", "query_hz": "--query-hz", "window": "--stream-window", "predictive": "--predictive"}


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Flags of `dvsot bench`."""
    p.add_argument("--tracker", action="append", required=True, metavar="NAME",
                   help=f"tracker to run (repeatable): {', '.join(BUILTIN)} or one you registered")
    p.add_argument("--data", nargs="+", default=None,
                   help=f"dataset files, directories or globs (default: {DEFAULT_DATA})")
    p.add_argument("--split", default="test", help="split attribute to keep: train, test, or 'any' (default test)")
    p.add_argument("--out", default=None, help="directory for the tables (default runs/bench-<time>)")
    p.add_argument("--jobs", type=int, default=None, help="parallel processes (default: min(2, runs))")
    p.add_argument("--scheduler", help="local:N (a Dask LocalCluster of N processes) or tcp://HOST:PORT: one task "
                                       "per (tracker, sequence) run; the data files must be at the same paths on the "
                                       "workers")
    p.add_argument("--tracker-module", action="append", default=[], metavar="MODULE",
                   help="import this module first, so that the trackers it registers can be named")
    p.add_argument("--max-segments", type=int, default=None,
                   help="only the first N (>= 1) segments of each sequence")
    p.add_argument("--plots", action="store_true", help="also write iou_over_time.png")
    p.add_argument("--video", action="append", default=[], metavar="SEQUENCE",
                   help="also write <out>/<SEQUENCE>.gif: event frames with predicted and true boxes")
    takers = f"{', '.join(CHECKPOINT_TRACKERS[:-1])} or {CHECKPOINT_TRACKERS[-1]}"
    p.add_argument("--checkpoint", help=f"checkpoint for the run's --tracker {takers} (default: the shipped one; "
                                        "each ships one); an error without one of them, "
                                        "or with several")
    p.add_argument("--no-energy", action="store_true", help=f"skip the energy table (made when {takers} runs)")
    p.add_argument("--option", action="append", default=[], metavar="TRACKER.KEY=VALUE",
                   help="constructor option of one tracker, e.g. sctn.fast=false or rct.cluster_size=0.05 "
                        "(checked before the run)")
    p.add_argument("--protocol", choices=["ar", "ope", "stream"], default="ar",
                   help="ar: the paper's A / R / ARscore with re-initialisation (default); ope: one pass, "
                        "success AUC and precision at 20 px; stream: latency-aware streaming evaluation "
                        "(benchmarks/evaluation/stream.py)")
    p.add_argument("--latency", action="append", default=None, metavar="MODEL",
                   help="stream: measured (default), scaled:F[,F...] (measured x F; several give a score curve) or "
                        "declared:PROFILE (counted operations x a hardware profile: cpu, loihi); repeatable")
    p.add_argument("--query-hz", type=float, default=None,
                   help="stream: ground-truth queries per second, 1 to 1e6 (default 1000)")
    p.add_argument("--stream-window", choices=["last", "since"], default=None,
                   help="stream: each call gets the last 10 ms of events (default) or all since its previous call")
    p.add_argument("--predictive", action="store_true",
                   help="stream: also score each answer extrapolated by its latency (a row of its own)")
    p.add_argument("--skip-absent", action="store_true",
                   help="leave segments whose target is wholly hidden unscored, as GOT-10k does (default: scored "
                        "apart, in the attribute table's absent column, as VOT-LT treats full occlusion)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def run(args: argparse.Namespace) -> int:
    """Check everything, run every tracker on every sequence, then print and write the tables (exit 1 on failures)."""
    from benchmarks.bench.plan import run_benchmark, tables_text

    done = run_benchmark(args.tracker, args.data, args.split, args.out, args.jobs, args.scheduler, args.tracker_module,
                         args.max_segments, args.plots, args.video, args.checkpoint, not args.no_energy, args.option,
                         args.protocol, progress=not args.quiet, show=lambda r: print(tables_text(r)), labels=FLAGS,
                         skip_absent=args.skip_absent,
                         stream={"latency": args.latency, "query_hz": args.query_hz, "window": args.stream_window,
                                 "predictive": args.predictive})
    print("written: " + ", ".join(str(x) for x in done.paths.values()))
    for r in done.failed:
        print(f"dvsot bench: failed: {r.tracker} on {r.sequence}: {r.error}", file=sys.stderr)
    return 1 if done.failed else 0
