"""Time SCTN tracking (fast mode with nearest-cell and bilinear crops, paper-faithful mode) and count
its synaptic operations; print JSON.

    python -m benchmarks.perf.bench_tracking [--data FILE.h5] [--checkpoint CKPT] [--segments 50] [--repeat 3]
        [--fast-only] [--ann | --ann-only] [--twin-checkpoint CKPT] [--siamfc-checkpoint CKPT]
    python -m benchmarks.perf.bench_tracking --sequences FILE.h5 [FILE.h5 ...] [--checkpoint CKPT] [--drop-biases]
        [--segments 50]

--sequences times, per file on one thread, the paper's per-candidate evaluation twice (the dense path:
encode_boxes and the whole network per candidate; the event-driven path, sctn/sparse/evaluate.py, which
SCTNTracker uses when it is exact) and the fast mode, and checks that both per-candidate runs track
the same boxes. --drop-biases evaluates the checkpoint's weights without its biases and tail steps (a
stand-in for a paper-preset checkpoint, for timing).

Without --data a synthetic 160x120 sequence (a textured square, made in numpy) is used. Timing is
tracker time per segment (scoring the candidates), fine-tuning excluded; one torch thread per
process as in `dvsot bench`, plus a two-thread run. This machine's speed drifts by tens of percent
between runs, so each fast-mode figure is the best of --repeat runs (the faithful mode runs once).
--ann adds the ANN trackers (sctn_ann: SCTN's ANN twin, per candidate; siamfc: per frame) on one thread,
timed the same way through the benchmark interface (init excluded); --ann-only runs only them.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from collections.abc import Callable
from functools import partial
from pathlib import Path

import numpy as np
import torch


def dense_scoring_tracker():
    """SCTNTracker whose per-candidate scores come from the dense path (the code before the event-driven one)."""
    from sctn.sparse.evaluate import dense_candidate_voltages
    from sctn.tracker import SCTNTracker

    class DenseTracker(SCTNTracker):
        def score(self, events, t0_us, boxes):
            if self.fast:
                return super().score(events, t0_us, boxes)
            self.candidate_path = "dense"
            return dense_candidate_voltages(self.model, events, t0_us, boxes)[:, :, 1].max(dim=1).values.numpy()

    return DenseTracker


def bias_free(model):
    """A copy of an SCTN with its weights and time constants, no biases and no tail steps."""
    from sctn.network import SCTN

    update = {"tail_steps": 0}
    if "bias" in type(model.cfg).model_fields:
        update["bias"] = False
    net = SCTN(model.cfg.model_copy(update=update))
    net.load_state_dict({k: v for k, v in model.state_dict().items() if not k.endswith(".bias")}, strict=False)
    with torch.no_grad():
        for layer in list(net.convs) + list(net.fcs):
            if layer.bias is not None:
                layer.bias.zero_()
    return net.eval()


def timing_segments(path: Path, segments: int) -> tuple:
    """(first segment with a ground-truth box, sensor (width, height), the up to `segments` segments after it) of
    a dataset file: what a timing run initialises on and tracks."""
    from dvsot.dataset import Dataset

    with Dataset(path) as ds:
        first = next(i for i, b in enumerate(ds.segment_boxes()) if np.isfinite(b).all())
        return ds.segment(first), (ds.width, ds.height), list(ds.segments(first + 1, first + 1 + segments))


def best_run(make: Callable[[], object], s0, wh: tuple[int, int], segs: list, repeat: int) -> tuple:
    """(tracker, wall s, CPU s, IoU per segment) of the fastest (wall time) of `repeat` runs of a benchmark tracker
    `make()`: init on s0's box, then an update per segment of segs."""
    from dvsot.dataset.boxes import iou_xywh

    best = None
    for _ in range(repeat):
        tracker = make()
        tracker.init(s0, s0.box.copy(), *wh)
        start, cpu = time.perf_counter(), time.process_time()
        ious = [float(iou_xywh(tracker.update(s), s.box)) for s in segs]
        wall, cpu = time.perf_counter() - start, time.process_time() - cpu
        if best is None or wall < best[1]:
            best = (tracker, wall, cpu, ious)
    return best


def rates(n: int, wall: float, cpu: float) -> dict:
    """Segments, segments/s, wall and CPU ms per segment of n segments tracked in wall (and cpu) seconds."""
    return {"segments": n, "segments_per_s": round(n / wall, 2), "ms_per_segment": round(1000 * wall / n, 2),
            "cpu_ms_per_segment": round(1000 * cpu / n, 2)}


