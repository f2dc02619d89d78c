"""`dvsot bench` end to end with a tracker registered in the test, and its bad-input errors."""

import json

import numpy as np

from benchmarks.trackers import register
from benchmarks.trackers.base import Tracker
from dvsot.cli import main
from dvsot.dataset import DatasetWriter
from dvsot.events import EventBatch


@register("test-still")
class StillTracker(Tracker):
    """Never moves: succeeds while the target stands still."""

    def init(self, segment, box_xywh, width, height):
        self.box = box_xywh.copy()

    def update(self, segment):
        return self.box.copy()


def make(path, split="test", moving=True, boxes=True):
    n = 20
    with DatasetWriter(path, 64, 48, attrs={"split": split}) as w:
        t = np.arange(n) * 10_000 + 1
        w.append_events(EventBatch(np.full(n, 3, np.uint16), np.full(n, 3, np.uint16), t, np.ones(n, np.uint8)))
        if boxes:
            ts = np.arange(n + 1) * 10_000
            x = 5 + (ts / 10_000 * 4 if moving else 0 * ts)
            w.append_boxes(ts, np.stack([x, np.full(n + 1, 5), np.full(n + 1, 10), np.full(n + 1, 10)], 1))
        w.close(n * 10_000)


def test_fake_tracker_end_to_end(tmp_path, capsys):
    make(tmp_path / "moving.h5")
    make(tmp_path / "still.h5", moving=False)
    make(tmp_path / "train.h5", split="train")
    out = tmp_path / "bench"
    assert main(["bench", "--tracker", "test-still", "--data", str(tmp_path), "--out", str(out), "--jobs", "1",
                 "--quiet", "--plots"]) == 0
    printed = capsys.readouterr().out
    assert "moving" in printed and "still" in printed and "train" not in printed
    res = json.loads((out / "results.json").read_text())["test-still"]
    assert res["still"]["A"] == 1.0 and res["still"]["segments"] == 19
    # moving 4 px per segment with a 10 px box: IoU 6/14 < 0.5 every time -> every other segment re-inits
    assert res["moving"]["R"] == 0.0 and res["moving"]["segments"] == 10
    assert (out / "iou_over_time.png").stat().st_size > 1000


def test_bad_input_exits_2(tmp_path, capsys):
    make(tmp_path / "a.h5")
    make(tmp_path / "nobox.h5", boxes=False)
    (tmp_path / "junk.h5").write_text("not hdf5")
    cases = [
        (["--tracker", "nope", "--data", str(tmp_path / "a.h5")], "unknown tracker 'nope'"),
        (["--tracker", "rct", "--data", str(tmp_path / "junk.h5")], "not a readable HDF5"),
        (["--tracker", "rct", "--data", str(tmp_path / "nobox.h5")], "no ground-truth"),
        (["--tracker", "rct", "--data", str(tmp_path / "a.h5"), "--split", "train"], "split 'train'"),
        (["--tracker", "rct", "--tracker-module", "no_such_module_x"], "cannot import"),
        (["--tracker", "rct", "--data", str(tmp_path / "a.h5"), "--option", "rct-size=3"], "TRACKER.KEY=VALUE"),
        (["--tracker", "rct", "--data", str(tmp_path / "a.h5"), "--option", "sctn.fast=false"], "not in this run"),
    ]
    for argv, words in cases:
        assert main(["bench", *argv, "--quiet"]) == 2, argv
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and words in err[0], (argv, err)
