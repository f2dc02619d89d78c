"""Ablations of SCTN: the paper preset against each named deviation, and the loss ablation (paper Fig. 7A).

Every row trains with the same budget and the same seeds and is tracked on the same test files; a
row differs from the paper preset in one setting only. Rows that change only the tracker (the fast
mode) reuse the preset's networks of the same seeds, so they differ in tracking alone. Results per
(row, seed) are written to --out as they finish (a rerun with the same --out skips the runs it has),
then the table prints mean and standard deviation over seeds.

    python -m benchmarks.experiments.ablation --train data/dvsot21 --test data/dvsot21 --rows paper squared_error \\
        --seeds 5 --epochs 2 --segments-per-epoch 400 --out runs/ablation     # one row per setting
    python -m benchmarks.experiments.ablation --rows paper loss_linear loss_basic --seeds 10 ...  # Fig. 7A
    python -m benchmarks.experiments.ablation --ci --rows paper loss_linear --seeds 2   # the two tiny CI scenes, quick
    python -m benchmarks.experiments.ablation ... --scheduler local:2 --retries 1      # each (row, seed) a Dask task
    python -m benchmarks.experiments.ablation --train data/dvsot21 --val-data data/val --test data/val \
        --test-split any --rows paper error_time_max calibration init_fluctuation --seeds 5 \
        --out runs/choices   # chosen on validation
    python -m benchmarks.experiments.ablation --train data/dvsot21 --test data/dvsot21 \
        --rows paper widths_x2 widths_x4 --seeds 3 --jobs 1 --out runs/widths   # + widths_mdnet: hours; speed: idle
    python -m benchmarks.experiments.ablation ... --rows paper background_term no_background_neuron --seeds 5

With --scheduler local:N | tcp://HOST:PORT each (row, seed) is one task on Dask (dvsot.runtime.dask_tasks.run_tasks, as
`dvsot generate` and `dvsot bench` use it); the workers need the data files and --out at the same paths. A
run that fails (it raised, or its worker died) is appended to runs.jsonl as {row, seed, attempt, worker,
error, final} and resubmitted, on another worker while there is one, up to --retries times while the others
go on; a tracker-only row whose network's training finally failed is recorded failed without running. The
exit status is 1 if any run finally failed (its row's table cell is then over fewer seeds).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

from sctn.network import NetworkConfig
from sctn.samples import TRACK

PRESET_NET = NetworkConfig()
MDNET_WIDTHS = {"channels": (96, 256, 512), "fc": (512, 512)}  # MDNet's conv1-3 and fc4-5 (Nam and Han 2016)


def scaled_widths(factor: int) -> dict:
    """NetworkConfig fields of the preset's convolution and fully connected widths times `factor`."""
    return {"channels": tuple(factor * c for c in PRESET_NET.channels), "fc": tuple(factor * n for n in PRESET_NET.fc)}


