"""Time one SCTN training step (forward, voltage loss, backward, Adam) with the compiled C-LIF and with
the reference loop of torch ops; print JSON.

    python -m benchmarks.perf.bench_training [--data FILE.h5] [--checkpoint CKPT] [--steps 5] [--repeat 3]
        [--batch-segments 2] [--threads 1] [--full DATA_DIR] [--row ROW] [--budget-steps N] [--compiled-only]

A step is what `dvsot train` runs per mini-batch: the samples of --batch-segments segments (20
positive + 40 negative each), encoded as 107x107 canvases. Without --data a synthetic 160x120
sequence (a textured square, made in numpy) gives the segments. Each figure is the best of --repeat
runs of --steps steps after one warm-up step (which compiles the numba kernels); the two paths start
from the same weights and batches.

The checkpoint's recorded budget (its .json's train_config) gives `projected_minutes`: its step count
times the compiled path's time per step (validation and data loading not included). `--full DATA_DIR`
measures instead of projecting: it trains a new network with that train_config on the files of DIR
named in the checkpoint's data list, as `dvsot train` does, and prints the wall and CPU minutes.

`--row ROW` times the network of an ablation row (benchmarks.experiments.ablation.ROWS, e.g. the widths
sweep's widths_x2 / widths_x4 / widths_mdnet) from its initial weights (seed 0) instead of the
checkpoint's; `--budget-steps N` projects N steps instead of the recorded budget (the ablation's plateau
budget is 500), so a row too slow to train here still gets its time to that budget.
"""

from __future__ import annotations

import argparse
import copy
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import torch


def time_steps(model, batches, reference: bool, steps: int, repeat: int) -> dict:
    """Best wall and CPU seconds per training step over `repeat` runs of `steps` steps (after a warm-up)."""
    from sctn.loss import error_voltages, voltage_loss
    from sctn.neurons import CLIF

    forward = CLIF.forward
    if reference:
        CLIF.forward = CLIF._forward_reference  # type: ignore[method-assign]
    try:
        best = None
        for _ in range(repeat):
            net = copy.deepcopy(model)
            net.train()
            opt = torch.optim.Adam(net.parameters(), lr=1e-3)
            losses = []
            for k in range(steps + 1):
                if k == 1:
                    start, cpu = time.perf_counter(), time.process_time()
                x, iou, pos = batches[k % len(batches)]
                # the preset's error-time rule; its random steps seeded per step, so both paths draw the same
                volts = error_voltages(net(x), pos, "stca", np.random.default_rng(k))
                loss = voltage_loss(volts, iou, pos, "exp")
                opt.zero_grad()
                loss.backward()
                opt.step()
                losses.append(float(loss.detach()))
            wall, cpu = time.perf_counter() - start, time.process_time() - cpu
            if best is None or wall < best[0]:
                best = (wall, cpu, losses)
    finally:
        CLIF.forward = forward  # type: ignore[method-assign]
    wall, cpu, losses = best
    return {"path": "reference torch loop" if reference else "compiled", "steps": steps,
            "s_per_step": round(wall / steps, 3), "cpu_s_per_step": round(cpu / steps, 3),
            "losses": [round(v, 6) for v in losses]}


def budget_steps(train_config: dict) -> int:
    """Optimiser steps of a training budget, given enough segments: epochs x (segments per epoch // per step)."""
    return int(train_config["epochs"]) * (
        int(train_config["segments_per_epoch"]) // int(train_config["batch_segments"])
    )


def full_training(meta: dict, data_dir: Path, threads: int) -> dict:
    """Train a new network with the checkpoint's recorded train_config on its training files found in data_dir;
    wall and CPU minutes."""
    from sctn.training.snn import TrainConfig, train

    names = [d["name"] for d in meta.get("data", []) if d.get("split", "train") == "train"]
    files = [data_dir / f"{n}.h5" for n in names]
    missing = [str(f) for f in files if not f.is_file()]
    if not names or missing:
        raise SystemExit(
            f"{data_dir}: --full needs the checkpoint's training files, missing: {missing or 'its data list'}"
        )
    cfg = TrainConfig(**meta["train_config"])
    torch.set_num_threads(threads)
    start, cpu = time.perf_counter(), time.process_time()
    _, history = train(files, cfg, progress=False, log=lambda *a, **k: None)
    return {"files": names, "steps": history["steps"], "minutes": round((time.perf_counter() - start) / 60, 2),
            "cpu_minutes": round((time.process_time() - cpu) / 60, 2), "silent": history.get("silent")}


