"""Dataset file: round trip, ms_to_idx, time queries, segments, atomic writes, clean errors on bad files."""

from __future__ import annotations

import h5py
import numpy as np
import pytest

from dvsot.core.errors import UserError
from dvsot.dataset import FORMAT_VERSION, Dataset, DatasetWriter, find_datasets
from dvsot.events import EventBatch


def random_events(rng: np.random.Generator, n: int, t_max_us: int, signal: bool = True) -> EventBatch:
    t = np.sort(rng.integers(0, t_max_us, n)).astype(np.int64)
    return EventBatch(rng.integers(0, 64, n).astype(np.uint16), rng.integers(0, 48, n).astype(np.uint16), t,
                      rng.integers(0, 2, n).astype(np.uint8), rng.random(n) > 0.1 if signal else None)


def write_file(path, events: EventBatch, duration_us: int, batches: int = 7, **attrs) -> None:
    with DatasetWriter(path, 64, 48, segment_us=10_000, attrs=attrs) as w:
        for idx in np.array_split(np.arange(len(events)), batches):
            w.append_events(events.select(idx))
        t = np.arange(0, duration_us + 1, 2500)
        xywh = np.stack([t / 1000.0, np.full(len(t), 5.0), np.full(len(t), 10.0), np.full(len(t), 8.0)], 1)
        w.append_boxes(t, xywh)
        w.close(duration_us)


@pytest.fixture
def sample(tmp_path):
    rng = np.random.default_rng(0)
    ev = random_events(rng, 20_000, 95_000)
    path = tmp_path / "seq.h5"
    write_file(path, ev, 100_000, name="seq", split="test", simulator={"cp": 0.2})
    return path, ev


def test_round_trip_events_attrs_and_boxes(sample):
    path, ev = sample
    with Dataset(path) as ds:
        assert (ds.width, ds.height, ds.segment_us, ds.duration_us) == (64, 48, 10_000, 100_000)
        assert ds.num_events == len(ev) and ds.name == "seq" and ds.split == "test"
        assert ds.attrs["simulator"] == {"cp": 0.2} and ds.attrs["format_version"] == FORMAT_VERSION
        got = ds.events(0, 100_000)
        for col in ("x", "y", "t", "p", "signal"):
            np.testing.assert_array_equal(getattr(got, col), getattr(ev, col))
        assert got.x.dtype == np.uint16 and got.t.dtype == np.int64 and got.p.dtype == np.uint8
        track = ds.boxes()
        assert track.t[0] == 0 and track.t[-1] == 100_000 and track.xywh.shape == (41, 4)
        np.testing.assert_array_equal(track.xywh, track.xywh_visible)


def test_ms_to_idx_agrees_with_brute_force(sample):
    path, ev = sample
    with h5py.File(path) as f:
        ms_to_idx = f["events/ms_to_idx"][()]
    assert len(ms_to_idx) == 101
    brute = np.array([np.count_nonzero(ev.t < ms * 1000) for ms in range(101)])
    np.testing.assert_array_equal(ms_to_idx, brute)


def test_time_window_queries_match_brute_force(sample):
    path, ev = sample
    rng = np.random.default_rng(1)
    with Dataset(path) as ds:
        for _ in range(200):
            t0, t1 = np.sort(rng.integers(-10, 101_000, 2))
            got = ds.events(int(t0), int(t1))
            want = (ev.t >= t0) & (ev.t < t1)
            np.testing.assert_array_equal(got.t, ev.t[want])
            np.testing.assert_array_equal(got.x, ev.x[want])


