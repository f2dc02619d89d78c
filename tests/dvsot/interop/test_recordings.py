"""A recorded sequence (AEDAT4 events + FE108-style boxes at annotation times) imported and scored at annotations
only."""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks.evaluation.protocol import run_sequence
from benchmarks.trackers.base import Tracker
from dvsot.cli import main
from dvsot.dataset import Dataset
from dvsot.dataset.boxes import match_annotations
from dvsot.interop.event_files import write_event_file

W, H = 64, 48
EPOCH = 1_600_000_000_000_000  # the recording's clock: epoch microseconds
START = EPOCH + 500  # first event
ANN_REL = np.array([3_000, 28_000, 52_000, 77_000, 104_000, 131_000])  # annotation times after EPOCH, us
BOXES = np.array([[10, 10, 10, 10], [10, 10, 10, 10], [15, 10, 10, 10], [30, 30, 5, 5], [20, 20, 10, 10],
                  [20, 20, 10, 20]], np.float32)
ABSENT = [0, 0, 0, 1, 0, 0]


@pytest.fixture
def recording(tmp_path):
    """A sequence folder as FE108 / VisEvent ship one: events, groundtruth_rect.txt, frame times, absent.txt."""
    n = 200
    t = START + np.arange(n) * 1_000
    write_event_file(tmp_path / "events.aedat4", t, np.full(n, 12), np.full(n, 14), np.arange(n) % 2, W, H)
    (tmp_path / "groundtruth_rect.txt").write_text("".join(",".join(f"{v:g}" for v in b) + "\n" for b in BOXES))
    (tmp_path / "frame_times.txt").write_text("".join(f"{EPOCH + v}\n" for v in ANN_REL))
    (tmp_path / "absent.txt").write_text("".join(f"{a}\n" for a in ABSENT))
    return tmp_path


def _import(folder, out, *extra):
    return main(["import", str(folder / "events.aedat4"), "--boxes", str(folder / "groundtruth_rect.txt"),
                 "--box-times-us", str(folder / "frame_times.txt"), "--absent", str(folder / "absent.txt"),
                 "-o", str(out), *extra])


def test_match_annotations_nearest_segment_end_within_half_a_segment():
    # ends at 10, 20, 30 ms: 4.9 ms is 5.1 ms from the first end (unmatched); 15 ms ties -> the later end (20);
    # 24 and 26 ms both nearest 20/30: 24 -> segment 1 (beaten by 20.5), 26 -> segment 2; 35.1 ms is past the last end
    t = np.array([4_900, 15_000, 20_500, 24_000, 26_000, 35_100])
    np.testing.assert_array_equal(match_annotations(t, 10_000, 3), [-1, 2, 4])


def test_import_rebases_keeps_annotations_and_absent(recording, tmp_path):
    out = tmp_path / "seq.h5"
    assert _import(recording, out) == 0
    with Dataset(out) as ds:
        assert ds.t_offset_us == START and ds.annotated
        assert ds.duration_us == 199_001  # last event at 199 ms after the first; ms_to_idx stays small
        assert ds.events(0, 1_000).t.tolist() == [0]
        track = ds.boxes()
        np.testing.assert_array_equal(track.t, ANN_REL - 500)  # at the annotation times, rebased
        np.testing.assert_array_equal(np.isnan(track.xywh).all(axis=1), np.array(ABSENT, bool))
        # annotations at 2.5, 27.5, 51.5, 76.5, 103.5, 130.5 ms: the first is 7.5 ms from any segment end
        want = np.full(ds.num_segments, -1)
        want[[2, 4, 7, 9, 12]] = [1, 2, 3, 4, 5]
        np.testing.assert_array_equal(ds.segment_annotations(), want)
        gt = ds.segment_boxes()
        np.testing.assert_array_equal(gt[[2, 4, 9, 12]], BOXES[[1, 2, 4, 5]])  # as annotated, not interpolated
        assert np.isnan(gt[7]).all() and np.isnan(gt[np.flatnonzero(want < 0)]).all()
    from dvsot.cli.info import summarise

    info = summarise(str(out))
    assert (info["t_offset_us"], info["ground_truth"], info["segments_matched_to_annotation"]) == (
        START,
        "annotations",
        5,
    )


