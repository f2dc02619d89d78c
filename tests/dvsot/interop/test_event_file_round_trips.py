"""dvsot export / import: every event format round-trips exactly, with the box track beside the events."""

from __future__ import annotations

import numpy as np
import pytest

from dvsot.cli import main
from dvsot.dataset import Dataset, DatasetWriter
from dvsot.events import EventBatch
from dvsot.interop.event_files import boxes_path, read_event_file, write_event_file
from dvsot.interop.text_events import format_rows

W, H = 64, 48


def make_dataset(path, n: int = 5_000, duration_us: int = 120_000) -> None:
    rng = np.random.default_rng(7)
    t = np.sort(rng.integers(0, duration_us, n))
    ev = EventBatch(rng.integers(0, W, n).astype(np.uint16), rng.integers(0, H, n).astype(np.uint16), t,
                    rng.integers(0, 2, n).astype(np.uint8))
    bt = np.arange(0, duration_us + 1, 4_000)
    xywh = np.stack([5 + bt / 7e3, 6 + bt / 11e3, np.full(len(bt), 10.5), np.full(len(bt), 8.25)], 1)
    xywh[10:13] = np.nan  # the target out of view for a while
    with DatasetWriter(path, W, H, attrs={"name": "seq"}) as w:
        w.append_events(ev)
        w.append_boxes(bt, xywh)
        w.close(duration_us)


def test_format_rows_writes_numbers_as_text():
    rows = format_rows([(np.array([0, 5, 123456789012]), 0), (np.array([7, 0, 999999]), 6), (np.array([1, 0, 9]), 0)],
                       [b".", b" "])
    assert rows == b"0.000007 1\n5.000000 0\n123456789012.999999 9\n"


@pytest.mark.parametrize("suffix, evt", [("aedat4", "3"), ("raw", "2"), ("raw", "3"), ("dat", "3"),
                                         ("csv", "3"), ("txt", "3")])
def test_export_then_import_is_exact(tmp_path, suffix, evt):
    src = tmp_path / "seq.h5"
    make_dataset(src)
    out = tmp_path / f"seq.{suffix}"
    assert main(["export", str(src), "-o", str(out), "--evt", evt]) == 0
    assert boxes_path(out).is_file()
    back = tmp_path / "back.h5"
    size = ["--size", f"{W}x{H}"] if suffix == "csv" else []
    assert main(["import", str(out), "--boxes", str(boxes_path(out)), "--interpolate", "--evt", evt,
                 "-o", str(back)] + size) == 0
    with Dataset(src) as a, Dataset(back) as b:
        assert (b.width, b.height, b.num_events, b.duration_us, b.t_offset_us) == (W, H, a.num_events, a.duration_us, 0)
        ea, eb = a.events(0, a.duration_us), b.events(0, b.duration_us)
        for col in "xytp":
            np.testing.assert_array_equal(getattr(eb, col), getattr(ea, col))
        np.testing.assert_array_equal(b.boxes().t, a.boxes().t)
        np.testing.assert_array_equal(b.boxes().xywh, a.boxes().xywh)  # NaN rows compare equal here
        np.testing.assert_array_equal(b.segment_boxes(), a.segment_boxes())
        assert not b.annotated


def test_epoch_timestamps_round_trip_in_every_format(tmp_path):
    rng = np.random.default_rng(2)
    t = np.sort(rng.integers(0, 5_000_000, 2_000)) + 1_650_000_000_123_456
    x, y, p = rng.integers(0, W, 2_000), rng.integers(0, H, 2_000), rng.integers(0, 2, 2_000)
    for name, evt in [("a.aedat4", "evt3"), ("a.raw", "evt2"), ("b.raw", "evt3"), ("a.dat", "evt3"),
                      ("a.csv", "evt3"), ("a.txt", "evt3")]:
        path = tmp_path / name
        write_event_file(path, t, x, y, p, W, H, evt)
        assert path.stat().st_size < 100_000  # no padding from time zero to the epoch
        ev = read_event_file(path, (W, H) if name.endswith(".csv") else None, evt)
        for got, want in zip((ev.t, ev.x, ev.y, ev.p), (t, x, y, p)):
            np.testing.assert_array_equal(got, want)


def _one_line_exit_2(capsys, argv, *words):
    code = main(argv)
    err = capsys.readouterr().err.strip()
    assert code == 2 and "\n" not in err, err
    for w in words:
        assert w in err, err
    return err


def test_unknown_export_suffix_writes_nothing(tmp_path, capsys):
    src = tmp_path / "seq.h5"
    make_dataset(src)
    out = tmp_path / "seq.xyz"
    _one_line_exit_2(capsys, ["export", str(src), "-o", str(out)], str(out), "unknown event file suffix '.xyz'")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["seq.h5"]


def test_default_raw_is_evt2_which_expelliarmus_reads_exactly(tmp_path):
    from expelliarmus import Wizard  # tonic's reader of Prophesee files

    rng = np.random.default_rng(5)
    n, offset = 4_000, 1_700_000_000_123_456  # an epoch start; 2 s with gaps past EVT 3's 4096 us time-high step
    t = np.sort(rng.integers(0, 2_000_000, n))
    ev = EventBatch(rng.integers(0, W, n).astype(np.uint16), rng.integers(0, H, n).astype(np.uint16), t,
                    rng.integers(0, 2, n).astype(np.uint8))
    with DatasetWriter(tmp_path / "seq.h5", W, H, t_offset_us=offset) as w:
        w.append_events(ev)
        w.close(2_000_000)
    out = tmp_path / "seq.raw"
    assert main(["export", str(tmp_path / "seq.h5"), "-o", str(out), "--no-boxes"]) == 0
    header = [line for line in out.read_bytes().split(b"\n")[:8] if line.startswith(b"%")]
    assert b"% evt 2.0" in header
    t0 = int(next(line for line in header if line.startswith(b"% t0 ")).split()[2])
    got = Wizard(encoding="evt2").read(out)  # expelliarmus leaves out the header's t0: added here
    np.testing.assert_array_equal(got["t"].astype(np.int64) + t0, t + offset)
    for col in "xyp":
        np.testing.assert_array_equal(got[col], getattr(ev, col))