# row -> (TrainConfig fields, NetworkConfig fields, SCTNTracker options) that differ from the paper preset
ROWS: dict[str, tuple[dict, dict, dict]] = {
    "paper": ({}, {}, {}),
    "fast_bilinear": ({}, {}, {"fast": True, "crop": "bilinear", "finetune_search_iters": 0}),
    "fast_nearest": ({}, {}, {"fast": True, "crop": "nearest", "finetune_search_iters": 0}),
    "fast_bilinear_search_tuned": ({}, {}, {"fast": True, "crop": "bilinear", "finetune_search_iters": 10}),
    "ops_penalty": ({"ops_penalty": 0.05}, {}, {}),
    "calibration": ({"init": "calibrate"}, {}, {}),
    "init_fluctuation": ({"init": "fluctuation"}, {}, {}),
    "error_time_max": ({"error_time": "max"}, {}, {"error_time": "max"}),
    "stca_code": ({"error_time": "stca_code"}, {}, {"error_time": "stca_code"}),  # STCA as its authors code it
    "lr_cosine": ({"lr_schedule": "cosine"}, {}, {}),  # the paper gives no schedule: constant, or cosine to 0
    "finetune_balanced": ({}, {}, {"finetune_balanced": True}),
    "finetune_fc_only": ({}, {}, {"finetune_layers": "fc"}),
    # what a re-initialisation starts from (the preset: a new tracker, Algorithm 1 from the trained network again)
    "online_tuning": ({}, {}, {"reinit": "online"}),  # online learning on the test sequence: tunes the tuned network
    "tuned_once": ({}, {}, {"reinit": "once"}),  # Algorithm 1's single tuning kept: box and range reset only
    "squared_error": ({"squared_error": True}, {}, {}),
    # the background output neuron: trained by the mirrored error, or left out of the network and its op counts
    # (the preset keeps it, untrained: the paper has two output neurons and trains the target's voltage)
    "background_term": ({"background_term": True}, {}, {}),
    "no_background_neuron": ({}, {"background_neuron": False}, {}),
    "tail_steps": ({}, {"tail_steps": 2}, {}),
    "biases": ({}, {"bias": True}, {}),
    "loss_linear": ({"loss": "linear"}, {}, {}),
    "loss_basic": ({"loss": "basic"}, {}, {}),
    # widths from the preset's (conv 8/16/16, fc 64/32) towards MDNet's; the paper gives none. Wider than 32
    # channels a convolution is evaluated densely (sctn.sparse.evaluate.exact_blocker), and MDNet's widths train and
    # track one to two orders of magnitude slower than the preset's
    "widths_x2": ({}, scaled_widths(2), {}),
    "widths_x4": ({}, scaled_widths(4), {}),
    "widths_mdnet": ({}, MDNET_WIDTHS, {}),
}
# rows that were renamed when the preset became a new tracker per re-initialisation: what each is now
RETIRED_ROWS = {"finetune_first_only": "tuned_once",
                "reinit_from_trained": "paper (which now also restarts the fine-tuning's generator)"}
METRICS = ("A", "R", "ARscore")
ENERGY_EVERY = 10  # each run counts the operations of every 10th tracked segment and of every initialisation


def training_key(row: str) -> str:
    """Rows that train the same network share it: the name of the row whose training this row uses."""
    train_kw, net_kw, _ = ROWS[row]
    for name, (t, n, _) in ROWS.items():
        if (t, n) == (train_kw, net_kw):
            return name
    return row  # pragma: no cover - every row matches itself


def run_one(row: str, seed: int, train_files: list[Path], test_files: list[Path], budget: dict, workdir: Path,
            n_candidates: int, max_segments: int | None, val_files: list[Path] | None = None) -> dict:
    """Train (or reuse) the network of one (row, seed) and track the test files; {row, seed, A, R, ARscore, ...}."""
    import torch

    from benchmarks.evaluation.metrics import pooled
    from benchmarks.evaluation.protocol import run_sequence
    from benchmarks.trackers.sctn import SCTNBenchTracker
    from dvsot.dataset import Dataset
    from sctn.checkpoint import load_checkpoint, save_checkpoint
    from sctn.energy_run import energy_as_run
    from sctn.network import NetworkConfig
    from sctn.tracker import SCTNTracker
    from sctn.training.snn import TrainConfig, provenance, train

    torch.set_num_threads(1)
    train_kw, net_kw, track_kw = ROWS[row]
    ckpt = workdir / f"{training_key(row)}_seed{seed}.pt"
    ckpt_meta = ckpt.is_file()
    if ckpt_meta:
        model, meta = load_checkpoint(ckpt)
        minutes, silent = meta.get("history", {}).get("minutes"), meta.get("history", {}).get("silent")
    else:
        cfg = TrainConfig(seed=seed, network=NetworkConfig(**net_kw), val_every=10**9, **budget, **train_kw)
        model, history = train(train_files, cfg, progress=False, val_files=val_files)
        save_checkpoint(ckpt, model, provenance(train_files, cfg, history))
        minutes, silent = history["minutes"], history.get("silent")
    ious, results = [], []
    tracked, seconds, init_seconds = 0, 0.0, 0.0
    for f in test_files:
        bench = SCTNBenchTracker.wrap(SCTNTracker(model, seed=seed, n_candidates=n_candidates, **track_kw),
                                      energy_every=ENERGY_EVERY)
        with Dataset(f) as ds:
            res = run_sequence(bench, ds, "sctn", max_segments=max_segments)
        ious.append(res.iou)
        results.append(res)
        tracked, seconds, init_seconds = (tracked + res.tracked_segments, seconds + res.tracker_seconds,
                                          init_seconds + res.init_seconds)
    s = pooled(ious)
    energy = energy_as_run(results)  # the tracker as it ran: its own counted segments and initialisations
    history = meta.get("history", {}) if ckpt_meta else history
    return {"row": row, "seed": seed, "A": s.accuracy, "R": s.robustness, "ARscore": s.arscore,
            "segments": s.segments, "train_minutes": minutes, "silent": silent,
            "target_vmax_pos": history.get("target_vmax_pos"), "nearly_silent": history.get("nearly_silent"),
            "ac_ops_per_evaluation": energy["per_evaluation"]["synaptic"]["ac_ops"] if energy else None,
            "ac_ops_per_segment": energy["per_segment"]["synaptic"]["ac_ops"] if energy else None,
            "state_updates_per_evaluation": energy["per_evaluation"]["state"]["state_updates"] if energy else None,
            "energy_pj_per_initialisation": energy["per_initialisation"]["energy_pj"] if energy else None,
            "energy_pj_per_sequence": energy["per_sequence"]["energy_pj"] if energy else None,
            "segments_per_s": tracked / seconds if seconds > 0 else None, "init_seconds": init_seconds}


