"""Bad data that used to pass: box values and root attributes checked on open, empty files
refused for training; each through the command line, one line naming the file and field, exit status 2."""

from __future__ import annotations

import h5py
import numpy as np
import pytest

from dvsot.cli import main
from dvsot.dataset import DatasetWriter
from dvsot.events import EventBatch

DIGEST_ATTR = "attrs_sha256"  # the root attribute the writer adds (dvsot.dataset.digest)

W, H = 64, 48


def make(path, events: int = 50, split: str = "train") -> None:
    """A valid 200 ms file, 64x48 px, a 10x8 px box moving right."""
    with DatasetWriter(path, W, H, attrs={"split": split, "scene_yaml": "name: x\n"}) as w:
        if events:
            t = np.sort(np.random.default_rng(0).integers(0, 199_000, events))
            w.append_events(EventBatch(np.full(events, 7, np.uint16), np.full(events, 9, np.uint16), t,
                                       np.ones(events, np.uint8)))
        ts = np.arange(0, 200_001, 5000)
        w.append_boxes(ts, np.stack([5 + ts / 1e4, np.full(len(ts), 6.0), np.full(len(ts), 10.0),
                                     np.full(len(ts), 8.0)], 1))
        w.close(200_000)


def one_error_line(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "Traceback" not in err, err
    return err


def _rows(name: str, row: int, values) -> callable:
    def damage(f):
        d = f[name][()]
        d[row] = values
        f[name][...] = d
    return damage


BOXES = {
    "negative_width": (_rows("segments/xywh", 3, [5, 5, -10, 8]), "/segments/xywh", "w=-10"),
    "zero_height": (_rows("boxes/xywh", 0, [5, 5, 10, 0]), "/boxes/xywh", "h=0"),
    "far_away": (_rows("segments/xywh", 7, [1e30, 5, 10, 8]), "/segments/xywh", "x=1e+30"),
    "half_nan": (_rows("boxes/xywh_visible", 2, [np.nan, 5, 10, 8]), "/boxes/xywh_visible", "x=nan"),
    "infinite": (_rows("segments/xywh_visible", 1, [5, 5, np.inf, 8]), "/segments/xywh_visible", "w=inf"),
    "huge_box": (_rows("boxes/xywh", 4, [-60, -40, 500, 8]), "/boxes/xywh", "inside [-64, 128]"),
}


@pytest.mark.parametrize("case", sorted(BOXES))
def test_bad_boxes_are_refused_by_info_bench_and_train(tmp_path, capsys, case):
    damage, field, words = BOXES[case]
    path = tmp_path / "seq.h5"
    make(path)
    with h5py.File(path, "a") as f:
        damage(f)
    for argv in (
        ["info", str(path)],
        ["bench", "--tracker", "rct", "--data", str(path), "--split", "any", "--out", str(tmp_path / "b")],
        ["train", "--data", str(path), "-o", str(tmp_path / "c.pt")],
    ):
        assert main(argv) == 2, argv
        err = one_error_line(capsys)
        assert str(path) in err and field in err and words in err, err
    assert not (tmp_path / "b").exists() and not (tmp_path / "c.pt").exists()


@pytest.mark.parametrize("name,value", [("name", "other"), ("scene_yaml", "name: y\n"), ("split", "test"),
                                        ("generator", "other"), ("seed", 3)])
def test_a_changed_root_attribute_is_refused(tmp_path, capsys, name, value):
    path = tmp_path / "seq.h5"
    make(path)
    with h5py.File(path, "a") as f:
        f.attrs[name] = value
    assert main(["info", str(path)]) == 2
    err = one_error_line(capsys)
    assert str(path) in err and DIGEST_ATTR in err, err


def test_a_file_without_the_digest_still_loads(tmp_path, capsys):
    path = tmp_path / "old.h5"
    make(path)
    with h5py.File(path, "a") as f:
        del f.attrs[DIGEST_ATTR]  # as written before the digest existed
        f.attrs["name"] = "renamed"
    assert main(["info", str(path)]) == 0
    assert "renamed" in capsys.readouterr().out


def test_a_file_without_events_is_refused_for_training(tmp_path, capsys):
    make(tmp_path / "full.h5")
    make(tmp_path / "empty.h5", events=0)
    assert main(["train", "--data", str(tmp_path), "-o", str(tmp_path / "c.pt"), "--quiet"]) == 2
    err = one_error_line(capsys)
    assert "empty.h5" in err and "no events" in err, err
    assert not (tmp_path / "c.pt").exists()


def test_simulate_refuses_boxes_far_outside_the_sensor(tmp_path, capsys):
    np.save(tmp_path / "s.npy", np.random.default_rng(1).random((5, 24, 32), dtype=np.float32))
    (tmp_path / "b.csv").write_text("0,1,1,4,4\n0.002,1e30,1,4,4\n")
    out = tmp_path / "o.h5"
    assert main(["simulate", str(tmp_path / "s.npy"), "--fps", "1000", "--boxes", str(tmp_path / "b.csv"),
                 "-o", str(out), "--quiet"]) == 2
    err = one_error_line(capsys)
    assert "b.csv" in err and "line 2" in err and "x=1e+30" in err, err
    assert not out.exists()
