"""Event files other tools read and write: AEDAT4, EVT2/EVT3 (.raw), DAT, CSV and TXT, to and from dataset files.

AEDAT4 (iniVation DV), EVT2/3 and DAT (Prophesee) go through faery; CSV and rpg/ESIM-style TXT through
dvsot.textevents. Timestamps in these files are on the recording's own clock: a dataset file's
`t + t_offset`. Every writer writes temp files beside its outputs and renames them when all are
complete, so bad input or a crash leaves nothing behind.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dvsot.errors import UserError, exception_line
from dvsot.validate import sensor_size_problem

# suffix -> format; .raw is EVT 3 unless told otherwise (evt_version)
SUFFIXES = {".aedat4": "aedat", ".raw": "evt", ".dat": "dat", ".csv": "csv", ".txt": "txt"}
EVT_VERSIONS = ("evt2", "evt3")


@dataclass(frozen=True)
class EventFile:
    """Events read from a file: t (us, the file's clock), x, y (pixels), p (0/1), the sensor size, where row i is."""

    t: np.ndarray
    x: np.ndarray
    y: np.ndarray
    p: np.ndarray
    width: int
    height: int
    path: Path
    header_lines: int | None = None  # text formats: lines before the data (rows are named by line)

    def where(self, i: int) -> str:
        """'path:LINE' of a text file's i-th event, or 'path: event i' of a binary one."""
        if self.header_lines is None:
            return f"{self.path}: event {i}"
        from dvsot.textevents import line_of_row

        return f"{self.path}:{line_of_row(self.path, self.header_lines, i)}"


def event_format(path: str | os.PathLike, flag: str) -> str:
    """The format named by a path's suffix; an unknown one is a UserError naming the flag and the known suffixes."""
    suffix = Path(path).suffix.lower()
    if suffix not in SUFFIXES:
        known = ", ".join(sorted(SUFFIXES))
        raise UserError(f"{path}: {flag}: unknown event file suffix '{suffix}' (known: {known})")
    return SUFFIXES[suffix]


def parse_size(text: str, label: str = "size") -> tuple[int, int]:
    """'WIDTHxHEIGHT' as two positive ints (pixels); otherwise a UserError naming the setting as `label`."""
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise UserError(f"{label} {text!r}: expected WIDTHxHEIGHT, e.g. 346x260") from None
    problem = sensor_size_problem(w, h)
    if problem:
        raise UserError(f"{label} {text!r}: {problem}")
    return w, h



def read_event_file(path: str | os.PathLike, size: tuple[int, int] | None = None,
                    evt_version: str = "evt3", size_label: str = "size", header: bool = False) -> EventFile:
    """All events of an event file, checked: time order, t >= 0, pixels on the sensor, polarity 0/1.

    size: (width, height) for files that do not say; messages name it as size_label. header: a CSV or TXT
    file's first line is a header (else only dvsot's own CSV header or TXT size line is one)."""
    p = Path(path)
    kind = event_format(p, "events file")
    from dvsot.validate import file_kind_problem

    problem = file_kind_problem(p)
    if problem:
        raise UserError(f"{p}: {problem}")
    if kind in ("csv", "txt"):
        from dvsot.textevents import read_text

        t, x, y, pol, skip, file_size = read_text(p, kind, header)
        size = file_size or size
        if size is None:
            raise UserError(f"{p}: a {kind.upper()} file has no sensor size; give {size_label} WIDTHxHEIGHT")
        ev = EventFile(t, x, y, pol, size[0], size[1], p, skip)
    else:
        ev = _read_with_faery(p, kind, size, evt_version, size_label)
    check_events(ev)
    return ev


def _read_with_faery(path: Path, kind: str, size: tuple[int, int] | None, evt_version: str,
                     size_label: str = "size") -> EventFile:
    import faery

    fallback = size or (1280, 720)
    try:
        stream = faery.events_stream_from_file(path, dimensions_fallback=fallback, version_fallback=
                                               evt_version if kind == "evt" else None)
        width, height = stream.dimensions()
        a = stream.to_array()
    except Exception as exc:  # faery's decoders raise bare Exceptions with their own messages
        raise UserError(f"{path}: cannot read {kind.upper()} events ({exception_line(exc, kind=False)})") from None
    if size is not None and (width, height) != tuple(size):
        raise UserError(f"{path}: the file says {width}x{height} pixels, {size_label} says {size[0]}x{size[1]}")
    return EventFile(a["t"].astype(np.int64), a["x"], a["y"], a["on"].astype(np.uint8), int(width), int(height), path)


def check_events(ev: EventFile) -> None:
    """Raise UserError naming the line or event of the first bad value: order, t < 0, off-sensor pixel, polarity."""
    problem = sensor_size_problem(ev.width, ev.height)
    if problem:
        raise UserError(f"{ev.path}: sensor size: {problem}")
    if len(ev.t) == 0:
        raise UserError(f"{ev.path}: no events")
    down = np.flatnonzero(ev.t[1:] < ev.t[:-1])
    if len(down):
        i = int(down[0]) + 1
        raise UserError(f"{ev.where(i)}: field t is {int(ev.t[i])} us, earlier than the event before it "
                        f"({int(ev.t[i - 1])} us); events must be in time order")
    if ev.t[0] < 0:
        raise UserError(f"{ev.where(0)}: field t is {int(ev.t[0])} us, expected >= 0")
    for name, values, limit in (("x", ev.x, ev.width), ("y", ev.y, ev.height), ("p", ev.p, 2)):
        if values.dtype.kind in "ub":  # binary formats: unsigned integers, one pass for the maximum
            if int(values.max()) < limit:
                continue
            bad = values >= limit
        else:  # text: any number, so also negative and fractional values
            bad = (values < 0) | (values >= limit) | (values != np.floor(values))
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            rule = "0 or 1" if name == "p" else f"an integer in 0..{limit - 1} ({ev.width}x{ev.height} sensor)"
            raise UserError(f"{ev.where(i)}: field {name} is {values[i]:g}, expected {rule}")


def write_event_file(path: str | os.PathLike, t: np.ndarray, x: np.ndarray, y: np.ndarray, p: np.ndarray,
                     width: int, height: int, evt_version: str = "evt3") -> None:
    """Write events (t us >= 0 in time order, pixels, polarity 0/1) in the format of the path's suffix."""
    kind = event_format(path, "output")
    if kind in ("csv", "txt"):
        from dvsot.textevents import write_text

        write_text(path, t, x, y, p, width, height, kind)
        return
    import faery

    a = np.empty(len(t), faery.EVENTS_DTYPE)
    a["t"], a["x"], a["y"], a["on"] = t, x, y, np.asarray(p).astype(bool)
    versions = {"evt": evt_version, "dat": "dat2", "aedat": None}
    # zero_t0: EVT and DAT hold the time since the first event (their time fields are 32-64 bits of
    # wrapping words; an epoch start would overflow DAT and pad EVT 2 with gigabytes of time-high words)
    # and t0 in the header, which faery (and Metavision) add back on reading
    faery.events_stream_from_array(a, (int(width), int(height))).to_file(
        path, version=versions[kind], zero_t0=True, file_type=kind)


def boxes_path(events_out: str | os.PathLike) -> Path:
    """Where the box track goes beside an exported events file: OUT.aedat4 -> OUT.boxes.csv."""
    p = Path(events_out)
    return p.with_name(p.stem + ".boxes.csv")


def write_box_csv(path: str | os.PathLike, t_us: np.ndarray, xywh: np.ndarray) -> None:
    """Box rows as CSV t_s,x,y,w,h (seconds with 6 decimals, float32 values that read back exactly, nan = absent)."""
    t = np.asarray(t_us, np.int64)
    with open(path, "w") as fh:
        fh.write("# t_s,x,y,w,h (pixels; nan = no target)\n")
        for ti, row in zip(t, np.asarray(xywh, np.float32)):
            sign, ti = ("-", -ti) if ti < 0 else ("", ti)
            fh.write(f"{sign}{ti // 1_000_000}.{ti % 1_000_000:06d}," + ",".join(f"{v:.9g}" for v in row) + "\n")


def export_dataset(dataset_path: str | os.PathLike, out_path: str | os.PathLike, evt_version: str = "evt3",
                   boxes: bool = True) -> list[Path]:
    """Write a dataset file's events (t + t_offset) to out_path and its box track to OUT.boxes.csv; the paths written."""
    from dvsot.dataset import Dataset
    from dvsot.outputs import replacing, run_outputs

    out = Path(out_path)
    event_format(out, "output")
    if evt_version not in EVT_VERSIONS:
        raise UserError(f"evt_version {evt_version!r}: expected one of {', '.join(EVT_VERSIONS)}")
    with Dataset(dataset_path) as ds:
        parts = list(ds.chunks())
        track = ds.boxes()
        width, height, offset = ds.width, ds.height, ds.t_offset_us
    t = np.concatenate([b.t for b in parts]) + offset if parts else np.empty(0, np.int64)
    if len(t) and t[0] < 0:
        raise UserError(f"{dataset_path}: /t_offset {offset} makes timestamps negative, which event files cannot hold")
    x, y, p = (np.concatenate([getattr(b, k) for b in parts]) if parts else np.empty(0, np.uint16) for k in "xyp")
    with run_outputs():  # both written to temp names, renamed together when both are complete
        with replacing(out) as tmp_events:
            write_event_file(tmp_events, t, x, y, p, width, height, evt_version)
        if boxes:
            with replacing(boxes_path(out)) as tmp_boxes:
                write_box_csv(tmp_boxes, track.t + offset, track.xywh)
    return [out] + ([boxes_path(out)] if boxes else [])
