"""The streaming protocol on a hand-made tracker with declared latencies: closed-form scores, determinism."""

import numpy as np
import pytest

from benchmarks.evaluation.latency import LatencyModel, check_declared, parse_latency
from benchmarks.evaluation.stream import latest_available, run_sequences, run_stream, stream_scores
from benchmarks.trackers.base import Tracker
from dvsot.core.errors import UserError
from dvsot.dataset import Dataset
from tests.synthetic import moving_square_file

V = np.array([150.0, 60.0])  # the square's velocity, px/s
START, SIZE = np.array([30.0, 30.0]), 30.0


def true_box(t_us):
    return np.array([*(START + V * t_us / 1e6), SIZE, SIZE])


class Oracle(Tracker):
    """Answers the exact box at its window's end; counts `ac_ops` so that its declared cpu latency is latency_s."""

    operations = ("ac_ops",)

    def __init__(self, latency_s=0.005, init_latency_s=0.005):
        self.latency_s, self.init_latency_s = latency_s, init_latency_s
        self.windows = []

    def init(self, segment, box_xywh, width, height):
        np.testing.assert_allclose(box_xywh, true_box(segment.t1_us), atol=1e-3)
        assert np.isnan(segment.box).all()  # a streaming call is never shown ground truth

    def update(self, segment):
        self.windows.append((segment.t0_us, segment.t1_us, len(segment.events)))
        return true_box(segment.t1_us)

    def energy_per_segment(self):
        return {"ac_ops": self.latency_s / 1e-9}

    def energy_per_init(self):
        return {"ac_ops": self.init_latency_s / 1e-9}


def square_iou(d):
    inter = np.prod(np.clip(SIZE - np.abs(d), 0, None), axis=-1)
    return inter / (2 * SIZE * SIZE - inter)


@pytest.fixture(scope="module")
def square(tmp_path_factory):
    return moving_square_file(tmp_path_factory.mktemp("s") / "sq.h5", duration_ms=120, split="test")


def expected(latency_us, predictive=False, end_us=120_000, step_us=1000):
    """Closed form: the init at 10 ms, calls at 11 ms + k L (k >= 0: the init's latency is not charged), answer k
    available at its call + L; each 1 ms query after 10 ms scores the latest available answer (the given box until
    the first answer)."""
    calls = 11_000 + latency_us * np.arange(0, 1000)
    calls = calls[calls <= end_us]
    # predictive: the velocity of two exact answers (the given box first) moves each exactly to its arrival
    describes = np.concatenate([[10_000], calls + (latency_us if predictive else 0)])
    avail = np.concatenate([[10_000], calls + latency_us])
    q = np.arange(11_000, end_us + 1, step_us)
    k = np.searchsorted(avail, q, side="right") - 1
    return square_iou(V[None, :] * (q - describes[k])[:, None] / 1e6)


def test_declared_latency_gives_the_closed_form_scores(square):
    tracker = Oracle()
    with Dataset(square) as ds:
        run = run_stream(tracker, ds, LatencyModel("declared", profile="cpu"))
    np.testing.assert_array_equal(run.query_us, np.arange(11_000, 120_001, 1000))
    np.testing.assert_allclose(run.iou, expected(5000), atol=1e-6)
    np.testing.assert_allclose(run.predictive_iou, expected(5000, predictive=True), atol=1e-6)
    arriving = (run.query_us >= 16_000) & (run.query_us % 5000 == 1000)  # an answer arrives at these queries
    assert np.all(run.predictive_iou[arriving] > 0.9999) and np.all(run.iou[arriving] < 0.99)  # exact when it lands
    # windows: the last 10 ms ending at each call, calls 5 ms apart from 11 ms
    assert [w[:2] for w in tracker.windows[:3]] == [(1_000, 11_000), (6_000, 16_000), (11_000, 21_000)]
    assert run.latency_s[1:].tolist() == pytest.approx([0.005] * (len(run.latency_s) - 1))
    s = stream_scores(run.iou, run.centre_error)
    assert s["A"] == pytest.approx(expected(5000).mean()) and s["queries"] == 110


def test_since_window_takes_everything_after_the_last_call_and_unaligned_windows_work(square):
    tracker = Oracle(latency_s=0.0037, init_latency_s=0.0037)
    with Dataset(square) as ds:
        run_stream(tracker, ds, LatencyModel("declared", profile="cpu"), window="since")
        n_events = ds.num_events
    t0s = [w[0] for w in tracker.windows]
    t1s = [w[1] for w in tracker.windows]
    assert t0s[0] == 10_000 and t1s[0] == 11_000 and t1s[1] == 14_700  # 1 ms after the init, then 3.7 ms later
    assert t0s[1:] == t1s[:-1]  # each call takes what arrived since the previous one, not aligned to 10 ms
    assert sum(w[2] for w in tracker.windows) < n_events


def test_faster_than_the_queries_waits_for_the_next_query_and_free_reference_calls_every_segment(square):
    tracker = Oracle(latency_s=1e-5)
    with Dataset(square) as ds:
        seq = run_sequences(lambda: tracker, ds, [LatencyModel("declared", profile="cpu")], "oracle")
    assert seq.error is None and set(seq.runs) == {"free", "declared:cpu"}
    free = seq.runs["free"]
    np.testing.assert_array_equal(free.window[1:, 1], np.arange(20_000, 120_001, 10_000))
    np.testing.assert_array_equal(free.available_us, free.window[:, 1])
    assert np.all(np.diff(seq.runs["declared:cpu"].window[1:, 1]) == 1000)  # one call per query period


