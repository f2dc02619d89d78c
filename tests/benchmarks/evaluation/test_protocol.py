"""Re-initialisation protocol with a scripted tracker whose failures are known in advance."""

import numpy as np

from benchmarks.evaluation.protocol import run_sequence
from benchmarks.trackers.base import Tracker
from dvsot.dataset import Dataset, DatasetWriter
from dvsot.events import EventBatch


def make_file(path, boxes):
    n = len(boxes)
    with DatasetWriter(path, 100, 100, segment_us=10_000, attrs={"name": "seq", "split": "test"}) as w:
        t = np.arange(n) * 10_000 + 5_000
        w.append_events(EventBatch(np.full(n, 5, np.uint16), np.full(n, 5, np.uint16), t, np.ones(n, np.uint8)))
        w.append_boxes(np.arange(n + 1) * 10_000, np.vstack([boxes[:1], boxes]))
        w.close(n * 10_000)


class Scripted(Tracker):
    """Returns the ground truth, shifted off target on the segments listed in `miss`."""

    def __init__(self, gt, miss, crash_at=None):
        self.gt, self.miss, self.crash_at = gt, set(miss), crash_at
        self.inits = []

    def init(self, segment, box_xywh, width, height):
        self.inits.append(segment.index)
        np.testing.assert_allclose(box_xywh, self.gt[segment.index])

    def update(self, segment):
        if segment.index == self.crash_at:
            raise RuntimeError("boom")
        box = self.gt[segment.index].copy()
        if segment.index in self.miss:
            box[0] += box[2]  # IoU 0
        return box


def test_failures_reinitialise_on_the_next_segment_and_init_segments_do_not_count(tmp_path):
    gt = np.tile(np.array([10, 10, 20, 20], np.float32), (10, 1))
    gt[6] = np.nan  # target out of view in segment 6
    make_file(tmp_path / "s.h5", gt)
    with Dataset(tmp_path / "s.h5") as ds:
        tr = Scripted(ds.segment_boxes(), miss=[2, 3])
        res = run_sequence(tr, ds, "scripted")
    # 0 init, 1 ok, 2 fail, 3 re-init (its miss is never asked), 4 ok, 5 ok, 6 skipped, 7 init, 8 ok, 9 ok
    assert tr.inits == [0, 3, 7] == res.init_segments
    counted = np.flatnonzero(~np.isnan(res.iou))
    assert counted.tolist() == [1, 2, 4, 5, 8, 9]
    assert res.iou[2] == 0.0 and np.all(res.iou[[1, 4, 5, 8, 9]] == 1.0)
    assert res.tracked_segments == 6 and res.error is None


def test_a_crashing_tracker_is_recorded_not_raised(tmp_path):
    gt = np.tile(np.array([10, 10, 20, 20], np.float32), (5, 1))
    make_file(tmp_path / "s.h5", gt)
    with Dataset(tmp_path / "s.h5") as ds:
        res = run_sequence(Scripted(ds.segment_boxes(), [], crash_at=3), ds, "scripted")
    assert res.error.startswith("RuntimeError: boom") and np.all(np.isnan(res.iou))


def test_initialisation_and_energy_counting_are_timed_apart_from_updates(tmp_path, monkeypatch):
    import benchmarks.evaluation.protocol as protocol

    clock = [0.0]
    monkeypatch.setattr(protocol.time, "perf_counter", lambda: clock[0])

    class Timed(Scripted):
        """Each init takes 5 s, each update 0.25 s and each energy count 1 s of the fake clock."""

        def init(self, segment, box_xywh, width, height):
            super().init(segment, box_xywh, width, height)
            clock[0] += 5.0

        def update(self, segment):
            clock[0] += 0.25
            return super().update(segment)

        def energy_per_segment(self):
            clock[0] += 1.0
            return None

    gt = np.tile(np.array([10, 10, 20, 20], np.float32), (6, 1))
    make_file(tmp_path / "s.h5", gt)
    with Dataset(tmp_path / "s.h5") as ds:
        res = run_sequence(Timed(ds.segment_boxes(), miss=[2]), ds, "timed")
    # 0 init, 1 ok, 2 fail, 3 re-init, 4 ok, 5 ok: 2 inits, 4 updates
    assert res.init_seconds == 10.0 and res.tracker_seconds == 1.0 and res.segments_per_s == 4.0
