"""Time EventSimulator.step in-process per sensor preset, side by side across checkouts; print JSON figures.

    python -m benchmarks.perf.bench_sensor [--preset ideal --preset davis346] [--blur 13 --blur 5]
        [--frames 58] [--runs 3] [--tree DIR ...]

Input: 640x480 8-bit frames (CodedFrames, as `dvsot simulate` hands decoded images to the simulator) of a
uniform noise texture box-blurred over --blur pixels both ways, shifted one pixel a frame at 1 kHz; a
wider blur gives fewer events (13: about 3,000 a frame under davis346, below its 12 Meps readout; 5: about
64,000 a frame, most dropped by the readout). Every (tree, preset, blur) runs in its own process, the
variants in turn each round (a loaded machine's drift hits them alike), after an untimed pass that loads
the compiled kernels. Printed per variant: the median over the rounds and the range of CPU milliseconds a
frame, over all frames (the simulator made, the first frame's set-up included) and over the frames after
the second (steady state); the events and a digest of them (x, y, t, p, signal flags, noise kinds), which
agree between trees whose events are the same.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

_CHILD = """
import hashlib, json, sys, time
import numpy as np
from dvsot.events import CodedFrame, EventParams, EventSimulator, log_intensity

preset, blur, n = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
W, H = 640, 480
rng = np.random.default_rng(5)
tex = rng.integers(0, 256, size=(H, W + n)).astype(np.float32)
box = np.ones(blur, np.float32) / blur
tex = np.apply_along_axis(lambda r: np.convolve(r, box, "same"), 1, tex)
tex = np.apply_along_axis(lambda c: np.convolve(c, box, "same"), 0, tex)
tex = (tex - tex.min()) / (tex.max() - tex.min()) * 230 + 10
table = log_intensity(np.arange(256, dtype=np.float32).reshape(1, -1) / 255.0, 1e-3)
frames = [CodedFrame(np.ascontiguousarray(tex[:, i:i + W]).astype(np.uint8), table) for i in range(n)]
times = [1000 * i for i in range(n)]

def once():
    c0 = time.process_time()
    sim = EventSimulator(W, H, EventParams(preset=preset), 1)
    out, c2 = [], None
    for k, (f, t) in enumerate(zip(frames, times)):
        if k == 2:
            c2 = time.process_time()
        out.append(sim.step(f, t))
    c1 = time.process_time()
    return c1 - c0, c1 - c2, out

once()  # loads the compiled kernels
whole, steady, out = once()
h = hashlib.sha256()
for b in out:
    for col in (b.x, b.y, b.t, b.p, b.signal, b.noise_kind):
        if col is not None:
            h.update(np.ascontiguousarray(col).tobytes())
print(json.dumps({"ms": 1e3 * whole / n, "steady_ms": 1e3 * steady / (n - 2), "events": sum(len(b) for b in out),
                  "digest": h.hexdigest()[:16]}))
"""


def _tree_env(tree: str) -> dict[str, str]:
    """This environment with the checkout `tree` (if any) first on PYTHONPATH."""
    env = dict(os.environ)
    if tree:
        env["PYTHONPATH"] = os.pathsep.join(p for p in (str(Path(tree).resolve()), env.get("PYTHONPATH")) if p)
    return env


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--preset", action="append", default=[], help="sensor preset (repeatable; default ideal "
                        "and davis346)")
    parser.add_argument("--blur", action="append", type=int, default=[], help="box blur of the texture, pixels "
                        "(repeatable; default 13 and 5)")
    parser.add_argument("--frames", type=int, default=58, help="frames a run (at least 3)")
    parser.add_argument("--runs", type=int, default=3, help="rounds; each runs every variant once")
    parser.add_argument("--tree", action="append", default=[], help="a dvsot checkout to time (repeatable)")
    args = parser.parse_args()
    if args.frames < 3 or args.runs < 1:
        parser.error("--frames must be >= 3 and --runs >= 1")
    presets, blurs, trees = args.preset or ["ideal", "davis346"], args.blur or [13, 5], args.tree or [""]
    runs: dict[str, list[dict]] = {}
    with tempfile.TemporaryDirectory() as where:  # not inside a checkout: its dvsot would shadow the tree's
        for _ in range(args.runs):
            for blur in blurs:
                for tree in trees:
                    for preset in presets:
                        name = f"{tree or 'dvsot'}[{preset}, blur {blur}]"
                        done = subprocess.run([sys.executable, "-c", _CHILD, preset, str(blur), str(args.frames)],
                                              env=_tree_env(tree), cwd=where, capture_output=True, text=True)
                        if done.returncode != 0:
                            raise SystemExit(f"{name} failed: {done.stderr.strip()[-400:]}")
                        runs.setdefault(name, []).append(json.loads(done.stdout.strip().splitlines()[-1]))
    print(
        json.dumps({"frames": args.frames, "runs": args.runs, "load_average": [round(v, 2) for v in os.getloadavg()]})
    )
    for name, rs in runs.items():  # one line a variant
        print(json.dumps({name: {"cpu_ms_per_frame": round(statistics.median(r["ms"] for r in rs), 2),
                                 "range": [round(min(r["ms"] for r in rs), 2), round(max(r["ms"] for r in rs), 2)],
                                 "steady_cpu_ms_per_frame": round(statistics.median(r["steady_ms"] for r in rs), 2),
                                 "events": rs[0]["events"], "digest": rs[0]["digest"]}}))


if __name__ == "__main__":
    main()
