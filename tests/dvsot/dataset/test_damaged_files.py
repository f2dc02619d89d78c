"""Damaged or inconsistent dataset files: each gives one UserError line naming the file and the field; checksums."""

from __future__ import annotations

import shutil

import h5py
import numpy as np
import pytest

from dvsot.cli.info import summarise
from dvsot.core.errors import UserError
from dvsot.dataset import Dataset, DatasetWriter, find_datasets
from dvsot.events import EventBatch

W, H, N, DURATION_US = 64, 48, 20_000, 100_000


def write_valid(path, checksum: bool = True) -> EventBatch:
    """A small valid file (64x48 px, 100 ms, 10 segments of 10 ms); returns the events written."""
    rng = np.random.default_rng(7)
    ev = EventBatch(rng.integers(0, W, N).astype(np.uint16), rng.integers(0, H, N).astype(np.uint16),
                    np.sort(rng.integers(0, DURATION_US - 5_000, N)).astype(np.int64),
                    rng.integers(0, 2, N).astype(np.uint8), rng.random(N) > 0.1)
    with DatasetWriter(path, W, H, segment_us=10_000, checksum=checksum) as w:
        for idx in np.array_split(np.arange(N), 4):
            w.append_events(ev.select(idx))
        t = np.arange(0, DURATION_US + 1, 2500)
        w.append_boxes(t, np.tile([5.0, 5.0, 10.0, 8.0], (len(t), 1)))
        w.close(DURATION_US)
    return ev


@pytest.fixture(scope="module")
def pristine(tmp_path_factory):
    path = tmp_path_factory.mktemp("pristine") / "seq.h5"
    write_valid(path)
    return path


def damaged_copy(pristine, tmp_path, damage) -> str:
    """A copy of the pristine file with `damage(h5py.File)` applied."""
    path = tmp_path / "bad.h5"
    shutil.copy(pristine, path)
    with h5py.File(path, "a") as f:
        damage(f)
    return path


def load_everything(path) -> None:
    """Open the file and read it the ways info, bench and train do: segments, boxes, a full scan."""
    with Dataset(path) as ds:
        for _ in ds.segments():
            pass
        ds.boxes()
        ds.verify()


def assert_one_line_error(path, field: str, words: str = "") -> str:
    with pytest.raises(UserError) as info:
        load_everything(path)
    msg = str(info.value)
    assert str(path) in msg and field in msg and "\n" not in msg, msg
    assert words in msg, msg
    return msg


def _set_attr(name, value):
    return lambda f: f.attrs.__setitem__(name, value)


def _replace(name, data):
    def damage(f):
        del f[name]
        f.create_dataset(name, data=data)
    return damage


def _write(name, fn):
    def damage(f):
        d = f[name]
        d[...] = fn(d[()])
    return damage


def _swap_two_times(t):
    t = t.copy()
    t[[5000, 5001]] = t[5001] + 1, t[5000]
    return t


def _as_group(name):
    def damage(f):
        del f[name]
        f.create_group(name)
    return damage


def _shift_one_ms(m):
    m = m.copy()
    m[40] = m[41]  # still non-decreasing, but not the index of the first event at 40 ms
    return m


