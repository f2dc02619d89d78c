"""The hidden-target rule (benchmarks/evaluation/protocol.py, rule 6) on crafted files: a target wholly covered
(`absent` = 1 with an amodal box) is never initialised on, is scored apart (neither success nor failure, the
`absent` column), or not at all with skip_absent; the AR and one-pass protocols follow it alike."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from benchmarks.evaluation.attributes import add_attributes, attribute_ope, attribute_scores
from benchmarks.evaluation.ope import add_centre_errors
from benchmarks.evaluation.protocol import nothing_to_score, run_sequence, segment_rules
from dvsot.dataset import Dataset, DatasetWriter

BOX = [10.0, 10.0, 20.0, 20.0]


def _file(path: Path, n: int, hidden: list[int]) -> Path:
    """n segments of 10 ms, boxes at their ends (segment i: row i + 1), the target wholly hidden on `hidden`."""
    box = np.tile(BOX, (n + 1, 1))
    vis_box, visibility = box.copy(), np.ones(n + 1)
    rows = np.asarray(hidden, int) + 1
    vis_box[rows], visibility[rows] = np.nan, 0.0
    with DatasetWriter(path, 100, 100, 10_000, {"name": path.stem, "split": "test"}) as w:
        w.append_boxes(np.arange(n + 1) * 10_000, box, vis_box, visibility)
        w.close(n * 10_000 + 1)
    return path


class Scripted:
    """The ground truth, shifted off the target (IoU 0) on the segments in `miss`; records what it is asked."""

    def __init__(self, gt, miss=()):
        self.gt, self.miss, self.inits, self.updates = gt, set(miss), [], []

    def init(self, segment, box_xywh, width, height):
        self.inits.append(segment.index)

    def update(self, segment):
        self.updates.append(segment.index)
        box = self.gt[segment.index].copy()
        box[0] += box[2] if segment.index in self.miss else 0.0
        return box

    def energy_per_segment(self):
        return None


def _run(path: Path, miss=(), **kw):
    with Dataset(path) as ds:
        tr = Scripted(ds.segment_boxes(), miss)
        return tr, add_attributes(run_sequence(tr, ds, "t", **kw), ds)


def test_the_file_flags_the_hidden_segments(tmp_path):
    with Dataset(_file(tmp_path / "h.h5", 14, [5, 6, 7])) as ds:
        rules = segment_rules(ds)
        assert np.flatnonzero(ds.segment_absent()).tolist() == [5, 6, 7]
    assert np.flatnonzero(rules.hidden).tolist() == [5, 6, 7] == np.flatnonzero(rules.apart).tolist()
    assert not rules.visible[[5, 6, 7]].any() and rules.visible.sum() == 11 and not rules.resets.any()


def test_hidden_segments_are_tracked_and_scored_apart(tmp_path):
    tr, r = _run(_file(tmp_path / "h.h5", 14, [5, 6, 7]), miss=[6])  # the miss on a hidden segment is no failure
    assert r.init_segments == [0] and tr.updates == list(range(1, 14))
    assert np.flatnonzero(~np.isnan(r.iou)).tolist() == [1, 2, 3, 4, 8, 9, 10, 11, 12, 13]
    assert np.flatnonzero(~np.isnan(r.hidden_iou)).tolist() == [5, 6, 7] and r.hidden_iou[6] == 0.0
    s = attribute_scores([r])["t"]
    assert s["all"].segments == 10 and s["all"].robustness == 1.0  # the hidden miss is not in A or R
    assert s["absent"].segments == 3 and s["absent"].accuracy == np.float64(2 / 3)


def test_reinitialisation_waits_for_the_target_to_reappear(tmp_path):
    tr, r = _run(_file(tmp_path / "h.h5", 14, [5, 6, 7]), miss=[4])  # fails just before the hidden stretch
    assert r.init_segments == [0, 8] == tr.inits and 5 not in tr.updates and 8 not in tr.updates
    assert np.isnan(r.hidden_iou).all()  # never asked while hidden: nothing scored apart


def test_a_sequence_that_starts_hidden_initialises_on_the_first_visible_segment(tmp_path):
    path = _file(tmp_path / "h.h5", 8, [0, 1, 2])
    for reinitialise in (True, False):
        tr, r = _run(path, reinitialise=reinitialise)
        assert r.init_segments == [3] and tr.updates == [4, 5, 6, 7]


def test_skip_absent_leaves_hidden_segments_out(tmp_path):
    tr, r = _run(_file(tmp_path / "h.h5", 14, [5, 6, 7]), miss=[6], skip_absent=True)
    assert r.init_segments == [0] and tr.updates == list(range(1, 14))  # still tracked, as GOT-10k runs them
    assert r.hidden_iou is None and np.isnan(r.iou[[5, 6, 7]]).all()
    assert "absent" not in attribute_scores([r])["t"]  # no column: nothing scored apart


def test_one_pass_scores_hidden_segments_apart_with_their_centre_errors(tmp_path):
    path = _file(tmp_path / "h.h5", 10, [4, 5])
    tr, r = _run(path, miss=[5, 7], reinitialise=False)
    with Dataset(path) as ds:
        add_centre_errors(r, ds.segment_boxes())
    assert np.flatnonzero(~np.isnan(r.extra["hidden_centre_error"])).tolist() == [4, 5]
    assert r.extra["hidden_centre_error"][5] == 20.0 and np.isnan(r.extra["centre_error"][[4, 5]]).all()
    s = attribute_ope([r])["t"]
    assert s["absent"]["segments"] == 2 and s["all"]["segments"] == 7 and s["absent"]["P@20"] == 1.0


def test_a_file_hidden_after_its_first_segment_has_nothing_to_score(tmp_path):
    assert nothing_to_score(_file(tmp_path / "ok.h5", 8, [1, 2, 3, 4, 5])) is None  # 0 init, hidden, 6 counted
    problem = nothing_to_score(_file(tmp_path / "bad.h5", 8, [1, 2, 3, 4, 5, 6, 7]))
    assert "bad.h5: no segment of 8 can be scored" in problem and "7 more with the target wholly hidden" in problem


def test_bench_scores_hidden_segments_apart_or_skips_them(tmp_path, capsys):
    import json

    from benchmarks.trackers import register
    from benchmarks.trackers.base import Tracker
    from dvsot.cli import main

    @register("test-hold-hidden")
    class Hold(Tracker):
        """Keeps its first box: right on every segment of a standing target."""

        def init(self, segment, box_xywh, width, height):
            self.box = box_xywh.copy()

        def update(self, segment):
            return self.box.copy()

    (tmp_path / "data").mkdir()
    _file(tmp_path / "data" / "h.h5", 14, [5, 6, 7])
    for flags, absent in (([], 3), (["--skip-absent"], None)):
        out = tmp_path / f"bench{len(flags)}"
        assert main(["bench", "--tracker", "test-hold-hidden", "--data", str(tmp_path / "data"), "--out", str(out),
                     "--jobs", "1", "--quiet", *flags]) == 0
        scores = json.loads((out / "attributes.json").read_text())["scores"]["test-hold-hidden"]
        assert scores["all"]["segments"] == 10
        assert (scores["absent"]["segments"] if "absent" in scores else None) == absent
    capsys.readouterr()


class Missing:
    """A streaming tracker that always answers a box off the target (IoU 0): every counted query fails."""

    operations = ("ac_ops",)

    def init(self, segment, box_xywh, width, height):
        self.init_at = segment.t1_us

    def update(self, segment):
        return np.array([60.0, 60.0, 20.0, 20.0])

    def energy_per_segment(self):
        return {"ac_ops": 5e6}  # 5 ms a call on the cpu profile

    def energy_per_init(self):
        return {"ac_ops": 5e6}


def test_the_streaming_protocol_scores_hidden_queries_apart_and_starts_on_a_visible_target(tmp_path):
    from benchmarks.evaluation.latency import LatencyModel
    from benchmarks.evaluation.stream import run_stream

    path = _file(tmp_path / "s.h5", 14, [0, 1, 5, 6, 7])
    tracker = Missing()
    with Dataset(path) as ds:
        run = run_stream(tracker, ds, LatencyModel("declared", profile="cpu"))
    assert tracker.init_at == 30_000  # segments 0 and 1 are hidden: the first visible one is segment 2
    hidden = np.isfinite(run.hidden_iou)
    # queries next to the hidden samples (rows 6..8, 60..80 ms, interpolated in between) are hidden ones
    assert hidden.any() and np.all((run.query_us[hidden] > 50_000) & (run.query_us[hidden] < 90_000))
    assert np.isnan(run.iou[hidden]).all() and np.isnan(run.predictive_iou[hidden]).all()
    counted = np.isfinite(run.iou)
    assert counted.sum() + hidden.sum() == len(run.query_us)  # every query counts once, in one place
