"""Ablations of SCTN: the paper preset against each named deviation, and the loss ablation (paper Fig. 7A).

Every row trains with the same budget and the same seeds and is tracked on the same test files; a
row differs from the paper preset in one setting only. Rows that change only the tracker (the fast
mode) reuse the preset's networks of the same seeds, so they differ in tracking alone. Results per
(row, seed) are written to --out as they finish (a rerun with the same --out skips the runs it has),
then the table prints mean and standard deviation over seeds.

    python -m benchmarks.ablation --train data/dvsot21 --test data/dvsot21 --rows paper squared_error \\
        --seeds 5 --epochs 2 --segments-per-epoch 400 --out runs/ablation     # one row per setting
    python -m benchmarks.ablation --rows paper loss_linear loss_basic --seeds 10 ...  # Fig. 7A
    python -m benchmarks.ablation --ci --rows paper loss_linear --seeds 2   # the two tiny CI scenes, quick
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import numpy as np

from sctn.samples import TRACK

# row -> (TrainConfig fields, NetworkConfig fields, SCTNTracker options) that differ from the paper preset
ROWS: dict[str, tuple[dict, dict, dict]] = {
    "paper": ({}, {}, {}),
    "fast_bilinear": ({}, {}, {"fast": True, "crop": "bilinear", "finetune_search_iters": 0}),
    "fast_nearest": ({}, {}, {"fast": True, "crop": "nearest", "finetune_search_iters": 0}),
    "fast_bilinear_search_tuned": ({}, {}, {"fast": True, "crop": "bilinear", "finetune_search_iters": 10}),
    "ops_penalty": ({"ops_penalty": 0.05}, {}, {}),
    "calibration": ({"calibrate": True}, {}, {}),
    "squared_error": ({"squared_error": True}, {}, {}),
    "background_term": ({"background_term": True}, {}, {}),
    "tail_steps": ({}, {"tail_steps": 2}, {}),
    "biases": ({}, {"bias": True}, {}),
    "loss_linear": ({"loss": "linear"}, {}, {}),
    "loss_basic": ({"loss": "basic"}, {}, {}),
}
METRICS = ("A", "R", "ARscore")


def training_key(row: str) -> str:
    """Rows that train the same network share it: the name of the row whose training this row uses."""
    train_kw, net_kw, _ = ROWS[row]
    for name, (t, n, _) in ROWS.items():
        if (t, n) == (train_kw, net_kw):
            return name
    return row  # pragma: no cover - every row matches itself


def run_one(row: str, seed: int, train_files: list[Path], test_files: list[Path], budget: dict, workdir: Path,
            n_candidates: int, max_segments: int | None) -> dict:
    """Train (or reuse) the network of one (row, seed) and track the test files; {row, seed, A, R, ARscore, ...}."""
    import torch

    from benchmarks.metrics import pooled
    from benchmarks.protocol import run_sequence
    from benchmarks.trackers.sctn import SCTNBenchTracker
    from dvsot.dataset import Dataset
    from sctn.checkpoint import load_checkpoint, save_checkpoint
    from sctn.network import NetworkConfig
    from sctn.tracker import SCTNTracker
    from sctn.train import TrainConfig, provenance, train

    torch.set_num_threads(1)
    train_kw, net_kw, track_kw = ROWS[row]
    ckpt = workdir / f"{training_key(row)}_seed{seed}.pt"
    if ckpt.is_file():
        model, meta = load_checkpoint(ckpt)
        minutes = meta.get("history", {}).get("minutes")
    else:
        cfg = TrainConfig(seed=seed, network=NetworkConfig(**net_kw), val_every=10**9, val_segments=2,
                          **budget, **train_kw)
        model, history = train(train_files, cfg, progress=False)
        save_checkpoint(ckpt, model, provenance(train_files, cfg, history))
        minutes = history["minutes"]
    ious, energy = [], []
    for f in test_files:
        bench = SCTNBenchTracker.wrap(SCTNTracker(model, seed=seed, n_candidates=n_candidates, **track_kw),
                                      energy_every=25)
        with Dataset(f) as ds:
            res = run_sequence(bench, ds, "sctn", max_segments=max_segments)
        ious.append(res.iou)
        e = bench.energy_per_segment()
        if e:
            energy.append(e["ac_ops"])
    s = pooled(ious)
    return {"row": row, "seed": seed, "A": s.accuracy, "R": s.robustness, "ARscore": s.arscore,
            "segments": s.segments, "train_minutes": minutes,
            "ac_ops_per_segment": float(np.mean(energy)) if energy else None}


def summarise(runs: list[dict]) -> dict:
    """{row: {"seeds": n, "mean": {...}, "std": {...}}} over the runs of each row (std over seeds, ddof 0)."""
    out: dict = {}
    for row in dict.fromkeys(r["row"] for r in runs):
        rs = [r for r in runs if r["row"] == row]
        keys = METRICS + ("ac_ops_per_segment",)
        vals = {k: [r[k] for r in rs if r.get(k) is not None] for k in keys}
        out[row] = {"seeds": len(rs), "mean": {k: float(np.mean(v)) if v else None for k, v in vals.items()},
                    "std": {k: float(np.std(v)) if v else None for k, v in vals.items()}}
    return out


def format_table(summary: dict) -> str:
    """The ablation as a markdown table: mean +- std over seeds per row."""
    lines = ["| row | A | R | ARscore | AC per segment | seeds |", "|---|---|---|---|---|---|"]
    for row, r in summary.items():
        cells = [f"{r['mean'][k]:.3f} ± {r['std'][k]:.3f}" for k in METRICS]
        ops = r["mean"]["ac_ops_per_segment"]
        lines.append(f"| {row} | " + " | ".join(cells) + f" | {ops:.2e} | {r['seeds']} |" if ops is not None else
                     f"| {row} | " + " | ".join(cells) + f" | | {r['seeds']} |")
    return "\n".join(lines)


def _ci_files(tmp: Path) -> tuple[list[Path], list[Path]]:
    """Render the two tiny CI scenes into tmp: ([train file], [test file])."""
    from benchmarks.regression import REFERENCE_DIR
    from dvsot.config import load_scene
    from dvsot.generate import generate

    files = {}
    for name in ("ci_train", "ci_test"):
        scene = REFERENCE_DIR / f"{name}.yaml"
        files[name] = tmp / f"{name}.h5"
        generate(load_scene(scene), files[name], scene.read_text(), progress=False)
    return [files["ci_train"]], [files["ci_test"]]


def main(argv: list[str] | None = None) -> int:
    """Command line of the ablation."""
    from concurrent.futures import ProcessPoolExecutor, as_completed

    from dvsot.dataset import find_datasets

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--train", nargs="+", help="training files / dirs / globs (split train)")
    p.add_argument("--test", nargs="+", help="test files / dirs / globs (split test)")
    p.add_argument("--ci", action="store_true", help="use the two tiny CI scenes (rendered into a temp dir)")
    p.add_argument("--rows", nargs="+", default=["paper"], choices=sorted(ROWS))
    p.add_argument("--seeds", type=int, default=5, help="seeds 0 .. N-1")
    p.add_argument("--first-seed", type=int, default=0)
    p.add_argument("--minutes", type=float, default=None, help="also stop each training after this long")
    p.add_argument("--epochs", type=int, default=2)
    p.add_argument("--segments-per-epoch", type=int, default=400)
    p.add_argument("--batch-segments", type=int, default=2)
    p.add_argument("--lr", type=float, default=3e-3)
    p.add_argument("--candidates", type=int, default=TRACK.n)
    p.add_argument("--max-segments", type=int, default=None, help="track at most this many segments per sequence")
    p.add_argument("--seed-major", action="store_true", help="run seed 0 of every row, then seed 1, ...")
    p.add_argument("--jobs", type=int, default=1, help="(row, seed) runs in parallel processes")
    p.add_argument("--out", required=True, help="directory for checkpoints and runs.jsonl (reused by a rerun)")
    a = p.parse_args(argv)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    budget = {"epochs": a.epochs, "segments_per_epoch": a.segments_per_epoch, "batch_segments": a.batch_segments,
              "lr": a.lr, "max_minutes": a.minutes}
    log = out / "runs.jsonl"
    done = [json.loads(line) for line in log.read_text().splitlines()] if log.is_file() else []
    have = {(r["row"], r["seed"]) for r in done}
    seeds = range(a.first_seed, a.first_seed + a.seeds)
    todo = [(row, s) for row in a.rows for s in seeds if (row, s) not in have]
    if a.seed_major:  # every row's first seeds before any row's later ones: a cut-short run still covers all rows
        todo.sort(key=lambda rs: rs[1])
    # rows that train first; tracker-only rows (which reuse those networks) once they exist
    phases = [[rs for rs in todo if training_key(rs[0]) == rs[0]], [rs for rs in todo if training_key(rs[0]) != rs[0]]]
    with tempfile.TemporaryDirectory() as tmp:
        if a.ci:
            train_files, test_files = _ci_files(Path(tmp))
        else:
            if not (a.train and a.test):
                p.error("give --train and --test, or --ci")
            train_files, test_files = find_datasets(a.train, "train"), find_datasets(a.test, "test")
        with ProcessPoolExecutor(a.jobs) as pool:
            for phase in phases:
                futures = [pool.submit(run_one, row, s, train_files, test_files, budget, out, a.candidates,
                                       a.max_segments) for row, s in phase]
                for fut in as_completed(futures):
                    r = fut.result()
                    with log.open("a") as fh:
                        fh.write(json.dumps(r) + "\n")
                    done.append(r)
                    print(json.dumps(r), flush=True)
    runs = [r for r in done if r["row"] in a.rows and r["seed"] in seeds]
    print(format_table(summarise(runs)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
