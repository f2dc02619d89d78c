"""Time the paper's ANN trackers trained here (goturn, siamrpn, siammask) per segment on one thread; print JSON.

    python -m benchmarks.perf.bench_trained_here [--data FILE.h5] [--segments 50] [--repeat 3]
        [--goturn-checkpoint CKPT] [--siamrpn-checkpoint CKPT] [--siammask-checkpoint CKPT]

Timing is tracker time per segment through the benchmark interface (the ATSLTD frame, crops, the network and the
post-processing; init excluded), best of --repeat runs, one torch thread as in `dvsot bench`. No checkpoint of
these ships: a tracker without one runs on an untrained network of its default size (seeded), which costs the
same per frame as a trained one; its IoU is then meaningless and reported as None. Without --data a synthetic
160x120 sequence (a textured square, made in numpy) is used. Also printed: each network's MACs per frame.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import torch

TRACKERS = {"goturn": "benchmarks.trackers.goturn.model:GOTURN",
            "siamrpn": "benchmarks.trackers.siamrpn.model:SiamRPN",
            "siammask": "benchmarks.trackers.siammask.model:SiamMask"}


def make_tracker(name: str, checkpoint: str | None):
    """The tracker on its checkpoint, or on an untrained network (seed 0) without one."""
    from benchmarks.trackers import get_tracker, tracker_class
    from benchmarks.training.registry import resolve

    if checkpoint is not None:
        return get_tracker(name, checkpoint=checkpoint)
    torch.manual_seed(0)
    return tracker_class(name).from_model(resolve(TRACKERS[name])().eval())


def time_tracker(name: str, checkpoint: str | None, path: Path, segments: int, repeat: int) -> dict:
    """Segments/s of one tracker on one thread (best of `repeat` runs) and its MACs per frame."""
    from dvsot.dataset import Dataset
    from dvsot.dataset.boxes import iou_xywh

    torch.set_num_threads(1)
    with Dataset(path) as ds:
        first = next(i for i, b in enumerate(ds.segment_boxes()) if np.isfinite(b).all())
        s0, wh = ds.segment(first), (ds.width, ds.height)
        segs = list(ds.segments(first + 1, first + 1 + segments))
    best = None
    for _ in range(repeat):
        tracker = make_tracker(name, checkpoint)
        tracker.init(s0, s0.box.copy(), *wh)
        start, cpu = time.perf_counter(), time.process_time()
        ious = [float(iou_xywh(tracker.update(s), s.box)) for s in segs]
        wall, cpu = time.perf_counter() - start, time.process_time() - cpu
        if best is None or wall < best[0]:
            best = (wall, cpu, ious)
    wall, cpu, ious = best
    return {"tracker": name, "checkpoint": checkpoint or "untrained (timing only)", "threads": 1,
            "segments": len(segs), "segments_per_s": round(len(segs) / wall, 2),
            "ms_per_segment": round(1000 * wall / len(segs), 2), "cpu_ms_per_segment": round(1000 * cpu / len(segs), 2),
            "mac_per_frame": tracker.energy_per_segment()["mac_ops"],
            "mean_iou_without_reinit": round(float(np.nanmean(ious)), 3) if checkpoint else None}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", help="dataset file (default: a synthetic sequence)")
    parser.add_argument("--segments", type=int, default=50)
    parser.add_argument("--repeat", type=int, default=3, help="runs per tracker; the best is kept")
    for name in TRACKERS:
        parser.add_argument(f"--{name}-checkpoint", help=f"{name} checkpoint (default: an untrained network)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(args.data) if args.data else None
        if path is None:
            sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests"))
            from synthetic import moving_square_file

            path = moving_square_file(Path(tmp) / "syn.h5", duration_ms=10 * (args.segments + 2), seed=1)
        runs = [time_tracker(name, getattr(args, f"{name}_checkpoint"), path, args.segments, args.repeat)
                for name in TRACKERS]
    print(json.dumps({"data": str(args.data or "synthetic 160x120 moving square"), "runs": runs}, indent=2))


if __name__ == "__main__":
    main()
