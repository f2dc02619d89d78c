"""A tracker's result depends on the sequence alone: run twice in one worker after every other tracker (as `bench
--jobs N` does) it gives, box for box, what it gives alone in a fresh worker (OpenCV's MIL drew its features from
the process's rand(), whose state the trackers before it had moved)."""

import sys
from concurrent.futures import ProcessPoolExecutor
from contextlib import ExitStack
from multiprocessing import get_context
from pathlib import Path

import numpy as np
import pytest

from benchmarks.trackers import BUILTIN

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from synthetic import moving_square_file  # noqa: E402

SEGMENTS = 8
LIGHT = {"finetune_iters": 2, "n_candidates": 16, "energy_every": 0}  # SCTN-like trackers, kept quick
TRACKERS = {"mil": {}, "csrt": {}, "kcf": {}, "rct": {}, "siamfc": {}, "sctn": {**LIGHT, "finetune_search_iters": 0},
            "sctn_ann": LIGHT, "goturn": {}, "siamrpn": {}, "siammask": {}, "ocean": {}, "automatch": {}}
UNTRAINED = {"goturn": "benchmarks.trackers.goturn.model:GOTURN",
             "siamrpn": "benchmarks.trackers.siamrpn.model:SiamRPN",
             "siammask": "benchmarks.trackers.siammask.model:SiamMask",
             "ocean": "benchmarks.trackers.ocean.model:Ocean",
             "automatch": "benchmarks.trackers.automatch.model:AutoMatch"}  # they ship no checkpoint


def run_in_order(order: list[str], path: str, options: dict | None = None) -> list[tuple[str, np.ndarray, str | None]]:
    """(tracker, predicted boxes, error) of each tracker of `order` run in turn on `path` in this process (options
    beside TRACKERS': the untrained checkpoints)."""
    from benchmarks.evaluation.runner import run_one

    out = []
    for name in order:
        r = run_one(name, path, max_segments=SEGMENTS, options={**TRACKERS[name], **(options or {}).get(name, {})})
        out.append((name, r.predictions, r.error))
    return out


@pytest.fixture(scope="module")
def sequence(tmp_path_factory) -> str:
    """A moving square (96x72 px, 16 px, 12 segments) that every tracker loses and re-finds now and then."""
    d = tmp_path_factory.mktemp("history")
    return str(moving_square_file(d / "sq.h5", width=96, height=72, size=16, duration_ms=120,
                                  velocity_px_s=(300.0, 120.0), start=(10.0, 10.0)))


def test_every_built_in_tracker_is_checked():
    assert sorted(TRACKERS) == sorted(BUILTIN)


@pytest.fixture(scope="module")
def untrained(tmp_path_factory) -> dict:
    """{tracker: {"checkpoint": path}} of an untrained network (seeded) for each tracker of UNTRAINED."""
    import torch

    from benchmarks.training.registry import resolve
    from sctn.checkpoint import save_checkpoint

    d = tmp_path_factory.mktemp("untrained")
    out = {}
    for name, net in UNTRAINED.items():
        torch.manual_seed(0)
        out[name] = {"checkpoint": str(save_checkpoint(d / f"{name}.pt", resolve(net)(), {}, kind=name))}
    return out


@pytest.mark.parametrize("names", [["mil", "csrt", "kcf", "rct"], ["siamfc", "sctn", "sctn_ann"],
                                   ["goturn", "siamrpn", "siammask"], ["ocean", "automatch"]],
                         ids=["opencv-rct", "torch", "trained-here", "anchor-free"])
def test_every_tracker_gives_the_same_boxes_twice_in_one_worker_and_alone(sequence, untrained, names):
    with ExitStack() as stack:
        spawn = get_context("spawn")
        pools = [stack.enter_context(ProcessPoolExecutor(1, mp_context=spawn)) for _ in names]
        # each twice, after all the others; the first tracker's first run is its run alone in a fresh worker
        shared = pools[0].submit(run_in_order, names + names[::-1], sequence, untrained)
        alone = {n: p.submit(run_in_order, [n], sequence, untrained)
                 for n, p in zip(names[1:], pools[1:])}  # a fresh worker each
        runs = shared.result(timeout=600)
        first = {names[0]: runs[0], **{n: f.result(timeout=600)[0] for n, f in alone.items()}}
    for name, boxes, error in runs:
        assert error is None and first[name][2] is None, (name, error, first[name][2])
        np.testing.assert_array_equal(boxes, first[name][1], err_msg=f"{name}: other boxes after other trackers")