def row_model(row: str):
    """A fresh network (seed 0, the preset's Kaiming start) with the NetworkConfig fields of ablation row `row`."""
    from benchmarks.experiments.ablation import ROWS
    from sctn.network import SCTN, NetworkConfig

    if row not in ROWS:
        raise SystemExit(f"--row: unknown ablation row {row!r}; rows: {', '.join(sorted(ROWS))}")
    torch.manual_seed(0)
    return SCTN(NetworkConfig(**ROWS[row][1]))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", help="dataset file (default: a synthetic sequence)")
    parser.add_argument("--checkpoint", help="SCTN checkpoint whose network is trained (default: the shipped one)")
    parser.add_argument("--steps", type=int, default=5)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--batch-segments", type=int, default=2)
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--full", type=Path, metavar="DATA_DIR",
                        help="also train the checkpoint's whole recorded budget on DIR's files and time it")
    parser.add_argument("--row", help="time this ablation row's network (fresh weights) instead of the checkpoint's")
    parser.add_argument("--compiled-only", action="store_true", help="skip the reference torch loop (wide rows)")
    parser.add_argument("--budget-steps", type=int, help="project this many steps instead of the recorded budget")
    args = parser.parse_args()
    if args.budget_steps is not None and args.budget_steps < 1:
        parser.error(f"--budget-steps must be >= 1, got {args.budget_steps}")
    if args.row and args.full:
        parser.error("--full trains the checkpoint's recorded network; it does not take --row")
    from dvsot.dataset import Dataset
    from sctn.checkpoint import load_checkpoint
    from sctn.training.snn import segment_batch, usable_segments

    torch.set_num_threads(args.threads)
    model, meta = load_checkpoint(args.checkpoint)
    if args.row:
        model = row_model(args.row)
    rng = np.random.default_rng(0)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(args.data) if args.data else None
        if path is None:
            sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests"))
            from synthetic import moving_square_file

            path = moving_square_file(Path(tmp) / "syn.h5", duration_ms=200, seed=1)
        with Dataset(path) as ds:
            usable = usable_segments(ds, 8.0)
            picks = rng.choice(usable, (args.steps + 1, args.batch_segments), replace=len(usable) < 2 * args.steps)
            batches = []
            for row in picks:
                segs = [ds.segment(int(i)) for i in row]
                batches.append(segment_batch([(s.events, s.t0_us, s.box) for s in segs],
                                             [(ds.width, ds.height)] * len(segs), rng, model.cfg))
    paths = (False,) if args.compiled_only else (False, True)
    runs = [time_steps(model, batches, reference, args.steps, args.repeat) for reference in paths]
    compare = {} if args.compiled_only else {"speedup": round(runs[1]["s_per_step"] / runs[0]["s_per_step"], 2),
                                             "same_losses": runs[0]["losses"] == runs[1]["losses"]}
    budget = {}
    if args.budget_steps is not None:
        budget = {"budget_steps": args.budget_steps,
                  "projected_minutes": round(args.budget_steps * runs[0]["s_per_step"] / 60, 2)}
    elif "train_config" in meta:
        steps = budget_steps(meta["train_config"])
        budget = {"recorded_budget_steps": steps, "recorded_batch_segments": meta["train_config"]["batch_segments"],
                  "projected_minutes": round(steps * runs[0]["s_per_step"] / 60, 2)}
        if not args.row:
            budget["recorded_minutes"] = round(meta.get("history", {}).get("minutes", float("nan")), 2)
        if args.batch_segments != meta["train_config"]["batch_segments"]:
            budget["note"] = "--batch-segments differs from the recorded budget: the projection scales a different step"
    if args.full:
        budget["full_training"] = full_training(meta, args.full, args.threads)
    print(json.dumps({"data": str(args.data or "synthetic 160x120 moving square"), "threads": args.threads,
                      "row": args.row or "the checkpoint's network",
                      "network": {"channels": model.cfg.channels, "fc": model.cfg.fc},
                      "samples_per_step": int(batches[0][0].shape[0]), "runs": runs, **compare, **budget}, indent=2))


if __name__ == "__main__":
    main()