class Keeper(Tracker):
    """Predicts the box it was initialised with; records the segments it was asked about."""

    def init(self, segment, box_xywh, width, height):
        self.box, self.updates = box_xywh.copy(), getattr(self, "updates", [])

    def update(self, segment):
        self.updates.append(segment.index)
        return self.box.copy()


def test_bench_scores_annotated_segments_only(recording, tmp_path):
    out = tmp_path / "seq.h5"
    assert _import(recording, out) == 0
    tracker = Keeper()
    with Dataset(out) as ds:
        res = run_sequence(tracker, ds, "keeper")
    # init on segment 2 (box 10,10,10,10); segment 4's annotation 15,10,10,10: IoU 50/150, a failure;
    # segment 7 is annotated absent (skipped); re-init on 9 (20,20,10,10); segment 12: IoU 100/200 = 0.5
    assert res.init_segments == [2, 9]
    scored = np.flatnonzero(~np.isnan(res.iou))
    np.testing.assert_array_equal(scored, [4, 12])
    np.testing.assert_allclose(res.iou[[4, 12]], [1 / 3, 0.5])
    assert tracker.updates == [3, 4, 10, 11, 12, 13, 14, 15, 16, 17, 18]


def _write(folder, name, text):
    (folder / name).write_text(text)
    return folder / name


@pytest.mark.parametrize("case, words", [
    ("order", "events.csv:4: field t is 1500 us, earlier than the event before it"),
    ("epoch", "events.csv:4: field t jumps by"),
    ("columns", "groundtruth_rect.txt:2: 3 fields, expected 4"),
    ("outside", "groundtruth_rect.txt:3: the box x=70 y=6 w=10 h=10 lies outside the 64x48 sensor"),
    ("far", "groundtruth_rect.txt:3: the box is x=70 y=6 w=80"),
    ("absent", "absent.txt: 2 absent flags for 3 boxes"),
    ("clock", "frame_times.txt: the annotation times"),
])
def test_bad_recordings_are_one_line_exit_2_and_write_nothing(tmp_path, capsys, case, words):
    events = ["t,x,y,p", "1000,1,2,1", "2000,3,4,0", "3000,5,6,1", "4000,7,8,0"]
    if case == "order":
        events[3] = "1500,5,6,1"
    if case == "epoch":
        events[3] = "1650000000000000,5,6,1"
        events[4] = "1650000000001000,7,8,0"
    boxes = ["1,2,10,10", "3,4,10,10", "5,6,10,10"]
    if case == "columns":
        boxes[1] = "3,4,10"
    if case in ("outside", "far"):
        boxes[2] = "70,6,10,10" if case == "outside" else "70,6,80,10"
    times = ["1000", "2000", "3000"] if case != "clock" else ["1650000000001000", "1650000000002000",
                                                              "1650000000003000"]
    argv = ["import", str(_write(tmp_path, "events.csv", "\n".join(events) + "\n")), "--size", f"{W}x{H}",
            "--boxes", str(_write(tmp_path, "groundtruth_rect.txt", "\n".join(boxes) + "\n")),
            "--box-times-us", str(_write(tmp_path, "frame_times.txt", "\n".join(times) + "\n")),
            "--absent", str(_write(tmp_path, "absent.txt", "0\n1\n" if case == "absent" else "0\n1\n0\n")),
            "-o", str(tmp_path / "out.h5")]
    code = main(argv)
    err = capsys.readouterr().err.strip()
    assert code == 2 and "\n" not in err and words in err, err
    assert not any(p.suffix == ".h5" or ".tmp" in p.name for p in tmp_path.iterdir())