def test_declared_runs_are_bit_identical(square):
    with Dataset(square) as ds:
        a = run_stream(Oracle(0.0041), ds, LatencyModel("declared", profile="loihi"))
        b = run_stream(Oracle(0.0041), ds, LatencyModel("declared", profile="loihi"))
    for name in ("window", "latency_s", "available_us", "boxes", "iou", "predictive_iou"):
        assert getattr(a, name).tobytes() == getattr(b, name).tobytes()


def test_latest_available_takes_the_latest_call_already_available():
    avail = np.array([0, 50, 30, 60])  # call 1 is slow: call 2's answer arrives first
    np.testing.assert_array_equal(latest_available(avail, np.array([-1, 0, 35, 55, 70])), [-1, 0, 2, 2, 3])


@pytest.mark.parametrize("spec, words", [("wall", "unknown latency model"), ("declared:tpu", "unknown hardware"),
                                         ("scaled:0", "scale factor"), ("scaled:x", "scale factor"),
                                         ("declared", "unknown latency model")])
def test_bad_latency_models_are_refused_naming_the_option(spec, words):
    with pytest.raises(UserError, match=f"--latency {spec}: .*{words}"):
        parse_latency(spec, "--latency")


def test_a_tracker_without_operations_is_refused_for_a_declared_model():
    models = parse_latency("declared:loihi")
    check_declared(models, {"oracle": Oracle})
    with pytest.raises(UserError, match="tracker 'plain' has no latency under it"):
        check_declared(models, {"plain": Tracker})
    assert [m.name for m in parse_latency("scaled:0.5,2")] == ["scaled:0.5", "scaled:2"]


def test_declared_seconds_of_each_profile():
    from benchmarks.evaluation.latency import declared_seconds

    counts = {"ac_ops": 1e6, "state_updates": 1e5, "mac_ops": 2e6, "activations": 0.0}
    assert declared_seconds(counts, "cpu") == pytest.approx(1e6 * 1e-9 + 1e5 * 1e-9 + 2e6 * 1e-9)
    # loihi: synaptic ops and updates shared by 128 cores, the MACs on the cpu host
    assert declared_seconds(counts, "loihi") == pytest.approx((1e6 * 3.5e-9 + 1e5 * 5e-9) / 128 + 2e6 * 1e-9)


def test_half_factor_is_interpolated_between_the_bracketing_factors():
    from benchmarks.evaluation.stream_summary import half_factor

    h = half_factor([(1.0, 0.8), (2.0, 0.6), (4.0, 0.2)], 0.8)
    assert h["reached"] and h["factor"] == pytest.approx(2.0 + 2.0 * (0.6 - 0.4) / (0.6 - 0.2))
    assert half_factor([(1.0, 0.8), (8.0, 0.5)], 0.8) == {"factor": None, "reached": False, "half_score": 0.4}
    assert half_factor([(0.5, 0.3)], 0.8)["at_or_below"]


def test_summary_pools_sequences_and_gives_the_drop_from_the_latency_free_run(square):
    from benchmarks.evaluation.stream_summary import summarise_stream

    with Dataset(square) as ds:
        seq = run_sequences(lambda: Oracle(0.02, 0.02), ds, [LatencyModel("declared", profile="cpu")], "oracle")
    summary = summarise_stream([seq], predictive=True)
    rows = summary["rows"]
    assert set(rows) == {"oracle", "oracle (predictive)"}
    free, late = rows["oracle"]["free"]["all"], rows["oracle"]["declared:cpu"]["all"]
    assert late["latency"]["p50_s"] == pytest.approx(0.02) and late["latency"]["calls"] == len(seq.runs["declared:cpu"]
                                                                                               .latency_s) - 1
    assert summary["drop"]["oracle"]["declared:cpu"]["ARscore"] == pytest.approx(free["ARscore"] - late["ARscore"])
    assert late["ARscore"] < free["ARscore"]  # 20 ms late on a moving target costs accuracy
    assert rows["oracle (predictive)"]["declared:cpu"]["all"]["A"] > late["A"]  # extrapolation recovers some


def test_a_recording_is_queried_at_its_annotations_only(tmp_path):
    from dvsot.dataset import DatasetWriter
    from dvsot.events import EventBatch

    n = 12  # segments of 10 ms; annotations every 20 ms (a recording is never interpolated)
    path = tmp_path / "rec.h5"
    with DatasetWriter(path, 160, 120, 10_000, {"name": "rec", "split": "test"}, annotated=True) as w:
        t = np.arange(n * 10) * 1000 + 500
        w.append_events(EventBatch(np.full(t.size, 50, np.uint16), np.full(t.size, 50, np.uint16), t,
                                   np.ones(t.size, np.uint8)))
        ann = np.arange(0, n * 10_000, 20_000) + 10_000
        w.append_boxes(ann, np.stack([true_box(a) for a in ann]).astype(np.float32))
        w.close(n * 10_000)
    with Dataset(path) as ds:
        run = run_stream(Oracle(0.004, 0.004), ds, LatencyModel("declared", profile="cpu"))
        annotations = ds.boxes().t
    assert set(run.query_us) <= set(annotations) and len(run.query_us) >= 3
    assert np.isfinite(run.iou).all()


@pytest.mark.parametrize("name", ["sctn", "sctn_ann", "siamfc", "goturn", "siamrpn", "siammask", "ocean", "automatch"])
def test_every_counting_tracker_has_a_declared_latency(name):
    """Each tracker that counts its operations (energy_per_segment) is timed by both hardware profiles."""
    from benchmarks.trackers import tracker_class

    cls = tracker_class(name)
    check_declared(parse_latency("declared:cpu") + parse_latency("declared:loihi"), {name: cls})
    assert {"mac_ops", "activations"} <= set(cls.operations) or "ac_ops" in cls.operations
