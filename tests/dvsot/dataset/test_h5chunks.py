"""Chunks encoded outside HDF5 (dvsot.dataset.h5chunks) are the bytes HDF5's filters store; the writer's files read
back."""

from __future__ import annotations

import zlib

import h5py
import numpy as np
import pytest

from dvsot.dataset import DatasetWriter, open_dataset
from dvsot.dataset.h5chunks import encode_chunk, fletcher32, shuffle
from dvsot.events import EventBatch


def _fletcher_loop(data: bytes) -> int:
    """HDF5's H5_checksum_fletcher32, word by word with its folds every 360 words."""
    n, s1, s2, i = len(data) // 2, 0, 0, 0
    while n:
        block = min(n, 360)
        n -= block
        for _ in range(block):
            s1 += (data[i] << 8) | data[i + 1]
            i += 2
            s2 += s1
        s1, s2 = (s1 & 0xFFFF) + (s1 >> 16), (s2 & 0xFFFF) + (s2 >> 16)
    if len(data) % 2:
        s1 += data[i] << 8
        s2 += s1
        s1, s2 = (s1 & 0xFFFF) + (s1 >> 16), (s2 & 0xFFFF) + (s2 >> 16)
    s1, s2 = (s1 & 0xFFFF) + (s1 >> 16), (s2 & 0xFFFF) + (s2 >> 16)
    return (s2 << 16) | s1


def test_fletcher32_matches_hdf5s_loop():
    rng = np.random.default_rng(3)
    cases = [b"", b"\x00", b"\xff", b"\xff\xff", b"\x00\x00\xff\xff", b"\xff\xff" * 1000, b"\xff" * 721, b"\x01" * 5]
    cases += [rng.integers(0, 256, int(rng.integers(1, 3000)), dtype=np.uint8).tobytes() for _ in range(60)]
    for data in cases:
        assert fletcher32(data) == _fletcher_loop(data), len(data)


def test_shuffle_is_bytes_grouped_by_position():
    v = np.array([0x0102, 0x0304, 0x0506], np.uint16)
    assert shuffle(v).tolist() == [0x02, 0x04, 0x06, 0x01, 0x03, 0x05]  # little-endian: low bytes first
    assert shuffle(np.arange(5, dtype=np.uint8)).tolist() == [0, 1, 2, 3, 4]


@pytest.mark.parametrize("dtype", [np.uint16, np.int64, np.uint8])
@pytest.mark.parametrize("n", [4096, 4000, 1])
def test_chunk_is_the_bytes_hdf5_stores(tmp_path, dtype, n):
    """With zlib's deflate the encoded chunk is HDF5's own, byte for byte (shuffle, level 1, Fletcher-32, padding)."""
    rng = np.random.default_rng(n)
    values = np.cumsum(rng.integers(0, 3, n)).astype(dtype) if dtype == np.int64 else \
        rng.integers(0, 300, n).astype(dtype)
    with h5py.File(tmp_path / "c.h5", "w") as f:
        ds = f.create_dataset("v", data=values, chunks=(4096,), maxshape=(None,), compression="gzip",
                              compression_opts=1, shuffle=True, fletcher32=True)
        _, stored = ds.id.read_direct_chunk((0,))
    assert encode_chunk(values, 4096, compress=lambda b: zlib.compress(b, 1)) == stored


def test_writer_chunks_read_back_through_hdf5(tmp_path):
    """Batches of uneven sizes over several chunks: the file's events are the ones appended, read by HDF5's filters."""
    rng = np.random.default_rng(1)
    n = (1 << 18) * 2 + 12345
    t = np.sort(rng.integers(0, 900_000, n))
    ev = EventBatch(rng.integers(0, 640, n).astype(np.uint16), rng.integers(0, 480, n).astype(np.uint16), t,
                    rng.integers(0, 2, n).astype(np.uint8), rng.random(n) < 0.9)
    cuts = np.sort(rng.integers(0, n, 40))
    with DatasetWriter(tmp_path / "w.h5", 640, 480) as w:
        for a, b in zip(np.r_[0, cuts], np.r_[cuts, n]):
            w.append_events(ev.select(slice(a, b)))
        w.close(1_000_000)
    with h5py.File(tmp_path / "w.h5") as f:
        for name in "xytp":
            assert f["events/" + name].compression == "gzip" and f["events/" + name].fletcher32
            assert np.array_equal(f["events/" + name][:], getattr(ev, name))
        assert np.array_equal(f["events/signal"][:], ev.signal.view(np.uint8))
    with open_dataset(tmp_path / "w.h5") as ds:
        got = ds.events(0, 1_000_000)
    assert np.array_equal(got.t, t) and np.array_equal(got.x, ev.x)
