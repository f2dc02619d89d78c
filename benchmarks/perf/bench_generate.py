"""Time `dvsot generate` on a fixed scene; print seconds per rendered sample (scene + masks), frames per
simulated second and total wall time as JSON.

    python -m benchmarks.perf.bench_generate [--scene blender_scenes/quickstart.yaml] [--duration S] [--resolution WxH]
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def main() -> None:
    from dvsot.config import load_scene
    from dvsot.generate import generate

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scene", default=str(ROOT / "blender_scenes" / "quickstart.yaml"))
    p.add_argument("--duration", type=float, default=None)
    p.add_argument("--resolution", default=None, help="WxH override")
    a = p.parse_args()
    overrides = {}
    if a.duration:
        overrides["duration_s"] = a.duration
    if a.resolution:
        w, h = (int(v) for v in a.resolution.split("x"))
        overrides.update({"sensor.width": w, "sensor.height": h})
    cfg = load_scene(a.scene, overrides)
    start = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        summary = generate(cfg, Path(tmp) / "bench.h5", progress=False)
    summary["total_wall_s_including_import"] = round(time.perf_counter() - start, 2)
    summary.pop("output", None)
    print(json.dumps(summary, indent=2))


if __name__ == "__main__":
    main()
