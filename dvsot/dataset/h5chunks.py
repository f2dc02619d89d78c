"""HDF5 chunks encoded outside HDF5: byte shuffle, deflate and Fletcher-32, as HDF5's own filters store them.

The dataset writer's event columns use HDF5's shuffle, deflate (gzip) and Fletcher-32 filters. Run by
HDF5 they take a global lock and zlib's deflate, the writer's largest cost for dense output; here the
same filtered bytes are made with ISA-L's deflate (a standard zlib stream, several times faster than
zlib at level 1 for about the same size; it releases the GIL) and handed to HDF5 as whole chunks
(h5py's write_direct_chunk). Any HDF5 reader decodes them with its own filters: the file is the same
format, only the deflate stream's bytes differ from zlib's.
"""

from __future__ import annotations

import numpy as np

_ISAL_LEVEL = 1  # ISA-L's levels run 0-3; 1 gives zlib level 1's size (benchmarks/perf/bench_compression.py)
_PIECE = 1 << 20  # 16-bit words summed in one int64 dot product: 65535 * 2**40 / 2 < 2**63


def shuffle(values: np.ndarray) -> np.ndarray:
    """HDF5's shuffle filter: byte k of every element, for k = 0 .. itemsize-1, as one uint8 array."""
    a = np.ascontiguousarray(values)
    if a.itemsize == 1:  # HDF5 leaves one-byte types as they are
        return a.view(np.uint8).reshape(-1)
    return np.ascontiguousarray(a.view(np.uint8).reshape(-1, a.itemsize).T).reshape(-1)


def _fold(s: int) -> int:
    """HDF5's one's-complement fold of a positive sum to 16 bits: the residue mod 65535, 0 shown as 0xffff."""
    return 0 if s == 0 else (s - 1) % 65535 + 1


def fletcher32(data: bytes | np.ndarray) -> int:
    """HDF5's Fletcher-32 (H5_checksum_fletcher32) of bytes: big-endian 16-bit words, an odd last byte as a high half.

    HDF5 folds its two sums every 360 words, which keeps each congruent mod 65535 and positive once a
    word was; so the result is the closed form of the two sums' residues, summed here in int64 over
    pieces of _PIECE words (exact: a piece's weighted sum stays below 2**63) and in Python integers across them.
    """
    b = np.frombuffer(data, np.uint8) if not isinstance(data, np.ndarray) else data.view(np.uint8).reshape(-1)
    n_even = b.size & ~1
    words = (b[:n_even:2].astype(np.int64) << 8) | b[1:n_even:2]
    if b.size & 1:
        words = np.append(words, np.int64(b[-1]) << 8)
    n = words.size
    s1 = s2 = 0
    for i in range(0, n, _PIECE):
        w = words[i:i + _PIECE]
        part = int(w.sum())
        # word j (0-based) enters the prefix sums j .. n-1: n - j of them
        s2 += int(np.dot(w, np.arange(w.size, 0, -1, dtype=np.int64))) + (n - i - w.size) * part
        s1 += part
    return (_fold(s2) << 16) | _fold(s1)


def encode_chunk(values: np.ndarray, chunk_len: int, checksum: bool = True, compress=None) -> bytes:
    """One chunk of a 1-D dataset with shuffle + deflate (+ Fletcher-32) filters, as HDF5 stores it.

    values holds at most chunk_len elements; a shorter last chunk is padded with zeros (HDF5 stores
    whole chunks and reads only the dataset's extent). compress(bytes) -> a zlib stream; ISA-L's by default.
    """
    if values.ndim != 1 or values.shape[0] > chunk_len:
        raise ValueError(f"a chunk holds at most {chunk_len} elements of a 1-D array, got shape {values.shape}")
    if values.shape[0] < chunk_len:
        values = np.concatenate([values, np.zeros(chunk_len - values.shape[0], values.dtype)])
    if compress is None:
        from isal import isal_zlib

        out = isal_zlib.compress(shuffle(values), _ISAL_LEVEL)
    else:
        out = compress(shuffle(values))
    if checksum:
        out += int(fletcher32(out)).to_bytes(4, "little")  # HDF5 appends it little-endian (UINT32ENCODE)
    return out