CASES = {
    "segment_us_zero": (_set_attr("segment_us", 0), "'segment_us'", "expected >= 1"),
    "width_negative": (_set_attr("width", -640), "'width'", "expected >= 1"),
    "height_zero": (_set_attr("height", 0), "'height'", "expected >= 1"),
    "width_text": (_set_attr("width", "abc"), "'width'", "expected an integer"),
    "duration_negative": (_set_attr("duration_us", -1000), "'duration_us'", "-1000"),
    "duration_huge": (_set_attr("duration_us", 10 ** 15), "'duration_us'", "disagrees"),
    "num_events_wrong": (_set_attr("num_events", 5), "'num_events'", "20000 rows"),
    "t_is_group": (_as_group("events/t"), "/events/t", "group, not a dataset"),
    "x_strings": (_replace("events/x", np.array([b"a"] * N)), "/events/x", "dtype"),
    "p_float": (_replace("events/p", np.full(N, 0.5)), "/events/p", "dtype"),
    "p_short": (_replace("events/p", np.zeros(N - 10, np.uint8)), "/events/p", "rows"),
    "boxes_3_columns": (_replace("boxes/xywh", np.zeros((41, 3), np.float32)), "/boxes/xywh", "shape"),
    "x_out_of_sensor": (_write("events/x", lambda x: np.full_like(x, 60000)), "/events/x", "x < width 64"),
    "y_out_of_sensor": (_write("events/y", lambda y: np.where(np.arange(N) == 7000, H, y)), "/events/y",
                        "event 7000"),
    "p_is_2": (_write("events/p", lambda p: np.where(np.arange(N) == 12345, 2, p)), "/events/p", "0 or 1"),
    "signal_is_3": (_write("events/signal", lambda s: np.where(np.arange(N) == 3, 3, s)), "/events/signal",
                    "0 or 1"),
    "t_reversed": (_write("events/t", lambda t: t[::-1]), "/events/t", ""),
    "t_two_swapped": (_write("events/t", _swap_two_times), "/events/t", "time order"),
    "t_garbage_value": (_write("events/t", lambda t: np.where(np.arange(N) == 9000, -(2 ** 62), t)),
                        "/events/t", ""),
    "t_beyond_duration": (_write("events/t", lambda t: t + DURATION_US), "/events/t", "duration_us"),
    "ms_to_idx_decreasing": (_write("events/ms_to_idx", lambda m: m[::-1]), "/events/ms_to_idx", ""),
    "ms_to_idx_shifted": (_write("events/ms_to_idx", _shift_one_ms), "/events/ms_to_idx", ""),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_damaged_file_gives_one_line_naming_file_and_field(pristine, tmp_path, case):
    damage, field, words = CASES[case]
    assert_one_line_error(damaged_copy(pristine, tmp_path, damage), field, words)


def test_info_scans_the_whole_file_and_reports_damage(pristine, tmp_path):
    # a bad value in the middle of the file: opening alone cannot see it, info's full scan must
    path = damaged_copy(pristine, tmp_path, _write("events/x", lambda x: np.where(np.arange(N) == 9999, W, x)))
    Dataset(path).close()
    with pytest.raises(UserError, match=r"/events/x holds 64 at event 9999"):
        summarise(str(path))


def test_writer_checksums_every_dataset(pristine):
    with h5py.File(pristine) as f:
        names = []
        f.visititems(lambda name, obj: names.append(name) if isinstance(obj, h5py.Dataset) else None)
        # /t_offset is a scalar, as DSEC stores it: HDF5 checksums chunks, and a scalar has none
        chunked = [name for name in names if f[name].shape != ()]
        assert chunked == [name for name in names if name != "t_offset"]
        assert len(chunked) >= 12 and all(f[name].fletcher32 for name in chunked), names


def _flip_byte_in_chunk(path, name: str) -> None:
    """Invert one byte in the middle of the first stored chunk of dataset `name`, on disk."""
    with h5py.File(path) as f:
        info = f[name].id.get_chunk_info(0)
    with open(path, "r+b") as fh:
        fh.seek(info.byte_offset + info.size // 2)
        byte = fh.read(1)
        fh.seek(-1, 1)
        fh.write(bytes([byte[0] ^ 0xFF]))


@pytest.mark.parametrize("name", ["events/t", "events/x", "events/p", "boxes/xywh", "segments/xywh",
                                  "events/ms_to_idx"])
def test_flipped_byte_in_a_checksummed_chunk_is_a_user_error(pristine, tmp_path, name):
    path = tmp_path / "flipped.h5"
    shutil.copy(pristine, path)
    _flip_byte_in_chunk(path, name)
    assert_one_line_error(path, f"/{name}", "corrupt")


def test_files_without_checksums_still_load(tmp_path):
    path = tmp_path / "old.h5"
    ev = write_valid(path, checksum=False)
    with h5py.File(path) as f:
        assert not f["events/t"].fletcher32
    with Dataset(path) as ds:
        got = EventBatch.concatenate(list(ds.chunks(step=3000)))
        assert sum(len(s.events) for s in ds.segments()) == N
    for col in ("x", "y", "t", "p", "signal"):
        np.testing.assert_array_equal(getattr(got, col), getattr(ev, col))
    load_everything(path)


def test_find_datasets_verifies_the_files_bench_and_train_will_use(pristine, tmp_path):
    # bench and train pick their files with find_datasets: a damaged one must stop them before any output
    path = damaged_copy(pristine, tmp_path, _write("events/p", lambda p: np.where(np.arange(N) == 15000, 9, p)))
    with pytest.raises(UserError, match=r"bad\.h5: .*/events/p holds 9 at event 15000"):
        find_datasets(tmp_path)
    assert find_datasets(tmp_path, verify=False) == [path]
