"""Line-oriented text inputs, each line checked and named in its error: numbered lines without `#` comments,
frame timestamps (seconds, one a line, as ESIM reads them) and box CSVs (t_s,x,y,w,h)."""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

from dvsot.core.bounds import file_kind_problem
from dvsot.core.errors import UserError
from dvsot.dataset.boxes import box_problem

MAX_SECONDS = 1e9  # keeps timestamps in microseconds well inside int64


def text_lines(path: str | os.PathLike, what: str) -> list[tuple[int, str]]:
    """(1-based line number, text) of a text file's lines that hold something once `#` comments are cut off."""
    p = Path(path)
    kind = file_kind_problem(p)  # before reading: a FIFO would block
    if kind:
        raise UserError(f"{p}: cannot read {what} ({'no such file' if kind == 'no such file' else kind})")
    try:
        lines = p.read_text().splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        reason = exc.strerror if isinstance(exc, OSError) else "not a text file"
        raise UserError(f"{p}: cannot read {what} ({reason})") from None
    numbered = ((no, ln.split("#")[0].strip()) for no, ln in enumerate(lines, start=1))
    return [(no, ln) for no, ln in numbered if ln]


def read_timestamps(path: str | os.PathLike, count: int) -> np.ndarray:
    """Timestamps in microseconds from a file of seconds, one per line (as ESIM reads them); checked."""
    p = Path(path)
    values = []
    for no, ln in text_lines(p, "timestamps"):
        try:
            v = float(ln.split()[0])
        except ValueError:
            raise UserError(f"{p}:{no}: not a number of seconds: {ln!r}") from None
        if not (math.isfinite(v) and abs(v) < MAX_SECONDS):
            raise UserError(f"{p}:{no}: not a finite number of seconds below {MAX_SECONDS:g}: {ln!r}")
        values.append(v)
    t = np.rint(np.array(values, np.float64) * 1e6).astype(np.int64)
    if len(t) != count:
        raise UserError(f"{p}: {len(t)} timestamps for {count} frames")
    bad = np.flatnonzero(np.diff(t) <= 0)
    if bad.size:
        raise UserError(f"{p}: timestamps must increase (frame {bad[0] + 1} at {values[bad[0] + 1]} s does not)")
    if t[0] < 0:
        raise UserError(f"{p}: timestamps must be >= 0")
    return t


def _box_row(path: str, no: int, line: str) -> list[float]:
    """One CSV line t_s,x,y,w,h as numbers; times finite, w and h positive (or the whole box NaN: absent)."""
    cells = [c.strip() for c in line.split(",")]
    if len(cells) != 5:
        raise UserError(f"{path}:{no}: expected 5 columns t_s,x,y,w,h, found {len(cells)}")
    try:
        row = [float(c) for c in cells]
    except ValueError:
        raise UserError(f"{path}:{no}: not a number in {line!r} (columns t_s,x,y,w,h)") from None
    t, x, y, w, h = row
    if not (math.isfinite(t) and abs(t) < MAX_SECONDS):
        raise UserError(f"{path}:{no}: box time must be a finite number of seconds below {MAX_SECONDS:g}, "
                        f"got {cells[0]!r}")
    if all(math.isnan(v) for v in (x, y, w, h)):
        return row  # NaN box: the target is absent at this time
    if not all(math.isfinite(v) for v in (x, y, w, h)):
        raise UserError(f"{path}:{no}: x,y,w,h must be finite (or all nan for no target), got {line!r}")
    if w <= 0 or h <= 0:
        raise UserError(f"{path}:{no}: box width and height must be positive, got w={cells[3]} h={cells[4]}")
    return row


def read_box_csv(path: str | os.PathLike, t_origin_us: int, width: int,
                 height: int) -> tuple[np.ndarray, np.ndarray]:
    """Box times (us, relative to t_origin_us) and x,y,w,h rows (pixels) of a CSV t_s,x,y,w,h; checked line by line."""
    numbered = text_lines(path, "boxes as CSV t_s,x,y,w,h")
    if not numbered:
        raise UserError(f"{path}: no boxes (expected lines t_s,x,y,w,h)")
    rows = np.array([_box_row(str(path), no, ln) for no, ln in numbered], np.float64)
    problem = box_problem(rows[:, 1:5], width, height, lambda i: f"the box on line {numbered[i][0]}")
    if problem:
        raise UserError(f"{path}: {problem}")
    t = np.rint(rows[:, 0] * 1e6).astype(np.int64) - t_origin_us
    bad = np.flatnonzero(np.diff(t) <= 0)
    if bad.size:
        raise UserError(f"{path}:{numbered[bad[0] + 1][0]}: box times must increase")
    return t, rows[:, 1:5]