def test_segments_cover_the_sequence_with_ground_truth_at_their_end(sample):
    path, ev = sample
    with Dataset(path) as ds:
        segs = list(ds.segments())
        assert ds.num_segments == len(segs) == 10
        assert sum(len(s.events) for s in segs) == len(ev)
        for s in segs:
            assert s.t1_us - s.t0_us == 10_000
            assert np.all((s.events.t >= s.t0_us) & (s.events.t < s.t1_us))
            # the box's x moves 1 px per ms in write_file
            np.testing.assert_allclose(s.box, [s.t1_us / 1000.0, 5, 10, 8], atol=1e-4)
        np.testing.assert_allclose(ds.segment_boxes()[3], segs[3].box)
        assert len(list(ds.segments(start=8))) == 2


def test_events_without_signal_flags_and_empty_sequence(tmp_path):
    rng = np.random.default_rng(2)
    ev = random_events(rng, 100, 5_000, signal=False)
    write_file(tmp_path / "a.h5", ev, 20_000, batches=3)
    with Dataset(tmp_path / "a.h5") as ds:
        assert ds.events(0, 20_000).signal is None
        assert np.all(np.isnan(ds.segment(1).box)) is np.False_  # boxes exist
    with DatasetWriter(tmp_path / "empty.h5", 8, 8) as w:
        w.close(25_000)
    with Dataset(tmp_path / "empty.h5") as ds:
        assert ds.num_events == 0 and ds.num_segments == 2 and np.all(np.isnan(ds.segment_boxes()))
        assert len(ds.segment(0).events) == 0


def test_out_of_order_events_are_refused(tmp_path):
    w = DatasetWriter(tmp_path / "bad.h5", 8, 8)
    one = EventBatch(np.zeros(1, np.uint16), np.zeros(1, np.uint16), np.array([500]), np.ones(1, np.uint8))
    w.append_events(one)
    with pytest.raises(ValueError):
        w.append_events(EventBatch(one.x, one.y, np.array([100]), one.p))
    w.abort()
    assert list(tmp_path.iterdir()) == []


def test_interrupted_write_leaves_no_file_and_keeps_an_existing_one(tmp_path, sample):
    path, _ = sample
    before = path.read_bytes()
    with pytest.raises(RuntimeError):
        with DatasetWriter(path, 64, 48) as w:
            w.append_events(random_events(np.random.default_rng(3), 10, 1000))
            raise RuntimeError("render failed")
    assert path.read_bytes() == before
    assert sorted(p.name for p in path.parent.iterdir()) == ["seq.h5"]


def test_foreign_truncated_and_damaged_files_give_one_line_errors(tmp_path, sample):
    path, _ = sample
    text = tmp_path / "notes.h5"
    text.write_text("hello")
    foreign = tmp_path / "foreign.h5"
    with h5py.File(foreign, "w") as f:
        f["x"] = np.arange(3)
    truncated = tmp_path / "truncated.h5"
    truncated.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
    damaged = tmp_path / "damaged.h5"
    damaged.write_bytes(path.read_bytes())
    with h5py.File(damaged, "a") as f:
        del f["events/ms_to_idx"]
    newer = tmp_path / "newer.h5"
    newer.write_bytes(path.read_bytes())
    with h5py.File(newer, "a") as f:
        f.attrs["format_version"] = FORMAT_VERSION + 1
    for bad, words in [(text, "not a readable HDF5"), (foreign, "not a dvsot dataset"),
                       (damaged, "missing /events/ms_to_idx"), (newer, "format_version"),
                       (tmp_path / "absent.h5", "no such dataset file")]:
        with pytest.raises(UserError, match=words) as info:
            Dataset(bad)
        assert "\n" not in str(info.value) and str(bad) in str(info.value)
    with pytest.raises(UserError):  # truncated: fails on open or on the first read, never a traceback
        with Dataset(truncated) as ds:
            ds.events(0, ds.duration_us)