def time_mode(model, path: Path, fast: bool, segments: int, threads: int, crop: str = "bilinear",
              repeat: int = 1, tracker_cls=None, boxes_out: list | None = None) -> dict:
    from dvsot.dataset.boxes import iou_xywh
    from sctn.tracker import SCTNTracker

    tracker_cls = tracker_cls or SCTNTracker

    torch.set_num_threads(threads)
    s0, wh, segs = timing_segments(path, segments)
    best = None
    for _ in range(repeat):
        tracker = tracker_cls(model, seed=0, fast=fast, finetune_iters=0, crop=crop)
        tracker.init(s0.events, s0.t0_us, s0.box, *wh)
        start, cpu = time.perf_counter(), time.process_time()
        tracked = [tracker.track(s.events, s.t0_us) for s in segs]
        wall, cpu = time.perf_counter() - start, time.process_time() - cpu
        ious = [float(iou_xywh(b, s.box)) for b, s in zip(tracked, segs)]
        if boxes_out is not None:
            boxes_out[:] = tracked
        if best is None or wall < best[0]:
            best = (wall, cpu)
    wall, cpu = best
    # cpu seconds show the cost when the machine is shared (wall time then overstates it)
    path_used = getattr(tracker, "candidate_path", None) if not fast else None
    return {"fast": fast, "crop": crop if fast else None, "per_candidate": path_used, "threads": threads,
            **rates(len(segs), wall, cpu), "mean_iou_without_reinit": round(float(np.nanmean(ious)), 3)}


