"""CI regression of tracking metrics: a tiny Blender-made benchmark whose A / R / ARscore are compared with a
committed reference (benchmarks/experiments/reference/ci_metrics.json) within stated tolerances.

    python -m benchmarks.experiments.regression                      # run, compare, exit 1 on a regression
    python -m benchmarks.experiments.regression --update-reference   # run and rewrite the reference (shows in the diff)

The run: `dvsot generate` renders benchmarks/experiments/reference/ci_train.yaml and ci_test.yaml (128x96,
0.3 s each); SCTN, the paper preset, is trained for a few deterministic steps on the first (one
thread, fixed seeds) and tracks the second with 64 candidates, each evaluated on its own masked
input; RCT tracks it too. The reference holds seed 0's metrics and, per metric, the spread (standard
deviation) over training seeds 0..4. The CI test runs seed 0 (deterministic) and holds it to the
reference within TOLERANCE in either direction: a drop is a regression, a rise a change to lock in by
updating the reference, so the reference always says what the code does. This command reports a
change against twice the seed spread instead (what a change of seed alone would give).

    python -m benchmarks.experiments.regression --update-reference --seeds 5   # re-baseline, spread over 5 seeds
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

REFERENCE_DIR = Path(__file__).resolve().parent / "reference"
REFERENCE = REFERENCE_DIR / "ci_metrics.json"
TOLERANCE = {"ARscore": 0.05, "A": 0.05, "R": 0.08}


def run_ci_benchmark(workdir: Path, seed: int = 0) -> dict:
    """Generate the two tiny sequences (once per workdir), train SCTN briefly with `seed`, track with sctn and rct;
    {tracker: {A, R, ARscore, segments}}."""
    import torch

    from benchmarks.evaluation.metrics import scores
    from benchmarks.evaluation.protocol import run_sequence
    from benchmarks.trackers import get_tracker
    from benchmarks.trackers.sctn import SCTNBenchTracker
    from dvsot.dataset import Dataset
    from dvsot.pipeline.generate import generate
    from dvsot.scene import load_scene
    from sctn.tracker import SCTNTracker
    from sctn.training.snn import TrainConfig, train

    torch.set_num_threads(1)
    files = {}
    for name in ("ci_train", "ci_test"):
        path = REFERENCE_DIR / f"{name}.yaml"
        files[name] = workdir / f"{name}.h5"
        if not files[name].is_file():
            generate(load_scene(path), files[name], path.read_text(), progress=False)
    cfg = TrainConfig(epochs=3, segments_per_epoch=24, batch_segments=2, lr=3e-3, seed=seed, val_every=1000,
                      val_segments=2)
    model, _ = train([files["ci_train"]], cfg, progress=False)
    sctn = SCTNBenchTracker.wrap(SCTNTracker(model, seed=seed, finetune_iters=3, n_candidates=64))
    out = {}
    with Dataset(files["ci_test"]) as ds:
        for name, tracker in (("sctn", sctn), ("rct", get_tracker("rct"))):
            res = run_sequence(tracker, ds, name)
            if res.error:
                raise RuntimeError(f"{name} crashed on the CI sequence: {res.error}")
            s = scores(res.iou)
            out[name] = {"A": round(s.accuracy, 4), "R": round(s.robustness, 4), "ARscore": round(s.arscore, 4),
                         "segments": s.segments}
    return out


def seed_spread(workdir: Path, seeds: int) -> tuple[dict, dict]:
    """Seed 0's metrics and {tracker: {metric: std over training seeds 0..seeds-1}}."""
    import numpy as np

    runs = [run_ci_benchmark(workdir, seed) for seed in range(seeds)]
    spread = {t: {m: round(float(np.std([r[t][m] for r in runs])), 4) for m in TOLERANCE} for t in runs[0]}
    return runs[0], spread


def tolerances(spread: dict | None, floor: dict = TOLERANCE) -> dict:
    """{tracker: {metric: tolerance}}: twice the seed spread, at least the floor (the floor alone without a spread)."""
    spread = spread or {}
    return {t: {m: max(f, 2 * spread.get(t, {}).get(m, 0.0)) for m, f in floor.items()}
            for t in set(spread) | {"*"}}


def compare(reference: dict, current: dict, tolerance: dict = TOLERANCE, spread: dict | None = None) -> list[str]:
    """Changes beyond tolerance in either direction (drops and rises), and trackers missing from the run."""
    problems = []
    tols = tolerances(spread, tolerance)
    for tracker, ref in reference.items():
        cur = current.get(tracker)
        if cur is None:
            problems.append(f"{tracker}: missing from this run")
            continue
        for metric, tol in tols.get(tracker, tols["*"]).items():
            if cur[metric] < ref[metric] - tol:
                problems.append(f"{tracker} {metric} {cur[metric]:.3f} < reference {ref[metric]:.3f} - {tol:.3f}")
            elif cur[metric] > ref[metric] + tol:
                problems.append(f"{tracker} {metric} {cur[metric]:.3f} > reference {ref[metric]:.3f} + {tol:.3f}: "
                                "a gain beyond the seed spread; lock it in with --update-reference")
    return problems


def main(argv: list[str] | None = None) -> int:
    """Run the CI benchmark; compare with (or rewrite) the reference."""
    parser = argparse.ArgumentParser(description="CI regression of tracking metrics")
    parser.add_argument(
        "--update-reference", action="store_true", help="rewrite benchmarks/experiments/reference/ci_metrics.json"
    )
    parser.add_argument("--seeds", type=int, default=5, help="training seeds for the spread (with --update-reference)")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="dvsot-ci-") as tmp:
        if args.update_reference:
            current, spread = seed_spread(Path(tmp), args.seeds)
        else:
            current = run_ci_benchmark(Path(tmp))
    print(json.dumps(current, indent=2))
    if args.update_reference:
        REFERENCE.write_text(json.dumps({"tolerance_floor": TOLERANCE, "seeds": args.seeds, "spread": spread,
                                         "metrics": current}, indent=2) + "\n")
        print(f"reference written: {REFERENCE}")
        return 0
    ref = json.loads(REFERENCE.read_text())
    problems = compare(ref["metrics"], current, spread=ref.get("spread"))
    for p in problems:
        print("REGRESSION: " + p, file=sys.stderr)
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
