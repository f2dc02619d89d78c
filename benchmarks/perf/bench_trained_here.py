"""Time the paper's ANN trackers trained here (goturn, siamrpn, siammask, ocean, automatch) per segment on one thread.

    python -m benchmarks.perf.bench_trained_here [--data FILE.h5] [--segments 50] [--repeat 3] [--tracker NAME ...]
        [--checkpoint NAME=CKPT ...] [--goturn-checkpoint CKPT] [--siamrpn-checkpoint CKPT]
        [--siammask-checkpoint CKPT] [--ocean-checkpoint CKPT] [--automatch-checkpoint CKPT]

Prints JSON. Timing is tracker time per segment through the benchmark interface (the ATSLTD frame, crops, the
network and the post-processing; init excluded), best of --repeat runs, one torch thread as in `dvsot bench`. Each
tracker runs on the checkpoint given for it (--checkpoint NAME=CKPT or --NAME-checkpoint CKPT), else on its
shipped one (benchmarks.trackers.trained_here.default_path) when that file is there, else on an untrained network
of its default size (seeded), which costs the same per frame as a trained one; its run then says "untrained" and
its IoU is None, since an untrained network's IoU means nothing. Without --data a synthetic 160x120 sequence (a
textured square, made in numpy) is used. Also printed: each network's MACs per frame.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from functools import partial
from pathlib import Path

import numpy as np
import torch

from dvsot.core.errors import UserError

TRACKERS = {"goturn": "benchmarks.trackers.goturn.model:GOTURN",
            "siamrpn": "benchmarks.trackers.siamrpn.model:SiamRPN",
            "siammask": "benchmarks.trackers.siammask.model:SiamMask",
            "ocean": "benchmarks.trackers.ocean.model:Ocean",
            "automatch": "benchmarks.trackers.automatch.model:AutoMatch"}


def weights_for(name: str, given: str | None) -> tuple[str | None, str]:
    """(checkpoint path or None, where the weights come from: "given", "shipped" or "untrained ...") of a tracker."""
    from benchmarks.trackers.trained_here import default_path

    if given is not None:
        return given, "given"
    shipped = default_path(name)
    if shipped.is_file():
        return str(shipped), "shipped"
    return None, f"untrained (timing only: no checkpoint given and none shipped at {shipped})"


def make_tracker(name: str, checkpoint: str | None):
    """The tracker on its checkpoint, or on an untrained network (seed 0) without one."""
    from benchmarks.trackers import get_tracker, tracker_class
    from benchmarks.training.registry import resolve

    if checkpoint is not None:
        return get_tracker(name, checkpoint=checkpoint)
    torch.manual_seed(0)
    return tracker_class(name).from_model(resolve(TRACKERS[name])().eval())


def time_tracker(name: str, checkpoint: str | None, path: Path, segments: int, repeat: int,
                 weights: str | None = None) -> dict:
    """Segments/s of one tracker on one thread (best of `repeat` runs), its MACs per frame and, on a checkpoint, its
    mean IoU without re-initialisation; `weights` says where the checkpoint came from."""
    from benchmarks.perf.bench_tracking import best_run, rates, timing_segments

    torch.set_num_threads(1)
    s0, wh, segs = timing_segments(path, segments)
    tracker, wall, cpu, ious = best_run(partial(make_tracker, name, checkpoint), s0, wh, segs, repeat)
    return {"tracker": name, "checkpoint": checkpoint or "untrained (timing only)",
            "weights": weights or ("given" if checkpoint else "untrained (timing only)"), "threads": 1,
            **rates(len(segs), wall, cpu), "mac_per_frame": tracker.energy_per_segment()["mac_ops"],
            "mean_iou_without_reinit": round(float(np.nanmean(ious)), 3) if checkpoint else None}


def given_checkpoints(args: argparse.Namespace) -> dict[str, str]:
    """Checkpoint paths by tracker from --checkpoint NAME=CKPT and --NAME-checkpoint; UserError on a bad one."""
    given = {name: getattr(args, f"{name}_checkpoint") for name in TRACKERS
             if getattr(args, f"{name}_checkpoint") is not None}
    for item in args.checkpoint:
        name, sep, ckpt = item.partition("=")
        if not sep or not ckpt:
            raise UserError(f"--checkpoint {item}: give NAME=CKPT (NAME one of {', '.join(TRACKERS)})")
        if name not in TRACKERS:
            raise UserError(f"--checkpoint {item}: '{name}' is not one of {', '.join(TRACKERS)}")
        if name in given and given[name] != ckpt:
            raise UserError(f"--checkpoint {item}: {name} is given two checkpoints ({given[name]} and {ckpt})")
        given[name] = ckpt
    for name, ckpt in given.items():
        if not Path(ckpt).is_file():
            raise UserError(f"{ckpt}: no such checkpoint (given for {name})")
    return given


def main(argv: list[str] | None = None) -> int:
    """Run the timing and print its JSON; 2 with one line on stderr for bad input."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", help="dataset file (default: a synthetic sequence)")
    parser.add_argument("--segments", type=int, default=50)
    parser.add_argument("--repeat", type=int, default=3, help="runs per tracker; the best is kept")
    parser.add_argument("--tracker", action="append", choices=list(TRACKERS),
                        help="a tracker to time (repeatable; default: all five)")
    parser.add_argument("--checkpoint", action="append", default=[], metavar="NAME=CKPT",
                        help="checkpoint of tracker NAME (repeatable; default: the shipped one, else untrained)")
    for name in TRACKERS:
        parser.add_argument(f"--{name}-checkpoint", help=f"{name} checkpoint (as --checkpoint {name}=CKPT)")
    args = parser.parse_args(argv)
    if args.segments < 1 or args.repeat < 1:
        print(f"--segments and --repeat must be at least 1 (got {args.segments} and {args.repeat})", file=sys.stderr)
        return 2
    if args.data and not Path(args.data).is_file():
        print(f"{args.data}: no such dataset file (--data)", file=sys.stderr)
        return 2
    try:
        given = given_checkpoints(args)
        names = list(dict.fromkeys(args.tracker or TRACKERS))
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(args.data) if args.data else None
            if path is None:
                sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests"))
                from synthetic import moving_square_file

                path = moving_square_file(Path(tmp) / "syn.h5", duration_ms=10 * (args.segments + 2), seed=1)
            runs = []
            for name in names:
                checkpoint, weights = weights_for(name, given.get(name))
                runs.append(time_tracker(name, checkpoint, path, args.segments, args.repeat, weights))
    except UserError as exc:  # a checkpoint or dataset file that cannot be used: nothing is printed on stdout
        print(str(exc), file=sys.stderr)
        return 2
    print(json.dumps({"data": str(args.data or "synthetic 160x120 moving square"), "runs": runs}, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
