"""Prophesee files (DAT, EVT 2, EVT 3) whose stored times step back, whose last record is cut, or whose header
states a size out of bounds are refused in one line, never rewritten to the time before them."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from dvsot.core.errors import UserError
from dvsot.interop.event_files import _header_bytes, read_event_file, write_event_file

T = np.array([100, 200, 500, 15990, 16000], np.int64)
X = np.array([1, 2, 3, 4, 5])
Y = np.ones(5, np.int64)
P = np.array([0, 1, 0, 1, 0])


def _split(path: Path) -> tuple[bytes, bytes]:
    data = path.read_bytes()
    n = _header_bytes(path)
    return data[:n], data[n:]


def test_dat_time_stepping_back_is_refused_naming_the_event(tmp_path: Path) -> None:
    src = tmp_path / "a.dat"
    write_event_file(src, T, X, Y, P, 32, 32)
    head, body = _split(src)
    records = np.frombuffer(body[2:], "<u4").reshape(-1, 2).copy()
    records[4, 0] = 400  # 15,900 us after T0 -> 400 us
    bad = tmp_path / "b.dat"
    bad.write_bytes(head + body[:2] + records.tobytes())
    with pytest.raises(UserError, match=r"b\.dat: event 4: .*400 us.*earlier than the event before it"):
        read_event_file(bad)
    records[4, 0] = records[3, 0]  # equal times stay allowed
    bad.write_bytes(head + body[:2] + records.tobytes())
    assert list(read_event_file(bad).t) == [100, 200, 500, 15990, 15990]


def test_dat_truncated_last_event_is_refused(tmp_path: Path) -> None:
    src = tmp_path / "a.dat"
    write_event_file(src, T, X, Y, P, 32, 32)
    cut = tmp_path / "cut.dat"
    cut.write_bytes(src.read_bytes()[:-3])
    with pytest.raises(UserError, match=r"cut\.dat: the file ends 5 bytes into event 4 .*truncated"):
        read_event_file(cut)


@pytest.mark.parametrize("suffix", ["dat", "raw"])
def test_header_size_out_of_bounds_is_named(tmp_path: Path, suffix: str) -> None:
    src = tmp_path / f"a.{suffix}"
    write_event_file(src, T, X, Y, P, 32, 32, "evt2")
    head, body = _split(src)
    huge = tmp_path / f"huge.{suffix}"
    huge.write_bytes(head.replace(b"32", b"100000") + body)
    with pytest.raises(UserError) as info:
        read_event_file(huge)
    assert "100000x100000" in str(info.value) and "no sensor size" not in str(info.value)


def test_evt2_time_stepping_back_is_refused(tmp_path: Path) -> None:
    src = tmp_path / "a.raw"
    write_event_file(src, np.array([100, 200, 15990, 15991, 16000]), X, Y, P, 32, 32, "evt2")
    head, body = _split(src)
    words = np.frombuffer(body, "<u4").copy()
    events = np.flatnonzero((words >> 28) < 2)
    words[events[3]] &= ~np.uint32(63 << 22)  # 15,991 -> 15,936 us: back within one time-high period
    bad = tmp_path / "b.raw"
    bad.write_bytes(head + words.tobytes())
    with pytest.raises(UserError, match=r"b\.raw: event 3: .*earlier than the event before it"):
        read_event_file(bad, evt_version="evt2")


def test_evt3_time_stepping_back_is_refused(tmp_path: Path) -> None:
    src = tmp_path / "a.raw"
    write_event_file(src, np.array([100, 200, 300, 400, 500]), X, Y, P, 32, 32, "evt3")
    head, body = _split(src)
    words = np.frombuffer(body, "<u2").copy()
    lows = np.flatnonzero((words >> 12) == 6)
    assert len(lows) >= 2
    words[lows[-1]] = (6 << 12) | 0  # the last time-low back to the start of its period
    bad = tmp_path / "b.raw"
    bad.write_bytes(head + words.tobytes())
    with pytest.raises(UserError, match=r"b\.raw: time-low word \d+: .*earlier than the event before it"):
        read_event_file(bad, evt_version="evt3")
