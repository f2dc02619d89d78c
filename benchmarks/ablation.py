"""Loss ablation (paper Fig. 7A): train and evaluate SCTN with the exponential-IoU, linear-IoU and basic losses
over several seeds; print mean +- std of A, R and ARscore per loss.

    python -m benchmarks.ablation --train data/dvsot21 --test data/dvsot21 --seeds 3 --minutes 5
        [--epochs 20 --segments-per-epoch 400 --finetune-iters 10]   # the tracker's own fine-tuning
    python -m benchmarks.ablation --ci          # the two tiny CI sequences (rendered first): a quick check
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import numpy as np


def run_ablation(train_files: list[Path], test_files: list[Path], seeds: list[int], minutes: float | None,
                 epochs: int, segments_per_epoch: int, n_candidates: int, max_segments: int | None,
                 finetune_iters: int = 3, finetune_search_iters: int = 10) -> dict:
    """{loss: {"runs": [{seed, A, R, ARscore}], "mean": {...}, "std": {...}}} over the given seeds."""
    import torch

    from benchmarks.metrics import pooled
    from benchmarks.protocol import run_sequence
    from benchmarks.trackers.sctn import SCTNBenchTracker
    from dvsot.dataset import Dataset
    from sctn.tracker import SCTNTracker
    from sctn.train import TrainConfig, train

    torch.set_num_threads(2)
    out: dict = {}
    for kind in ("exp", "linear", "basic"):
        runs = []
        for seed in seeds:
            cfg = TrainConfig(epochs=epochs, segments_per_epoch=segments_per_epoch, loss=kind, seed=seed,
                              max_minutes=minutes, val_every=10**9, val_segments=2, lr=3e-3, batch_segments=2)
            model, _ = train(train_files, cfg, progress=False)
            ious = []
            for f in test_files:
                bench = SCTNBenchTracker.wrap(SCTNTracker(model, seed=seed, fast=True, finetune_iters=finetune_iters,
                                                          finetune_search_iters=finetune_search_iters,
                                                          n_candidates=n_candidates))
                with Dataset(f) as ds:
                    ious.append(run_sequence(bench, ds, "sctn", max_segments=max_segments).iou)
            s = pooled(ious)
            runs.append({"seed": seed, "A": s.accuracy, "R": s.robustness, "ARscore": s.arscore})
        keys = ("A", "R", "ARscore")
        out[kind] = {"runs": runs, "mean": {k: float(np.mean([r[k] for r in runs])) for k in keys},
                     "std": {k: float(np.std([r[k] for r in runs])) for k in keys}}
    return out


def format_ablation(result: dict) -> str:
    """Fig. 7A as text: mean +- std per loss."""
    lines = [f"{'loss':8s} {'A':>15s} {'R':>15s} {'ARscore':>15s}   seeds"]
    for kind, r in result.items():
        cells = [f"{r['mean'][k]:.3f} +- {r['std'][k]:.3f}" for k in ("A", "R", "ARscore")]
        lines.append(f"{kind:8s} " + " ".join(f"{c:>15s}" for c in cells) + f"   {len(r['runs'])}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """Command line of the ablation."""
    from dvsot.dataset import find_datasets

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--train", nargs="+", help="training files / dirs / globs (split train)")
    p.add_argument("--test", nargs="+", help="test files / dirs / globs (split test)")
    p.add_argument("--ci", action="store_true", help="use the two tiny CI scenes (rendered into a temp dir)")
    p.add_argument("--seeds", type=int, default=3)
    p.add_argument("--minutes", type=float, default=None, help="training budget per run")
    p.add_argument("--epochs", type=int, default=3)
    p.add_argument("--segments-per-epoch", type=int, default=200)
    p.add_argument("--candidates", type=int, default=256)
    p.add_argument("--max-segments", type=int, default=None)
    p.add_argument("--finetune-iters", type=int, default=3,
                   help="fine-tuning mini-batches per initialisation (the tracker's default is 10)")
    p.add_argument("--finetune-search-iters", type=int, default=10,
                   help="more mini-batches through the fast mode (forward_search)")
    p.add_argument("--out", help="also write the result as JSON here")
    a = p.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        if a.ci:
            from benchmarks.regression import REFERENCE_DIR
            from dvsot.config import load_scene
            from dvsot.generate import generate

            files = {}
            for name in ("ci_train", "ci_test"):
                scene = REFERENCE_DIR / f"{name}.yaml"
                files[name] = Path(tmp) / f"{name}.h5"
                generate(load_scene(scene), files[name], scene.read_text(), progress=False)
            train_files, test_files = [files["ci_train"]], [files["ci_test"]]
        else:
            if not (a.train and a.test):
                p.error("give --train and --test, or --ci")
            train_files, test_files = find_datasets(a.train, "train"), find_datasets(a.test, "test")
        result = run_ablation(train_files, test_files, list(range(a.seeds)), a.minutes, a.epochs,
                              a.segments_per_epoch, a.candidates, a.max_segments, a.finetune_iters,
                              a.finetune_search_iters)
    print(format_ablation(result))
    if a.out:
        Path(a.out).write_text(json.dumps(result, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