def test_the_read_back_compares_every_stored_chunk_with_the_one_written(tmp_path, monkeypatch):
    from dvsot.core.errors import RunError
    from dvsot.dataset import writer as writer_module

    rng = np.random.default_rng(2)
    path = tmp_path / "seq.h5"
    write_file(path, random_events(rng, 500, 95_000), 100_000, name="old")
    before = path.read_bytes()
    digest = writer_module.chunk_digest
    seen = []

    def flipped(data: bytes) -> bytes:  # as if HDF5 stored /events/y's chunk with a flipped bit
        seen.append(len(data))
        return digest(data[:-1] + bytes([data[-1] ^ 1])) if len(seen) == 2 else digest(data)  # columns x, y, t, p

    monkeypatch.setattr(writer_module, "chunk_digest", flipped)
    with pytest.raises(
        RunError, match=r"seq\.h5: the file just written failed its read-back check.*chunk 0 of /events/y"
    ):
        write_file(path, random_events(rng, 500, 95_000), 100_000, name="new")
    assert path.read_bytes() == before and sorted(p.name for p in tmp_path.iterdir()) == ["seq.h5"]
    monkeypatch.setattr(writer_module, "chunk_digest", digest)
    write_file(path, random_events(rng, 500, 95_000), 100_000, name="new")  # and an intact one lands
    with Dataset(path) as ds:
        assert ds.attrs["name"] == "new"
        ds.verify()


def test_events_off_the_sensor_are_refused_when_appended(tmp_path):
    ev = EventBatch(
        np.array([0, 64], np.uint16), np.array([0, 1], np.uint16), np.array([5, 6]), np.array([1, 0], np.uint8)
    )
    with pytest.raises(ValueError, match="event x must lie in 0..63"):
        with DatasetWriter(tmp_path / "a.h5", 64, 48) as w:
            w.append_events(ev)
    assert list(tmp_path.iterdir()) == []


def test_find_datasets_in_a_directory_skips_a_file_another_run_is_writing(tmp_path):
    rng = np.random.default_rng(5)
    write_file(tmp_path / "a.h5", random_events(rng, 50, 9_000), 10_000)
    w = DatasetWriter(tmp_path / "b.h5", 64, 48)  # staged as a hidden temp beside b.h5 until it closes
    try:
        assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".b.h5.tmp")]
        assert [p.name for p in find_datasets(tmp_path)] == ["a.h5"]
    finally:
        w.abort()


def test_find_datasets_by_directory_glob_list_and_split(tmp_path):
    rng = np.random.default_rng(4)
    for name, split in [("a", "train"), ("b", "test"), ("c", "train")]:
        write_file(tmp_path / f"{name}.h5", random_events(rng, 50, 9_000), 10_000, split=split)
    assert [p.name for p in find_datasets(tmp_path)] == ["a.h5", "b.h5", "c.h5"]
    assert [p.name for p in find_datasets(str(tmp_path / "*.h5"), split="train")] == ["a.h5", "c.h5"]
    assert [p.name for p in find_datasets([tmp_path / "b.h5"])] == ["b.h5"]
    with pytest.raises(UserError, match="split 'val'"):
        find_datasets(tmp_path, split="val")
    with pytest.raises(UserError, match="no such file"):
        find_datasets(tmp_path / "nope")


def test_a_file_that_fails_its_read_back_never_replaces_the_old_one(tmp_path, monkeypatch):
    from dvsot.core.errors import RunError

    rng = np.random.default_rng(1)
    path = tmp_path / "seq.h5"
    write_file(path, random_events(rng, 500, 95_000), 100_000, name="old")
    before = path.read_bytes()

    def corrupt_chunk(self, stored=None):  # what a chunk failing its Fletcher-32 checksum looks like to the reader
        raise self._damaged("cannot read /events/y events 0..499, its stored data is corrupt")

    monkeypatch.setattr(Dataset, "verify", corrupt_chunk)
    with pytest.raises(RunError, match=r"seq\.h5: the file just written failed its read-back check.*/events/y"):
        write_file(path, random_events(rng, 500, 95_000), 100_000, name="new")
    assert path.read_bytes() == before and sorted(p.name for p in tmp_path.iterdir()) == ["seq.h5"]
