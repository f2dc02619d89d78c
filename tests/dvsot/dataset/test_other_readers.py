"""Dataset files other tools read: DSEC-style slicing with plain h5py, h5dump, gzip; version 1 files still load."""

from __future__ import annotations

import math
import shutil
import subprocess

import h5py
import numpy as np
import pytest

from dvsot.core.errors import UserError
from dvsot.dataset import Dataset, DatasetWriter
from dvsot.events import EventBatch
from tests.dvsot.dataset.test_round_trip import random_events

OFFSET = 1_600_000_123_456  # an epoch-microsecond start, as real recordings have


def dsec_slice(h5: h5py.File, t0_us: int, t1_us: int) -> dict[str, np.ndarray] | None:
    """Events of [t0_us, t1_us) on the recording's clock, the way DSEC's EventSlicer finds them (root keys only)."""
    ms_to_idx = np.asarray(h5["ms_to_idx"], dtype="int64")
    t_offset = int(h5["t_offset"][()]) if "t_offset" in h5.keys() else 0
    t0, t1 = t0_us - t_offset, t1_us - t_offset
    ms0, ms1 = math.floor(t0 / 1000), math.ceil(t1 / 1000)  # a conservative window of whole milliseconds
    if ms1 >= ms_to_idx.size:
        return None
    i0, i1 = int(ms_to_idx[ms0]), int(ms_to_idx[ms1])
    t = np.asarray(h5["events/t"][i0:i1])
    j0, j1 = np.searchsorted(t, t0, "left"), np.searchsorted(t, t1, "left")
    out = {"t": t[j0:j1] + t_offset}
    for name in ("x", "y", "p"):
        out[name] = np.asarray(h5[f"events/{name}"][i0 + j0:i0 + j1])
    return out


@pytest.fixture
def recorded(tmp_path):
    ev = random_events(np.random.default_rng(3), 30_000, 195_000)
    path = tmp_path / "rec.h5"
    with DatasetWriter(path, 64, 48, t_offset_us=OFFSET) as w:
        for idx in np.array_split(np.arange(len(ev)), 5):
            w.append_events(ev.select(idx))
        w.append_boxes([0, 200_000], [[1, 2, 3, 4], [5, 6, 7, 8]])
        w.close(200_000)
    return path, ev


def test_root_link_offset_and_gzip(recorded):
    path, _ = recorded
    with h5py.File(path) as f:
        assert f["ms_to_idx"].id == f["events/ms_to_idx"].id  # one table under two names, not a copy
        assert f["t_offset"].shape == () and int(f["t_offset"][()]) == OFFSET
        assert f["events/t"].compression == "gzip" and f["events/t"].compression_opts == 1 and f["events/t"].shuffle
        assert f.attrs["format_version"] == 2
    with Dataset(path) as ds:
        assert ds.t_offset_us == OFFSET and ds.format_version == 2


def test_dsec_style_slices_match_the_reader(recorded):
    path, ev = recorded
    rng = np.random.default_rng(1)
    with h5py.File(path) as f, Dataset(path) as ds:
        for _ in range(100):
            a = int(rng.integers(0, 190_000))
            b = a + int(rng.integers(1, 10_000))
            got = dsec_slice(f, a + OFFSET, b + OFFSET)
            want = ds.events(a, b)
            keep = (ev.t >= a) & (ev.t < b)
            assert len(want) == keep.sum()
            np.testing.assert_array_equal(got["t"], want.t + OFFSET)
            for name in ("x", "y", "p"):
                np.testing.assert_array_equal(got[name], getattr(want, name))


