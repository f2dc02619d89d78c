"""Per-event labels leave dvsot: the CSV export's object column and table, the torch dataset's ids and target mask."""

from __future__ import annotations

import csv

import numpy as np
import pytest

from dvsot.dataset import Dataset
from dvsot.events import EventParams, EventSimulator
from dvsot.events.labels import TARGET_ID, LabelledFrame, object_table
from dvsot.pipeline.sequence import write_sequence

W, H = 24, 16


def _labelled(path, labels=True):
    """A 4 px square (target) moving 2 px right per ms over a background, 8 samples; 4 ms segments."""
    frames = []
    for k in range(9):
        level, ids = np.zeros((H, W)), np.zeros((H, W), np.uint8)
        level[6:10, 2 + 2 * k:6 + 2 * k], ids[6:10, 2 + 2 * k:6 + 2 * k] = 0.6, TARGET_ID
        frames.append(LabelledFrame(level, ids) if labels else level)
    sim = EventSimulator(W, H, EventParams(cp=0.2, cn=0.2, shot_noise_hz=500.0), seed=1)
    out, _ = write_sequence(path, frames, np.arange(9) * 1000, sim, {}, 4000, is_log=True,
                            objects=object_table([("ball, red", "distractor")]) if labels else None)
    return out


def test_csv_export_has_the_object_column_and_table(tmp_path):
    from dvsot.cli import main
    from dvsot.interop.event_files import read_event_file

    src = _labelled(tmp_path / "l.h5")
    out = tmp_path / "l.csv"
    assert main(["export", str(src), "-o", str(out)]) == 0
    with Dataset(src) as ds:
        ev = ds.events(0, ds.duration_us)
        table = ds.objects
    rows = np.loadtxt(out, delimiter=",", skiprows=1, dtype=np.int64, ndmin=2)
    assert out.read_text().splitlines()[0] == "t,x,y,p,object"
    assert np.array_equal(rows[:, 4], ev.object) and np.array_equal(rows[:, 0], ev.t)
    with open(tmp_path / "l.csv.objects.csv", newline="") as fh:
        got = list(csv.DictReader(fh))
    assert [(int(r["id"]), r["name"], r["role"]) for r in got] == [(r["id"], r["name"], r["role"]) for r in table]
    back = read_event_file(out, size=(W, H))  # the labelled CSV reads back as events
    assert np.array_equal(back.t, ev.t) and np.array_equal(back.x, ev.x)


def test_unlabelled_csv_export_is_unchanged(tmp_path):
    from dvsot.interop.event_files import export_dataset

    src = _labelled(tmp_path / "u.h5", labels=False)
    paths = export_dataset(src, tmp_path / "u.csv")
    assert (tmp_path / "u.csv").read_text().splitlines()[0] == "t,x,y,p"
    assert not (tmp_path / "u.csv.objects.csv").exists() and len(paths) == 3


def test_torch_dataset_gives_labels_and_target_mask(tmp_path):
    from dvsot.dataset.torchdata import SegmentDataset, collate_segments

    src = _labelled(tmp_path / "l.h5")
    data = SegmentDataset(src, labels=True, with_box=False)
    events, box, objects, mask, truth = data[1]
    assert truth["silhouette"] is None and np.isnan(truth["visibility"])  # a file without masks or visibility
    with Dataset(src) as ds:
        seg = ds.segment(1)
    assert np.array_equal(objects, seg.events.object) and len(objects) == len(events)
    hit = seg.events.object == TARGET_ID
    want = np.zeros((H, W), bool)
    want[seg.events.y[hit], seg.events.x[hit]] = True
    assert mask.shape == (H, W) and np.array_equal(mask, want) and mask.any()
    # segment 1 is [4, 8) ms: its events come from the intervals 3-4 ms (the crossings at 4 ms: the square at 8..11,
    # then 10..13) to 7-8 ms (those before 8 ms: 16..19, then 18..21), so its edges swept columns 8..21
    assert np.array_equal(np.flatnonzero(mask.any(axis=0)), np.arange(8, 22))
    pytest.importorskip("torch")
    ev_b, box_b, obj_b, mask_b, truth_b = collate_segments([data[0], data[1]])
    assert tuple(mask_b.shape) == (2, H, W) and len(obj_b) == 2


def test_torch_labels_need_a_labelled_file(tmp_path):
    from dvsot.core.errors import UserError
    from dvsot.dataset.torchdata import SegmentDataset

    src = _labelled(tmp_path / "u.h5", labels=False)
    with pytest.raises(UserError, match="no per-event labels"):
        SegmentDataset(src, labels=True, with_box=False)
