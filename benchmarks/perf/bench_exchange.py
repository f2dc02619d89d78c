"""Export and import speed of every event format on a synthetic dataset file; print events/s both ways.

    python -m benchmarks.perf.bench_exchange [--events 10000000]

A dataset file of random events (640x480, 10 s, one box track) is written to a temporary directory,
then for each format `dvsot.interop.event_files.export_dataset` (dataset file -> OUT + OUT.boxes.csv) and
`dvsot.interop.recordings.import_recording` (OUT -> a new dataset file) are timed once each, wall clock and
CPU time of the process (all its threads; on a loaded machine the CPU time is the steadier figure),
including reading and writing the files. Each exported file is deleted before the next.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from dvsot.dataset import DatasetWriter
from dvsot.events import EventBatch
from dvsot.interop.event_files import boxes_path, export_dataset
from dvsot.interop.recordings import import_recording

W, H = 640, 480
FORMATS = [("aedat4", "evt3"), ("raw", "evt2"), ("raw", "evt3"), ("dat", "evt3"), ("csv", "evt3"), ("txt", "evt3")]


def make_dataset(path: Path, n: int, duration_us: int = 10_000_000) -> None:
    """A dataset file of n uniformly random events over duration_us and a box track every 10 ms."""
    rng = np.random.default_rng(0)
    with DatasetWriter(path, W, H) as w:
        step = 1 << 20
        t = np.sort(rng.integers(0, duration_us, n))
        for i in range(0, n, step):
            m = len(t[i:i + step])
            w.append_events(EventBatch(rng.integers(0, W, m).astype(np.uint16), rng.integers(0, H, m).astype(np.uint16),
                                       t[i:i + step], rng.integers(0, 2, m).astype(np.uint8)))
        bt = np.arange(0, duration_us + 1, 10_000)
        w.append_boxes(bt, np.tile([100.0, 100.0, 50.0, 40.0], (len(bt), 1)))
        w.close(duration_us)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--events", type=int, default=10_000_000)
    args = parser.parse_args()
    n = args.events
    print("| format | file MB | export s (CPU s) | export Mev/s | import s (CPU s) | import Mev/s |")
    print("|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory(prefix="dvsot-exchange-") as tmp:
        src = Path(tmp) / "src.h5"
        make_dataset(src, n)
        for suffix, evt in FORMATS:
            out = Path(tmp) / f"seq.{suffix}"
            start, cpu = time.perf_counter(), time.process_time()
            export_dataset(src, out, evt_version=evt)
            exp, exp_cpu = time.perf_counter() - start, time.process_time() - cpu
            size = out.stat().st_size
            back = Path(tmp) / "back.h5"
            start, cpu = time.perf_counter(), time.process_time()
            import_recording(out, back, boxes=boxes_path(out), size=(W, H), evt_version=evt, interpolate=True)
            imp, imp_cpu = time.perf_counter() - start, time.process_time() - cpu
            name = f"{suffix} ({evt.upper()})" if suffix == "raw" else suffix
            print(f"| {name} | {size / 1e6:.1f} | {exp:.2f} ({exp_cpu:.2f}) | {n / exp / 1e6:.1f} | {imp:.2f} "
                  f"({imp_cpu:.2f}) | {n / imp / 1e6:.1f} |", flush=True)
            for p in (out, boxes_path(out), back):
                p.unlink(missing_ok=True)


if __name__ == "__main__":
    main()