def time_ann_trackers(path: Path, segments: int, repeat: int, twin_checkpoint: str | None = None,
                      siamfc_checkpoint: str | None = None) -> list[dict]:
    """Segments/s of sctn_ann and siamfc on one thread (best of `repeat` runs; init, i.e. fine-tuning, excluded)."""
    from benchmarks.trackers import get_tracker

    torch.set_num_threads(1)
    s0, wh, segs = timing_segments(path, segments)
    runs = []
    for name, ckpt in (("sctn_ann", twin_checkpoint), ("siamfc", siamfc_checkpoint)):
        make = partial(get_tracker, name, checkpoint=ckpt, **({"energy_every": 0} if name == "sctn_ann" else {}))
        _, wall, cpu, ious = best_run(make, s0, wh, segs, repeat)
        runs.append({"tracker": name, "threads": 1, **rates(len(segs), wall, cpu),
                     "mean_iou_without_reinit": round(float(np.nanmean(ious)), 3)})
    return runs


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", help="dataset file (default: a synthetic sequence)")
    parser.add_argument("--checkpoint", help="SCTN checkpoint (default: the shipped one)")
    parser.add_argument("--segments", type=int, default=50)
    parser.add_argument("--repeat", type=int, default=3, help="fast-mode runs per setting; the best is kept")
    parser.add_argument("--fast-only", action="store_true", help="skip the paper-faithful mode (~1 segment/s)")
    parser.add_argument("--sequences", nargs="+", help="per file: per-candidate dense vs event-driven, and fast mode")
    parser.add_argument("--drop-biases", action="store_true", help="evaluate the checkpoint without biases/tail steps")
    parser.add_argument("--ann", action="store_true", help="also time sctn_ann and siamfc (one thread)")
    parser.add_argument("--ann-only", action="store_true", help="time only sctn_ann and siamfc")
    parser.add_argument("--twin-checkpoint", help="sctn_ann checkpoint (default: the shipped one)")
    parser.add_argument("--siamfc-checkpoint", help="siamfc checkpoint (default: the shipped one)")
    args = parser.parse_args()
    if args.ann_only and not args.sequences:
        print(json.dumps({"data": str(args.data or "synthetic 160x120 moving square"), "ann_runs": _ann_runs(args)},
                         indent=2))
        return
    if args.ann_only:  # per sequence
        print(json.dumps({Path(f).stem: time_ann_trackers(Path(f), args.segments, args.repeat, args.twin_checkpoint,
                                                          args.siamfc_checkpoint) for f in args.sequences}, indent=2))
        return
    ann = _ann_runs(args) if args.ann and not args.sequences else None
    from sctn.checkpoint import load_checkpoint
    from sctn.encoding import encode_boxes, encode_search
    from sctn.energy import count_search_ops, count_synaptic_ops
    from sctn.samples import TRACK, propose

    model, _ = load_checkpoint(args.checkpoint)
    if args.drop_biases:
        model = bias_free(model)
    if args.sequences:
        result = per_sequence(model, [Path(p) for p in args.sequences], args.segments)
        if args.ann:  # the ANN trackers on the same files, beside SCTN's rows
            result["ann"] = {Path(f).stem: time_ann_trackers(Path(f), args.segments, 1, args.twin_checkpoint,
                                                             args.siamfc_checkpoint) for f in args.sequences}
        print(json.dumps(result, indent=2))
        return
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(args.data) if args.data else None
        if path is None:
            sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests"))
            from synthetic import moving_square_file

            path = moving_square_file(Path(tmp) / "syn.h5", duration_ms=10 * (args.segments + 2), seed=1)
        runs = [time_mode(model, path, True, args.segments, threads, crop, args.repeat)
                for crop in ("bilinear", "nearest") for threads in (1, 2)]
        if not args.fast_only:
            runs += [time_mode(model, path, False, args.segments, threads) for threads in (1, 2)]
        from dvsot.dataset import Dataset

        with Dataset(path) as ds:
            seg = ds.segment(len(ds.segment_boxes()) // 2)
            wh = (ds.width, ds.height)
        cfg = model.cfg
        x = encode_boxes(seg.events, seg.t0_us, seg.box[None], cfg)
        ops = count_synaptic_ops(model, x)["ac_ops_per_sample"]
        boxes = propose(np.random.default_rng(0), seg.box.astype(np.float64), TRACK.n, "gaussian", TRACK.trans,
                        TRACK.scale, wh)
        inputs = encode_search(seg.events, seg.t0_us, boxes, seg.box, cfg)
        search = {crop: count_search_ops(model, *inputs, crop=crop) for crop in ("nearest", "bilinear")}
    print(json.dumps({"data": str(args.data or "synthetic 160x120 moving square"),
                      "network": {"channels": cfg.channels, "fc": cfg.fc}, "runs": runs,
                      "faithful_ac_ops_per_candidate": ops, "faithful_ac_ops_per_segment": ops * TRACK.n,
                      "fast_search_per_segment": {crop: {k: ops[k] for k in ("ac_ops", "mac_ops", "energy_pj")}
                                                  for crop, ops in search.items()},
                      **({"ann_runs": ann} if args.ann else {})},
                     indent=2))


def per_sequence(model, paths: list[Path], segments: int) -> dict:
    """Segments/s on one thread per file: per candidate (dense path, event-driven path) and fast mode."""
    from sctn.sparse.evaluate import exact_blocker

    rows = []
    for fast, cls in ((False, dense_scoring_tracker()), (False, None), (True, None)):  # compile / load numba code
        time_mode(model, paths[0], fast, 2, 1, tracker_cls=cls)
    for path in paths:
        dense_boxes: list = []
        sparse_boxes: list = []
        dense = time_mode(model, path, False, segments, 1, tracker_cls=dense_scoring_tracker(), boxes_out=dense_boxes)
        sparse = time_mode(model, path, False, segments, 1, boxes_out=sparse_boxes)
        fast = time_mode(model, path, True, segments, 1)
        rows.append({"sequence": path.stem, "segments": dense["segments"],
                     "per_candidate_dense_segments_per_s": dense["segments_per_s"],
                     "per_candidate_event_driven_segments_per_s": sparse["segments_per_s"],
                     "speed_up": round(sparse["segments_per_s"] / dense["segments_per_s"], 1),
                     "cpu_ms_per_segment_dense_vs_event_driven": [dense["cpu_ms_per_segment"],
                                                                  sparse["cpu_ms_per_segment"]],
                     "fast_bilinear_segments_per_s": fast["segments_per_s"],
                     "same_boxes": bool(np.array_equal(np.array(dense_boxes), np.array(sparse_boxes))),
                     "event_driven_path": sparse["per_candidate"],
                     "mean_iou_without_reinit": sparse["mean_iou_without_reinit"],
                     "per_candidate_ac_ops_per_segment": segment_ops(model, path)})
    return {"threads": 1, "exact_blocker": exact_blocker(model), "sequences": rows}


def _ann_runs(args: argparse.Namespace) -> list[dict]:
    """time_ann_trackers on --data (or the synthetic sequence)."""
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(args.data) if args.data else None
        if path is None:
            sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests"))
            from synthetic import moving_square_file

            path = moving_square_file(Path(tmp) / "syn.h5", duration_ms=10 * (args.segments + 2), seed=1)
        return time_ann_trackers(path, args.segments, args.repeat, args.twin_checkpoint, args.siamfc_checkpoint)


def segment_ops(model, path: Path, segments: int = 8) -> float | None:
    """Mean ACs per segment of the paper's evaluation (256 gaussian candidates around the true box, each on its own
    masked canvas), over `segments` labelled segments spread over the file; None if the model is not exact there."""
    from dvsot.dataset import Dataset
    from sctn.samples import TRACK, propose
    from sctn.sparse.evaluate import candidate_record, exact_blocker

    if exact_blocker(model) is not None:
        return None
    totals = []
    with Dataset(path) as ds:
        labelled = np.flatnonzero(np.isfinite(ds.segment_boxes()).all(axis=1))
        for i in labelled[np.linspace(0, len(labelled) - 1, segments).astype(int)]:
            seg = ds.segment(int(i))
            boxes = propose(np.random.default_rng(int(i)), seg.box.astype(np.float64), TRACK.n, "gaussian",
                            TRACK.trans, TRACK.scale, (ds.width, ds.height))
            _, rec = candidate_record(model, seg.events, seg.t0_us, boxes)
            totals.append(sum(float(ops.sum()) for ops in rec["ac_ops"].values()))
    return float(np.mean(totals))


if __name__ == "__main__":
    main()
