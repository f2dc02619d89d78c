"""`dvsot import` on files written by the tools users have: expelliarmus's headers without geometry and its DAT
type 0x00, and an FE108-style AEDAT4 recording written by dv-processing whose frame track times the boxes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from expelliarmus import Wizard

from dvsot.cli import main
from dvsot.dataset import Dataset

FE108_LIKE = (
    Path(__file__).resolve().parents[2] / "data" / "fe108_like.aedat4"
)  # written by tests/data/make_fe108_like.py
W, H = 64, 48


def expelliarmus_events(n: int = 3_000) -> np.ndarray:
    rng = np.random.default_rng(27)
    a = np.zeros(n, np.dtype([("t", "<i8"), ("x", "<i2"), ("y", "<i2"), ("p", "u1")]))
    a["t"] = np.sort(rng.integers(0, 300_000, n))
    a["x"], a["y"], a["p"] = rng.integers(0, W, n), rng.integers(0, H, n), rng.integers(0, 2, n)
    return a


def one_error_line(capsys, *words: str) -> str:
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and all(w in err for w in words), err
    return err


@pytest.mark.parametrize("suffix, encoding", [("raw", "evt2"), ("dat", "dat")])
def test_a_header_without_geometry_needs_size(tmp_path, capsys, suffix, encoding):
    events = expelliarmus_events()
    path = tmp_path / f"exp.{suffix}"
    Wizard(encoding=encoding).save(str(path), events)  # expelliarmus writes no width or height
    out = tmp_path / "seq.h5"
    evt = ["--evt", encoding[-1]] if suffix == "raw" else []
    assert main(["import", str(path), "-o", str(out), *evt]) == 2
    one_error_line(capsys, str(path), "gives no sensor size", "--size WIDTHxHEIGHT")
    assert not out.exists() and list(tmp_path.iterdir()) == [path]
    assert main(["import", str(path), "-o", str(out), "--size", f"{W}x{H}", *evt]) == 0
    with Dataset(out) as ds:
        assert (ds.width, ds.height, ds.num_events) == (W, H, len(events))
        got = ds.events(0, ds.duration_us)
        np.testing.assert_array_equal(got.t + ds.t_offset_us, events["t"])
        for col in "xyp":
            np.testing.assert_array_equal(getattr(got, col), events[col])


def test_evt3_without_time_high_words_is_refused(tmp_path, capsys):
    path = tmp_path / "exp.raw"
    Wizard(encoding="evt3").save(str(path), expelliarmus_events())  # one time-high word, then only time-lows
    out = tmp_path / "seq.h5"
    assert main(["import", str(path), "-o", str(out), "--size", f"{W}x{H}", "--evt", "3"]) == 2
    one_error_line(capsys, str(path), "wraps from", "no time-high word", "EVT 2")
    assert not out.exists()


@pytest.mark.parametrize("n, duration_us, misread", [(30_000, 20_000_000, False), (5_000, 20_000_000, True)])
def test_evt3_time_high_wraps_faery_misreads_are_refused(tmp_path, capsys, n, duration_us, misread):
    from dvsot.interop.event_files import evt3_time_problem, write_event_file

    rng = np.random.default_rng(4)
    t = np.sort(rng.integers(0, duration_us, n))  # past the 2^24 us wrap of EVT 3's time; sparse: gaps over 4 ms
    src = tmp_path / "spec.raw"
    write_event_file(src, t, rng.integers(0, W, n), rng.integers(0, H, n), rng.integers(0, 2, n), W, H,
                     evt_version="evt3")
    problem = evt3_time_problem(src)
    assert (problem is not None) == misread
    assert evt3_time_problem(src, words_per_chunk=4_097) == problem  # state carried across chunks
    out = tmp_path / "seq.h5"
    if misread:  # faery would decode every time after the wrap wrong: refused, nothing written
        assert "time-high word" in problem and "wraps from 4094 to 0" in problem
        assert main(["import", str(src), "-o", str(out)]) == 2
        one_error_line(capsys, str(src), "time-high word", "EVT 2")
        assert not out.exists()
    else:
        assert main(["import", str(src), "-o", str(out)]) == 0
        with Dataset(out) as ds:
            np.testing.assert_array_equal(ds.events(0, ds.duration_us).t + ds.t_offset_us, t)


def test_a_size_the_header_contradicts_is_refused(tmp_path, capsys):
    src = tmp_path / "seq.raw"
    from dvsot.interop.event_files import write_event_file

    write_event_file(src, np.array([5, 9]), np.array([1, 2]), np.array([3, 4]), np.array([0, 1]), W, H)
    assert main(["import", str(src), "-o", str(tmp_path / "o.h5"), "--size", "640x480"]) == 2
    one_error_line(capsys, str(src), f"the file says {W}x{H} pixels", "--size says 640x480")


def test_dat_type_0x00_is_read(tmp_path):
    events = expelliarmus_events()
    path = tmp_path / "exp.dat"
    Wizard(encoding="dat").save(str(path), events)
    assert path.read_bytes().split(b"\n% ")[-1].split(b"\n", 1)[1][:1] == b"\x00"  # the event type byte: 2D
    assert main(["import", str(path), "-o", str(tmp_path / "seq.h5"), "--size", f"{W}x{H}"]) == 0
    with Dataset(tmp_path / "seq.h5") as ds:
        got = ds.events(0, ds.duration_us)
        np.testing.assert_array_equal(got.p, events["p"])
        np.testing.assert_array_equal(got.t + ds.t_offset_us, events["t"])


def _boxes(path: Path, n: int) -> Path:
    path.write_text("".join(f"{10 + k},{12 + k},20,16\n" for k in range(n)))  # FE108's groundtruth_rect.txt
    return path


def test_fe108_box_times_from_the_frame_track(tmp_path):
    out = tmp_path / "seq.h5"
    assert main(["import", str(FE108_LIKE), "--boxes", str(_boxes(tmp_path / "groundtruth_rect.txt", 6)),
                 "--box-times-from-frames", "-o", str(out)]) == 0
    frames = 1_600_000_000_000_000 + np.arange(6) * 50_000 + 1_000  # as make_fe108_like.py wrote them
    with Dataset(out) as ds:
        assert (ds.width, ds.height, ds.num_events, ds.annotated) == (W, H, 1_200, True)
        track = ds.boxes()
        np.testing.assert_array_equal(track.t + ds.t_offset_us, frames)
        np.testing.assert_array_equal(track.xywh[:, 0], 10 + np.arange(6))
        assert ds.t_offset_us <= frames[0]


def test_box_times_from_frames_errors(tmp_path, capsys):
    out = tmp_path / "seq.h5"
    assert main(["import", str(FE108_LIKE), "--boxes", str(_boxes(tmp_path / "five.txt", 5)),
                 "--box-times-from-frames", "-o", str(out)]) == 2
    one_error_line(capsys, "five.txt", "5 boxes for the 6 frames", str(FE108_LIKE))
    times = tmp_path / "times.txt"
    times.write_text("1\n2\n")
    assert main(["import", str(FE108_LIKE), "--boxes", str(tmp_path / "five.txt"), "--box-times-us", str(times),
                 "--box-times-from-frames", "-o", str(out)]) == 2
    one_error_line(capsys, "--box-times-us", "--box-times-from-frames", "not both")
    raw = tmp_path / "exp.raw"
    Wizard(encoding="evt2").save(str(raw), expelliarmus_events())
    assert main(["import", str(raw), "--size", f"{W}x{H}", "--evt", "2", "--boxes", str(tmp_path / "five.txt"),
                 "--box-times-from-frames", "-o", str(out)]) == 2
    one_error_line(capsys, str(raw), "not a .aedat4 file")
    assert not out.exists()


@pytest.mark.parametrize("words, where", [
    ([0x8000 | 4094, 0x6000 | 5, 0x6000 | 4000, 0x8000 | 0], "time-high word 3 wraps from 4094 to 0"),
    ([0x8000 | 1, 0x6000 | 4000, 0x2000 | 3, 0x6000 | 10], "time-low word 3 wraps from 4000 to 10"),
    ([0x8000 | 4095, 0x6000 | 1, 0x6000 | 1, 0x6000 | 0, 0x8000 | 0, 0x6000 | 2], None),  # 1 us of jitter is fine
])
def test_evt3_time_words_by_hand(tmp_path, words, where):
    from dvsot.interop.event_files import evt3_time_problem

    path = tmp_path / "hand.raw"
    path.write_bytes(b"% evt 3.0\n% geometry 64x48\n" + np.array(words, "<u2").tobytes())
    for chunk in (1, 2, 1 << 24):  # one word a chunk: every comparison crosses a chunk boundary
        problem = evt3_time_problem(path, words_per_chunk=chunk)
        assert (problem is None) if where is None else (where in problem), (chunk, problem)
