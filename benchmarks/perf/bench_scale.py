"""Throughput of `dvsot generate --variants` on Dask LocalClusters of 1 and 2 worker processes, the scheduling
overhead per scene, and the projected cost of DVSOT21-size sequences from measured per-frame figures.

    python -m benchmarks.perf.bench_scale [--variants 8] [--workers 1 2] [--project]

For each worker count: a fresh LocalCluster renders the same tiny variants (80x60, 50 ms); run_s is the
wall time from the first submit to the last result (the cluster's start, start_s, is reported apart: it is
paid once per run); sequences per hour = variants / run_s. Scheduling overhead per scene, from the
1-worker run where tasks run one after another: (run_s - sum of task_s) / variants, task_s being each
task's own time inside its worker (imports, scene check, render, file). --project renders one variant of
blender_scenes/templates/dvsot21_random.yaml at 640x480 for 0.05 s to measure the per-sequence setup and
the seconds per frame, counts the frames of 20 drawn variants (sample times need no renderer) and prints
the cost of 1,000 such sequences on N machines.
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
TINY = """name: tiny
seed: 1
duration_s: 0.05
sensor: {width: 80, height: 60, focal_mm: 35}
camera:
  keyframes: [{t: 0, location: [0, -10, 0], look_at: [0, 0, 0]}]
target:
  shape: {choice: [cube, sphere, star]}
  size_m: {uniform: [1.2, 1.8]}
  trajectory:
    interpolation: linear
    keyframes: [{t: 0, location: [-1, 0, 0]}, {t: 0.05, location: [{uniform: [0.5, 1.5]}, 0, 0]}]
background:
  material: {texture: {type: noise, scale: 10}}
sampling: {min_rate_hz: 200}
"""


def run_cluster(template: Path, variants: int, workers: int, tmp: Path) -> dict:
    """One run of `variants` tiny variants on a new LocalCluster of `workers` processes: timing and task times."""
    from dvsot.batch import generate_many, variant_tasks

    out = tmp / f"w{workers}"
    tasks, inputs = variant_tasks(template, variants, out)
    m = generate_many(tasks, inputs, out, f"local:{workers}", retries=0)
    task_s = [r["attempts"][-1]["task_s"] for r in m.records]
    failed = [r["name"] for r in m.records if r["status"] != "done"]
    run_s = m.timing["run_s"]
    return {"workers": workers, "variants": variants, "failed": failed, "start_s": m.timing.get("start_s"),
            "run_s": run_s, "sum_task_s": round(sum(task_s), 2), "mean_task_s": round(sum(task_s) / len(task_s), 3),
            "sequences_per_hour": round(variants / run_s * 3600, 1),
            "overhead_per_scene_s": round((run_s - sum(task_s) / workers) / variants, 3)}


def project(n_sequences: int = 1000, machines: tuple = (1, 4, 16, 64), cores_per_machine: int = 2) -> dict:
    """Per-sequence cost of the shipped DVSOT21-like template from one short full-size render; the projection."""
    from dvsot.config import parse_scene
    from dvsot.generate import generate, sample_times
    from dvsot.templates import draw_variants, read_template

    tpl = read_template(ROOT / "blender_scenes" / "templates" / "dvsot21_random.yaml")
    vs = draw_variants(tpl, 20)
    frames = [len(sample_times(parse_scene(v.text("t"), "t", tpl.base_dir))) for v in vs]
    cfg = parse_scene(vs[0].text("t"), "t", tpl.base_dir, {"duration_s": 0.05, "render.threads": cores_per_machine})
    with tempfile.TemporaryDirectory() as d:
        s = generate(cfg, Path(d) / "p.h5", progress=False)
    per_frame = s["s_per_frame_after_first"]
    setup = s["wall_s"] - (s["frames"] - 1) * per_frame  # scene build, bake, first render, file
    mean_frames = sum(frames) / len(frames)
    seq_s = setup + mean_frames * per_frame  # one sequence on one machine using all its cores
    return {"mean_frames_per_sequence": round(mean_frames), "s_per_frame_640x480": per_frame,
            "setup_s": round(setup, 2), "sequence_s_one_machine": round(seq_s, 1),
            "hours_for": {f"{n_sequences} on {m} machine{'s' if m > 1 else ''}": round(n_sequences * seq_s / m / 3600, 1)
                          for m in machines}}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--variants", type=int, default=8)
    p.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    p.add_argument("--project", action="store_true", help="also project 1,000 DVSOT21-size sequences")
    a = p.parse_args()
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        template = tmp / "tiny.yaml"
        template.write_text(TINY)
        runs = [run_cluster(template, a.variants, w, tmp) for w in a.workers]
    result: dict = {"runs": runs}
    base = next((r for r in runs if r["workers"] == 1), None)
    if base:
        result["overhead_per_scene_s"] = base["overhead_per_scene_s"]
        result["speedup"] = {r["workers"]: round(r["sequences_per_hour"] / base["sequences_per_hour"], 2)
                             for r in runs}
    if a.project:
        result["projection"] = project()
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
