"""Time the event generator alone on 640x480 frames of a moving textured pattern; print JSON figures.

    python -m benchmarks.perf.bench_events [--frames 300] [--runs 1]

Two cases: "sparse" (a slow pattern: about 2 % of pixels fire per interval) and "dense" (a fast,
high-contrast pattern: most pixels fire several times per interval). Frames are made in numpy
beforehand, so only EventSimulator.step is timed, after one untimed interval (which loads the compiled
kernel). With --runs N each case is timed N times: the median and the range are printed. Targets on
the 2-core machine: >= 600 frame pairs/s (sparse), >= 20 M events/s (dense).
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from dvsot.events import EventParams, EventSimulator

W, H = 640, 480


def pattern(n: int, speed_px: float, contrast: float, seed: int = 0) -> list[np.ndarray]:
    """n linear-intensity frames of a textured pattern translating by speed_px pixels per frame."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float32)
    fx, fy, ph = rng.uniform(0.02, 0.12, 4), rng.uniform(0.02, 0.12, 4), rng.uniform(0, 6.3, 4)
    frames = []
    for i in range(n):
        x = xx - speed_px * i
        v = sum(np.sin(fx[k] * x + ph[k]) * np.cos(fy[k] * yy + ph[k]) for k in range(4)) / 4
        frames.append(np.exp(contrast * v).astype(np.float32) * 0.2)
    return frames


def time_case(frames: list[np.ndarray], params: EventParams, dt_us: int) -> dict:
    """One timed pass of EventSimulator.step over the frames (after an untimed warm-up interval)."""
    warm = EventSimulator(W, H, params, seed=0)
    warm.step(frames[0], 0)
    warm.step(frames[1], dt_us)
    sim = EventSimulator(W, H, params, seed=0)
    sim.step(frames[0], 0)
    events, fired = 0, []
    start, cpu = time.perf_counter(), time.process_time()
    for i, frame in enumerate(frames[1:], start=1):
        batch = sim.step(frame, i * dt_us)
        events += len(batch)
        fired.append(batch.y.astype(np.int64) * W + batch.x)
    wall, cpu = time.perf_counter() - start, time.process_time() - cpu
    pairs = len(frames) - 1
    fired = sum(np.unique(f).size for f in fired) / pairs  # outside the timed loop
    return {
        "frame_pairs": pairs,
        "wall_s": round(wall, 3),
        "frame_pairs_per_s": round(pairs / wall, 1),
        "events": events,
        "events_per_s": round(events / wall),
        # CPU time of this process: what a loaded machine's other work does not inflate as much
        "cpu_s": round(cpu, 3),
        "frame_pairs_per_cpu_s": round(pairs / cpu, 1),
        "events_per_cpu_s": round(events / cpu),
        "events_per_pair": round(events / pairs),
        "fired_pixel_fraction": round(fired / (W * H), 4),
    }


def repeated(frames: list[np.ndarray], params: EventParams, dt_us: int, runs: int) -> dict:
    """time_case run `runs` times: the median run's figures, and the range of the rates."""
    results = sorted((time_case(frames, params, dt_us) for _ in range(runs)), key=lambda r: r["wall_s"])
    out = dict(results[len(results) // 2])
    if runs > 1:
        for key in ("frame_pairs_per_s", "events_per_s"):
            out[key + "_range"] = [results[-1][key], results[0][key]]
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=300)
    parser.add_argument("--runs", type=int, default=1, help="timed runs per case (median and range printed)")
    args = parser.parse_args()
    params = EventParams(cp=0.2, cn=0.2, sigma_cp=0.03, sigma_cn=0.03, refractory_us=0)
    dense = pattern(args.frames // 3, 6.0, 4.0)
    result = {
        "resolution": f"{W}x{H}",
        "sparse": repeated(pattern(args.frames, 0.6, 1.0), params, 1_000, args.runs),
        "dense": repeated(dense, params, 1_000, args.runs),
        "dense_refractory_100us": repeated(dense, params.model_copy(update={"refractory_us": 100}), 1_000,
                                           args.runs),
    }
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