def summarise(runs: list[dict]) -> dict:
    """{row: {"seeds": n, "mean": {...}, "std": {...}}} over the runs of each row (std over seeds, ddof 0)."""
    out: dict = {}
    for row in dict.fromkeys(r["row"] for r in runs):
        rs = [r for r in runs if r["row"] == row]
        keys = METRICS + ("ac_ops_per_segment", "ac_ops_per_evaluation", "target_vmax_pos", "segments_per_s")
        vals = {k: [r[k] for r in rs if r.get(k) is not None] for k in keys}
        out[row] = {"seeds": len(rs), "silent": sum(bool(r.get("silent")) for r in rs),
                    "nearly_silent": sum(bool(r.get("nearly_silent")) for r in rs),
                    "mean": {k: float(np.mean(v)) if v else None for k, v in vals.items()},
                    "std": {k: float(np.std(v)) if v else None for k, v in vals.items()}}
    return out


def format_table(summary: dict) -> str:
    """The ablation as a markdown table: mean +- std over seeds per row; tracking speed is segments per second of the
    tracker's update time (fine-tuning apart), one thread, as loaded as the machine was."""
    lines = ["| row | A | R | ARscore | AC per evaluation | AC per segment | segments/s | seeds | silent "
             "| nearly silent |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for row, r in summary.items():
        cells = [f"{r['mean'][k]:.3f} ± {r['std'][k]:.3f}" for k in METRICS]
        ops = [r["mean"].get(k) for k in ("ac_ops_per_evaluation", "ac_ops_per_segment")]
        speed = r["mean"].get("segments_per_s")
        lines.append(f"| {row} | " + " | ".join(cells) + "".join(f" | {v:.2e}" if v is not None else " | " for v in ops)
                     + (f" | {speed:.2f}" if speed is not None else " | ")
                     + f" | {r['seeds']} | {r.get('silent', 0)} | {r.get('nearly_silent', 0)} |")
    return "\n".join(lines)


def _ci_files(tmp: Path) -> tuple[list[Path], list[Path]]:
    """Render the two tiny CI scenes into tmp: ([train file], [test file])."""
    from benchmarks.experiments.regression import REFERENCE_DIR
    from dvsot.pipeline.generate import generate
    from dvsot.scene import load_scene

    files = {}
    for name in ("ci_train", "ci_test"):
        scene = REFERENCE_DIR / f"{name}.yaml"
        files[name] = tmp / f"{name}.h5"
        generate(load_scene(scene), files[name], scene.read_text(), progress=False)
    return [files["ci_train"]], [files["ci_test"]]


def read_log(log: Path) -> list[dict]:
    """The records of runs.jsonl: results ({row, seed, A, R, ...}) and failed attempts (with "error")."""
    return [json.loads(line) for line in log.read_text().splitlines() if line.strip()] if log.is_file() else []


def _append(log: Path, record: dict) -> None:
    with log.open("a") as fh:
        fh.write(json.dumps(record) + "\n")


def _run(phases: list[list[tuple]], args: tuple, scheduler: str | None, retries: int, on_result, on_failure) -> list:
    """Each phase's (row, seed) runs as tasks (dvsot.runtime.dask_tasks.TaskRunner: here when scheduler is None, else
    on one cluster for every phase), a failed run retried; the (row, seed)s that finally failed."""
    from dvsot.runtime.dask_tasks import Failure, TaskRunner

    failed: list[tuple] = []
    with TaskRunner(scheduler) as runner:
        for phase in phases:
            runnable = []
            for row, s in phase:  # a tracker-only row needs its network's checkpoint from the first phase
                if (training_key(row), s) in failed:
                    failure = Failure(f"its network's training run ({training_key(row)}, seed {s}) failed")
                    on_failure(row, s, 1, failure, True)
                    failed.append((row, s))
                else:
                    runnable.append((row, s))
            tries = [0] * len(runnable)

            def failed_attempt(k: int, failure, final: bool, runnable=runnable, tries=tries) -> None:
                tries[k] += 1
                on_failure(*runnable[k], tries[k], failure, final)
                if final:
                    failed.append(runnable[k])

            runner.run(run_one, [(row, s, *args) for row, s in runnable], retries,
                       on_result=lambda k, r: on_result(r), on_failure=failed_attempt, name="ablation-run",
                       lease_dir=args[3])  # --out: the checkpoints
    return failed


def main(argv: list[str] | None = None) -> int:
    """Command line of the ablation: 0, or 1 if a run finally failed (with --scheduler)."""
    from dvsot.dataset import find_datasets
    from dvsot.runtime.dask_tasks import parse_scheduler

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--train", nargs="+", help="training files / dirs / globs (split train)")
    p.add_argument("--test", nargs="+", help="test files / dirs / globs (split test)")
    p.add_argument("--test-split", default="test", help="split of the --test files, or 'any' (validation scenes "
                   "have none: --test data/val --test-split any makes the rows' choice on validation)")
    p.add_argument("--ci", action="store_true", help="use the two tiny CI scenes (rendered into a temp dir)")
    p.add_argument("--rows", nargs="+", default=["paper"], help=f"rows: {', '.join(ROWS)}")
    p.add_argument("--seeds", type=int, default=5, help="seeds 0 .. N-1")
    p.add_argument("--first-seed", type=int, default=0)
    p.add_argument("--minutes", type=float, default=None, help="also stop each training after this long")
    # the training budget: the recipe's (sctn.training.snn.TrainConfig's defaults) unless given
    p.add_argument("--epochs", type=int, default=None, help="default: the recipe's")
    p.add_argument("--segments-per-epoch", type=int, default=None, help="default: the recipe's")
    p.add_argument("--batch-segments", type=int, default=None, help="default: the recipe's")
    p.add_argument("--lr", type=float, default=None, help="default: the recipe's")
    p.add_argument("--val-data", nargs="+", default=None, help="validation files / dirs / globs (any split): the "
                   "silence check (target V_max on positives) on them instead of every 10th training segment")
    p.add_argument("--val-segments", type=int, default=2, help="validation segments of the silence check")
    p.add_argument("--candidates", type=int, default=TRACK.n)
    p.add_argument("--max-segments", type=int, default=None, help="track at most this many segments per sequence")
    p.add_argument("--seed-major", action="store_true", help="run seed 0 of every row, then seed 1, ...")
    p.add_argument("--jobs", type=int, default=1, help="(row, seed) runs in parallel processes: local:N (1: here)")
    p.add_argument("--scheduler", help="run each (row, seed) as a Dask task: local:N (a LocalCluster of N "
                   "single-threaded workers) or tcp://HOST:PORT (a running cluster)")
    p.add_argument("--retries", type=int, default=1, help="resubmit a failed run this many times")
    p.add_argument("--out", required=True, help="directory for checkpoints and runs.jsonl (reused by a rerun)")
    a = p.parse_args(argv)
    for row in a.rows:
        if row in RETIRED_ROWS:
            p.error(f"--rows {row}: renamed; it is now {RETIRED_ROWS[row]}")
        if row not in ROWS:
            p.error(f"--rows {row}: no such row (choose from {', '.join(ROWS)})")
    if a.scheduler:
        parse_scheduler(a.scheduler)  # a bad spec: one line, before anything runs
    if a.retries < 0:
        p.error(f"--retries must be >= 0, got {a.retries}")
    if a.jobs < 1:
        p.error(f"--jobs must be >= 1, got {a.jobs}")
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    given = {"epochs": a.epochs, "segments_per_epoch": a.segments_per_epoch, "batch_segments": a.batch_segments,
             "lr": a.lr}
    budget = {**{k: v for k, v in given.items() if v is not None}, "max_minutes": a.minutes,
              "val_segments": a.val_segments}
    log = out / "runs.jsonl"
    done = [r for r in read_log(log) if "error" not in r]  # failed attempts are run again
    have = {(r["row"], r["seed"]) for r in done}
    seeds = range(a.first_seed, a.first_seed + a.seeds)
    todo = [(row, s) for row in a.rows for s in seeds if (row, s) not in have]
    if a.seed_major:  # every row's first seeds before any row's later ones: a cut-short run still covers all rows
        todo.sort(key=lambda rs: rs[1])
    # rows that train first; tracker-only rows (which reuse those networks) once they exist
    phases = [[rs for rs in todo if training_key(rs[0]) == rs[0]], [rs for rs in todo if training_key(rs[0]) != rs[0]]]
    failed: list = []
    if todo:  # nothing to run: no scene rendered, no cluster started
        with tempfile.TemporaryDirectory() as tmp:
            if a.ci:
                train_files, test_files = _ci_files(Path(tmp))
            else:
                if not (a.train and a.test):
                    p.error("give --train and --test, or --ci")
                train_files = find_datasets(a.train, "train")
                test_files = find_datasets(a.test, None if a.test_split == "any" else a.test_split)
            val_files = find_datasets(a.val_data, None) if a.val_data else None
            args = (train_files, test_files, budget, out, a.candidates, a.max_segments, val_files)

            def on_result(r: dict) -> None:
                _append(log, r)
                done.append(r)
                print(json.dumps(r), flush=True)

            def on_failure(row: str, seed: int, attempt: int, failure, final: bool) -> None:
                _append(log, {"row": row, "seed": seed, "attempt": attempt, "worker": failure.worker,
                              "error": failure.error, "final": final})
                print(f"ablation: {row} seed {seed} failed{f' on {failure.worker}' if failure.worker else ''} "
                      f"({failure.error}){'' if final else '; retrying'}", file=sys.stderr, flush=True)

            scheduler = a.scheduler or (f"local:{a.jobs}" if a.jobs > 1 else None)
            failed = _run(phases, args, scheduler, a.retries, on_result, on_failure)
    runs = [r for r in done if r["row"] in a.rows and r["seed"] in seeds]
    print(format_table(summarise(runs)))
    if failed:
        print(f"ablation: {len(failed)} run(s) failed: " + ", ".join(f"{r} seed {s}" for r, s in failed),
              file=sys.stderr)
        return 1
    return 0


def cli(argv: list[str] | None = None) -> int:
    """main, with bad input (exit 2) and a run that could not start (exit 1) as one line on stderr."""
    from dvsot.core.errors import RunError, UserError

    try:
        return main(argv)
    except UserError as exc:
        print(f"ablation: {exc}", file=sys.stderr)
        return 2
    except RunError as exc:
        print(f"ablation: {exc}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    raise SystemExit(cli())
