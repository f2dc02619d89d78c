"""Every built-in tracker runs the streaming protocol: windows ending anywhere, of any length."""

import numpy as np
import pytest

from benchmarks.evaluation.latency import LatencyModel
from benchmarks.evaluation.stream import run_stream
from benchmarks.trackers import get_tracker
from dvsot.dataset import Dataset
from tests.synthetic import moving_square_file

SMALL = {"sctn": {"finetune_iters": 0, "finetune_search_iters": 0, "n_candidates": 16, "energy_every": 1},
         "sctn_ann": {"finetune_iters": 0, "n_candidates": 16, "energy_every": 1}}


@pytest.fixture(scope="module")
def square(tmp_path_factory):
    return moving_square_file(tmp_path_factory.mktemp("s") / "sq.h5", width=96, height=72, size=20,
                              duration_ms=50, velocity_px_s=(200.0, 0.0), split="test")


@pytest.mark.parametrize("name", ["rct", "csrt", "kcf", "mil", "siamfc", "sctn", "sctn_ann"])
@pytest.mark.parametrize("window", ["last", "since"])
def test_tracker_streams_on_unaligned_windows(square, name, window):
    tracker = get_tracker(name, **SMALL.get(name, {}))
    model = LatencyModel("declared", profile="cpu") if tracker.operations else LatencyModel("scaled", 3.3)
    with Dataset(square) as ds:
        run = run_stream(tracker, ds, model, window=window, max_segments=4, query_hz=700)
    assert len(run.latency_s) >= 2 and np.isfinite(run.boxes).all()
    assert np.any(run.window[1:, 1] % 10_000 != 0)  # calls end between segment boundaries
    if window == "since":
        np.testing.assert_array_equal(run.window[2:, 0], run.window[1:-1, 1])
    assert np.isfinite(run.iou).sum() == len(run.query_us) > 0


def test_sctn_encodes_a_long_windows_latest_steps():
    from dvsot.dataset import Segment
    from dvsot.events import EventBatch

    tracker = get_tracker("sctn", **SMALL["sctn"])
    cfg = tracker.tracker.model.cfg
    span = cfg.steps * cfg.step_us

    def seg(t0, t1):
        return Segment(0, t0, t1, EventBatch.empty(), np.full(4, np.nan, np.float32))

    assert tracker._t0(seg(3_000, 3_000 + span)) == 3_000  # a window of the network's span starts where it starts
    assert tracker._t0(seg(0, 2 * span + 700)) == span + 700  # a longer one: its latest span
