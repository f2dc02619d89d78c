"""Events as text: CSV (`t,x,y,p`, microseconds) and rpg/ESIM-style TXT (`t x y p`, seconds), read and written.

TXT is the layout of the rpg event-camera datasets and ESIM (timestamp in seconds, then x, y and
polarity 0/1, space-separated), with a first line `width height` as rpg_e2vid reads it; on import that
line is optional. Both are written by a vectorised formatter (no Python loop over events) and read by
numpy's C parser; every error names the file and line. Timestamps in seconds are written with 6
decimals, so microseconds round-trip exactly.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from dvsot.core.errors import UserError

_ROWS_PER_CHUNK = 1 << 20  # rows formatted at a time (about 60 MB of scratch)
# "0000" .. "9999" as one little-endian u4 each: four digits written per store
_QUADS = np.frombuffer(b"".join(b"%04d" % i for i in range(10_000)), dtype=np.uint32)
_POW10 = 10 ** np.arange(1, 19, dtype=np.int64)  # 10 .. 10^18: digit counts by search


def _digits(v: np.ndarray, top: int | None = None) -> np.ndarray:
    """Decimal digits (int8) of each non-negative int64 (1 for 0); top: the largest value, if known."""
    top = int(v.max()) if top is None else top
    out = np.ones(len(v), np.int8)
    for power in _POW10[: len(str(top)) - 1]:  # one comparison per digit the largest value has
        out += v >= power
    return out


def format_rows(fields: list[tuple[np.ndarray, int]], seps: list[bytes], end: bytes = b"\n",
                tops: list[int] | None = None, scratch: dict | None = None) -> bytes:
    """Rows of non-negative integers as text: field k, then seps[k], ...; a width of 0 is variable, w > 0 zero-padded.

    Each row is first laid out in fixed slots (every number right-aligned in a slot of whole 4-digit
    groups, each separator in a 4-byte slot of its own), then the unused leading bytes are dropped.
    tops (each field's largest value over all chunks) and a scratch dict let chunk after chunk reuse
    one layout and its buffers (a fresh buffer costs a page fault per 4 kB, as much as the formatting).
    """
    n = len(fields[0][0])
    values = [np.asarray(v, np.int64) for v, _ in fields]
    slots = []  # (quads, kept bytes per row) per slot, in row order
    for k, (v, (_, w)) in enumerate(zip(values, fields)):
        top = (int(v.max()) if n else 0) if tops is None else tops[k]
        quads = max(-(-max(len(str(top)), w) // 4), 1)
        slots.append((v, quads, _digits(v, top) if w == 0 else np.full(n, w, np.int8)))
        slots.append((seps[k] if k < len(seps) else end, 1, None))
    row_quads = sum(q for _, q, _ in slots)
    # built column by column in column-major buffers (each write contiguous), transposed once at the end
    scratch = {} if scratch is None else scratch
    if scratch.get("shape", (0, 0))[1] < n or scratch["shape"][0] != row_quads:
        scratch.update(shape=(row_quads, n), rec=np.empty((row_quads, n), np.uint32),
                       keep=np.empty((4 * row_quads, n), bool))
    rec, keep = scratch["rec"][:, :n], scratch["keep"][:, :n]
    col = 0
    for v, quads, width in slots:
        if width is None:  # a separator: its bytes at the end of its slot
            rec[col] = np.frombuffer(v.rjust(4, b"\0"), np.uint32)[0]
            keep[4 * col:4 * col + 4] = (np.arange(4) >= 4 - len(v))[:, None]
        else:
            rest = v
            for q in range(quads - 1, -1, -1):  # least significant group in the slot's last quad
                rest, group = np.divmod(rest, 10_000)
                rec[col + q] = _QUADS[group]
            nbytes = 4 * quads
            for j in range(nbytes):  # byte j of the slot holds a digit when the number has more than nbytes - j
                np.greater(width, nbytes - 1 - j, out=keep[4 * col + j])
        col += quads
    rows = np.ascontiguousarray(rec.T).view(np.uint8)  # (n, 4 * row_quads) bytes, row after row
    return rows[np.ascontiguousarray(keep.T)].tobytes()


def write_text(path: str | os.PathLike, t: np.ndarray, x: np.ndarray, y: np.ndarray, p: np.ndarray,
               width: int, height: int, kind: str, objects: np.ndarray | None = None) -> None:
    """Write events (t microseconds >= 0, pixels, polarity 0/1) as 'csv' (header t,x,y,p; with objects, the
    object id of each event as a fifth column, t,x,y,p,object) or 'txt' (seconds; no object column)."""
    t = np.asarray(t, np.int64)
    if len(t) and t.min() < 0:
        raise ValueError("text export needs timestamps >= 0")
    with open(path, "wb") as fh:
        labelled = objects is not None and kind == "csv"
        fh.write(
            (b"t,x,y,p,object\n" if labelled else b"t,x,y,p\n") if kind == "csv" else f"{width} {height}\n".encode()
        )
        if not len(t):
            return
        scratch: dict = {}
        xyp_tops = [int(np.max(x)), int(np.max(y)), int(np.max(p))]
        for i in range(0, len(t), _ROWS_PER_CHUNK):
            s = slice(i, i + _ROWS_PER_CHUNK)
            xyp = [(x[s], 0), (y[s], 0), (p[s], 0)]
            if labelled:
                fh.write(format_rows([(t[s], 0)] + xyp + [(objects[s], 0)], [b",", b",", b",", b","],
                                     tops=[int(t[-1])] + xyp_tops + [255], scratch=scratch))
            elif kind == "csv":
                fh.write(format_rows([(t[s], 0)] + xyp, [b",", b",", b","], tops=[int(t[-1])] + xyp_tops,
                                     scratch=scratch))
            else:
                fh.write(format_rows([(t[s] // 1_000_000, 0), (t[s] % 1_000_000, 6)] + xyp, [b".", b" ", b" ", b" "],
                                     tops=[int(t[-1]) // 1_000_000, 999_999] + xyp_tops, scratch=scratch))


def _data_lines(path: Path, skip: int) -> list[int]:
    """1-based numbers of the lines numpy's parser reads as data rows (after `skip` lines; blank and # lines
    skipped)."""
    numbers = []
    with open(path, "rb") as fh:
        for no, line in enumerate(fh, start=1):
            text = line.split(b"#")[0].strip()
            if no > skip and text:
                numbers.append(no)
    return numbers


def line_of_row(path: Path, skip: int, row: int) -> int:
    """The line number of data row `row` (0-based); only called on the way to an error message."""
    lines = _data_lines(path, skip)
    return lines[row] if 0 <= row < len(lines) else len(lines) + skip


CSV_HEADERS = (
    b"t,x,y,p",
    b"t,x,y,p,object",
)  # the header lines dvsot writes (without, with labels), known without --header
# |t| bounds under which float64 holds every microsecond exactly: CSV microseconds below 2**53, TXT seconds
# below 2**31 (a float's spacing there is 0.24 us, so two microseconds never share a float; epoch times until 2038)
MAX_CSV_US = 2.0 ** 53
MAX_TXT_SECONDS = 2.0 ** 31


def _header(path: Path, kind: str, header: bool = False) -> tuple[int, tuple[int, int] | None]:
    """(lines before the data, sensor size from a TXT 'width height' line or None).

    A CSV's first line is data unless `header` says it is not or it is dvsot's own 't,x,y,p' (or 't,x,y,p,object'): a
    line that is neither is parsed as an event, and fails naming its line when it is not one.
    """
    with open(path, "rb") as fh:
        first = fh.readline().split(b"#")[0].strip()
    if kind == "csv":
        own = b"".join(first.split()).lower() in CSV_HEADERS
        return (1 if header or own else 0), None
    cells = first.split()
    if len(cells) == 2:
        try:
            return 1, (int(cells[0]), int(cells[1]))
        except ValueError:
            raise UserError(
                f"{path}:1: expected 'width height' or 't x y p', got {first.decode(errors='replace')!r}"
            ) from None
    return (1 if header else 0), None


def exact_microseconds(t: np.ndarray, kind: str) -> tuple[np.ndarray, int | None, str]:
    """Times as parsed (CSV: microseconds, TXT: seconds) as int64 microseconds, and the first row that is not
    exact (not finite, beyond MAX_CSV_US or MAX_TXT_SECONDS, or finer than a microsecond) with why, or None and ''.

    A TXT time is exact when it is the float nearest to a whole number of microseconds: the text had at
    most six decimals (to float64's 16 significant digits).
    """
    t = np.asarray(t, np.float64)
    csv = kind == "csv"
    with np.errstate(invalid="ignore", over="ignore"):
        us = np.rint(t if csv else t * 1e6)
        bad_range = ~(np.abs(t) < (MAX_CSV_US if csv else MAX_TXT_SECONDS))  # NaN and infinities included
        inexact = (us != t) if csv else (us / 1e6 != t)
    bad = bad_range | inexact
    if not bad.any():
        return us.astype(np.int64), None, ""
    i = int(np.flatnonzero(bad)[0])
    if bad_range[i]:
        why = ("expected a finite number of microseconds below 2**53" if csv else
               "expected a finite number of seconds below 2**31")
    else:
        why = ("expected a whole number of microseconds" if csv else
               "finer than a microsecond (at most 6 decimals); times are not rounded")
    return np.zeros(0, np.int64), i, f"field t is {t[i]!r} {'microseconds' if csv else 's'}, {why}"


def read_text(path: str | os.PathLike, kind: str, header: bool = False) -> tuple[np.ndarray, ...]:
    """(t microseconds, x, y, p, lines before the data, sensor size or None) of a CSV or TXT events file.

    Every line after the header is an event (blank and # lines aside): one that is not fails naming its
    line. Times are exact or refused, never truncated or rounded; `header` skips a CSV's first line.
    """
    from dvsot.core.bounds import sensor_size_problem

    p = Path(path)
    skip, size = _header(p, kind, header)
    problem = size and sensor_size_problem(*size)
    if problem:  # before the events are read
        raise UserError(f"{p}:1: sensor size: {problem}")
    delimiter = "," if kind == "csv" else None
    try:
        rows = np.loadtxt(p, delimiter=delimiter, skiprows=skip, dtype=np.float64, ndmin=2, comments="#")
    except ValueError as exc:
        hint = "" if skip or kind != "csv" else " (a header line? give --header)"
        raise UserError(f"{p}:{_loadtxt_problem(p, skip, exc)}{hint}") from None
    except OSError as exc:
        raise UserError(f"{p}: cannot read events ({exc.strerror or exc})") from None
    if rows.shape[0] == 0:
        raise UserError(f"{p}: no events")
    if kind == "csv" and skip and rows.shape[1] == 5 and _csv_fields(p)[4:] == ["object"]:
        rows = rows[:, :4]  # dvsot export's object labels: not event data, left out
    if rows.shape[1] != 4:
        raise UserError(f"{p}:{line_of_row(p, skip, 0)}: {rows.shape[1]} fields, expected 4 (t, x, y, p)")
    t, bad, why = exact_microseconds(rows[:, 0], kind)
    if bad is not None:
        raise UserError(f"{p}:{line_of_row(p, skip, bad)}: {why}")
    return t, rows[:, 1], rows[:, 2], rows[:, 3], skip, size


def _csv_fields(path: Path) -> list[str]:
    """The names in a CSV file's header line, stripped."""
    with open(path, "rb") as fh:
        return [c.strip().decode(errors="replace") for c in fh.readline().split(b"#")[0].split(b",")]


def _loadtxt_problem(path: Path, skip: int, exc: ValueError) -> str:
    """numpy's parse error as 'LINE: what' on the file's own line numbers (numpy counts data rows from 0 in a
    conversion error, from 1 in a changed column count)."""
    import re

    text = " ".join(str(exc).split())
    changed = re.search(r"columns changed from \d+ to (\d+) at row (\d+)", text)
    if changed:
        line = line_of_row(path, skip, int(changed.group(2)) - 1)
        return f"{line}: {changed.group(1)} fields, expected 4 (t, x, y, p)"
    bad = re.search(r"could not convert string '([^']*)' to \w+ at row (\d+), column (\d+)", text)
    if bad:
        col = int(bad.group(3))
        name = ("t", "x", "y", "p")[col - 1] if col <= 4 else str(col)
        return f"{line_of_row(path, skip, int(bad.group(2)))}: field {name} is {bad.group(1)!r}, not a number"
    return f" {text}"