@pytest.mark.skipif(shutil.which("h5dump") is None, reason="h5dump (hdf5-tools) is not installed")
def test_h5dump_reads_the_events(recorded, tmp_path):
    path, ev = recorded
    out = tmp_path / "t.txt"
    # -o writes the values alone; -y drops indices, -w0 one long line: the plain list of numbers
    subprocess.run(["h5dump", "-d", "/events/t", "-y", "-w", "0", "-o", str(out), str(path)],
                   check=True, capture_output=True)
    values = np.array(out.read_text().replace(",", " ").split(), dtype=np.int64)
    np.testing.assert_array_equal(values, ev.t)


def _as_version_1(path) -> None:
    """Turn a file into what the version 1 writer wrote: LZF events, no root /ms_to_idx, no /t_offset."""
    with h5py.File(path, "a") as f:
        del f["ms_to_idx"], f["t_offset"]
        f.attrs["format_version"] = 1
        for name in ("attrs_sha256", "ground_truth"):  # added after version 1
            if name in f.attrs:
                del f.attrs[name]


def test_version_1_files_still_load(tmp_path):
    ev = random_events(np.random.default_rng(5), 5_000, 95_000)
    path = tmp_path / "old.h5"
    with DatasetWriter(path, 64, 48, compression="lzf") as w:
        w.append_events(ev)
        w.append_boxes([0, 100_000], [[1, 2, 3, 4], [5, 6, 7, 8]])
        w.close(100_000)
    _as_version_1(path)
    with h5py.File(path) as f:
        assert f["events/t"].compression == "lzf" and "ms_to_idx" not in f and "t_offset" not in f
    with Dataset(path) as ds:
        assert ds.format_version == 1 and ds.t_offset_us == 0
        np.testing.assert_array_equal(ds.events(0, 100_000).t, ev.t)
        ds.verify()


@pytest.mark.parametrize("damage, words", [
    (lambda f: f.__delitem__("t_offset"), "missing /t_offset"),
    (lambda f: (f.__delitem__("t_offset"), f.create_dataset("t_offset", data=[1, 2])), "/t_offset is not a scalar"),
    (lambda f: (f.__delitem__("ms_to_idx"), f.create_dataset("ms_to_idx", data=np.arange(201, dtype=np.uint64))),
     "/ms_to_idx differs from /events/ms_to_idx"),
])
def test_bad_root_entries_name_the_field(recorded, tmp_path, damage, words):
    path, _ = recorded
    bad = tmp_path / "bad.h5"
    shutil.copy(path, bad)
    with h5py.File(bad, "a") as f:
        damage(f)
    with pytest.raises(UserError, match=words) as info:
        Dataset(bad)
    assert str(bad) in str(info.value) and "\n" not in str(info.value)


def test_writer_refuses_epoch_timestamps_before_allocating(tmp_path):
    ev = EventBatch(
        np.zeros(2, np.uint16), np.zeros(2, np.uint16), np.array([OFFSET, OFFSET + 5]), np.ones(2, np.uint8)
    )
    with pytest.raises(ValueError, match="rebase the timestamps and keep the start in t_offset_us"):
        with DatasetWriter(tmp_path / "epoch.h5", 64, 48) as w:
            w.append_events(ev)
    assert list(tmp_path.iterdir()) == []


def test_text_attributes_read_back_as_str(tmp_path):
    path = tmp_path / "seq.h5"
    with DatasetWriter(path, 64, 48, attrs={"name": "Straße 5", "split": "test", "simulator": {"model": "v2e"}}) as w:
        w.close(10_000)
    with Dataset(path) as ds:
        assert type(ds.attrs["name"]) is str and ds.attrs["name"] == ds.name == "Straße 5"
        assert type(ds.attrs["format"]) is str and type(ds.attrs["split"]) is str
        assert type(ds.attrs["simulator"]["model"]) is str
        text = [k for k, v in ds.attrs.items() if isinstance(v, (bytes, np.bytes_))]
        assert text == []
    with h5py.File(path) as f:  # plain h5py: fixed-length UTF-8 comes back as bytes, as docs/dataset-files.md says
        assert f.attrs["name"].decode("utf-8") == "Straße 5"
