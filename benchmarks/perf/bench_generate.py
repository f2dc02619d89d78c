"""Time `dvsot generate` on a fixed scene; print seconds per rendered sample (scene + masks), frames per
simulated second and total wall time as JSON (and a one-line table row with --table).

    python -m benchmarks.perf.bench_generate [--scene blender_scenes/quickstart.yaml] [--duration S]
        [--resolution WxH] [--set render.surface=principled ...] [--repeat N] [--table] [--compare-labels]

s_per_frame is the wall time of BlenderScene.render per sample: one Cycles render (luma + visible mask),
the EXR read-back and the amodal mask; s_per_frame_after_first leaves out the first render, which also
builds Cycles' BVH and shaders once (first_frame_s). The event simulator and file writing are in wall_s only;
other_s = wall_s - frames x s_per_frame is the scene build (with the background bake, render.bake_background)
plus events and writing. --repeat N runs it N times and adds the min and median of s_per_frame_after_first
(the machine's speed drifts, so one run is not a figure).

--compare-labels runs generate with and without the per-event object labels (the object-index frame kept
per sample and each event labelled: dvsot.events.labels), alternating, --repeat times each, and prints the
median wall seconds per sample of both and their ratio (the labels' cost per sample), after one
uncounted warm-up run.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def _setting(text: str) -> tuple[str, object]:
    from dvsot.scene import yaml_value

    key, sep, value = text.partition("=")
    if not sep or not key:
        raise argparse.ArgumentTypeError(f"expected KEY=VALUE, got {text!r}")
    return key.strip(), yaml_value(value)


def main() -> None:
    from dvsot.pipeline.generate import generate
    from dvsot.scene import load_scene

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scene", default=str(ROOT / "blender_scenes" / "quickstart.yaml"))
    p.add_argument("--duration", type=float, default=None)
    p.add_argument("--resolution", default=None, help="WxH override")
    p.add_argument("--set", dest="settings", type=_setting, action="append", default=[], metavar="KEY=VALUE",
                   help="scene override, e.g. render.amodal_mask=render (repeatable)")
    p.add_argument("--repeat", type=int, default=1, help="runs; reports min and median s per sample over them")
    p.add_argument("--table", action="store_true", help="also print a markdown table row")
    p.add_argument("--compare-labels", action="store_true",
                   help="time generate with and without per-event labels, side by side")
    a = p.parse_args()
    overrides = dict(a.settings)
    if a.duration:
        overrides["duration_s"] = a.duration
    if a.resolution:
        w, h = (int(v) for v in a.resolution.split("x"))
        overrides.update({"sensor.width": w, "sensor.height": h})
    cfg = load_scene(a.scene, overrides)
    if a.compare_labels:
        print(json.dumps(_compare_labels(cfg, max(a.repeat, 1)), indent=2))
        return
    runs = []
    for _ in range(max(a.repeat, 1)):
        start = time.perf_counter()
        with tempfile.TemporaryDirectory() as tmp:
            summary = generate(cfg, Path(tmp) / "bench.h5", progress=False)
        summary["total_wall_s_including_import"] = round(time.perf_counter() - start, 2)
        summary["other_s"] = round(summary["wall_s"] - summary["frames"] * summary["s_per_frame"], 2)
        runs.append(summary)
    if len(runs) > 1:
        after = sorted(r["s_per_frame_after_first"] or r["s_per_frame"] for r in runs)
        summary["runs"] = len(runs)
        summary["s_per_frame_after_first_min"] = after[0]
        summary["s_per_frame_after_first_median"] = after[len(after) // 2]
    summary["settings"] = {k: v for k, v in overrides.items() if k != "duration_s"}
    summary.pop("output", None)
    print(json.dumps(summary, indent=2))
    if a.table:
        print("| scene | resolution | settings | frames | s/sample | s/sample after first | frames/sim s | wall s |")
        print("|---|---|---|---|---|---|---|---|")
        extra = ", ".join(f"{k}={v}" for k, v in summary["settings"].items()) or "default"
        print(
            f"| {summary['name']} | {summary['resolution']} | {extra} | {summary['frames']} | "
            f"{summary['s_per_frame']} | {summary['s_per_frame_after_first']} | "
            f"{summary['frames_per_simulated_s']} | {summary['wall_s']} |"
        )


def _compare_labels(cfg, repeat: int) -> dict:
    """Median wall seconds per sample with and without per-event labels (runs alternate), and their ratio."""
    from dvsot.pipeline.generate import generate

    per_sample: dict[str, list[float]] = {"labels": [], "no_labels": []}
    frames = 0
    with tempfile.TemporaryDirectory() as tmp:  # warm-up, not counted: numba's kernels, Blender's first import
        generate(cfg, Path(tmp) / "warm.h5", progress=False, labels=True)
    for _ in range(repeat):
        for key, labels in (("no_labels", False), ("labels", True)):
            with tempfile.TemporaryDirectory() as tmp:
                summary = generate(cfg, Path(tmp) / "bench.h5", progress=False, labels=labels)
            frames = summary["frames"]
            per_sample[key].append(summary["wall_s"] / frames)
    med = {k: sorted(v)[len(v) // 2] for k, v in per_sample.items()}
    return {"name": cfg.name, "resolution": f"{cfg.sensor.width}x{cfg.sensor.height}", "frames": frames,
            "runs_each": repeat, "wall_s_per_sample_no_labels": round(med["no_labels"], 4),
            "wall_s_per_sample_labels": round(med["labels"], 4),
            "labels_over_no_labels": round(med["labels"] / med["no_labels"], 3)}


if __name__ == "__main__":
    main()
