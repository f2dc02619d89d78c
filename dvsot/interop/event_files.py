"""Event files other tools read and write: AEDAT4, EVT2/EVT3 (.raw), DAT, CSV and TXT, to and from dataset files.

AEDAT4 (iniVation DV), EVT2/3 and DAT (Prophesee) go through faery; CSV and rpg/ESIM-style TXT through
dvsot.interop.text_events. Timestamps in these files are on the recording's own clock: a dataset file's
`t + t_offset`. Every writer writes temp files beside its outputs and renames them when all are
complete, so bad input or a crash leaves nothing behind.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from dvsot.core.bounds import sensor_size_problem
from dvsot.core.defaults import EXPORT_EVT_VERSION, IMPORT_EVT_VERSION
from dvsot.core.errors import UserError, exception_line, label

if TYPE_CHECKING:
    from dvsot.dataset import Dataset

# suffix -> format; a .raw is EVT 2 or 3 (evt_version)
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
        from dvsot.interop.text_events import line_of_row

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
                    evt_version: str = IMPORT_EVT_VERSION, size_label: str = "size", header: bool = False) -> EventFile:
    """All events of an event file, checked: time order, t >= 0, pixels on the sensor, polarity 0/1.

    size: (width, height) for files that do not say; messages name it as size_label. header: a CSV or TXT
    file's first line is a header (else only dvsot's own CSV header or TXT size line is one)."""
    p = Path(path)
    kind = event_format(p, "events file")
    from dvsot.core.bounds import file_kind_problem

    problem = file_kind_problem(p)
    if problem:
        raise UserError(f"{p}: {problem}")
    if kind in ("csv", "txt"):
        from dvsot.interop.text_events import read_text

        t, x, y, pol, skip, file_size = read_text(p, kind, header)
        size = file_size or size
        if size is None:
            raise UserError(f"{p}: a {kind.upper()} file has no sensor size; give {size_label} WIDTHxHEIGHT")
        ev = EventFile(t, x, y, pol, size[0], size[1], p, skip)
    else:
        ev = _read_with_faery(p, kind, size, evt_version, size_label)
    check_events(ev)
    return ev


def _header(path: Path, kind: str, evt_version: str) -> tuple[tuple[int, int] | None, str | None]:
    """(sensor size, DAT event type or EVT version) of an EVT or DAT header; the size is None when it has none.

    faery's decoders put a fallback where the header has no size: two fallbacks that differ tell."""
    from faery.extension import dat, evt

    sizes, kind_of = [], None
    for fallback in ((1, 1), (2, 2)):
        if kind == "dat":
            with dat.Decoder(path, fallback, "dat2") as decoder:
                sizes.append(tuple(decoder.dimensions))
                kind_of = decoder.event_type
        else:
            with evt.Decoder(path, fallback, evt_version) as decoder:
                sizes.append(tuple(decoder.dimensions))
                kind_of = decoder.version
    return (sizes[0] if sizes[0] == sizes[1] else None), kind_of


def _header_bytes(path: Path) -> int:
    """The length of a Prophesee file's text header: its leading lines that start with '%'."""
    with open(path, "rb") as fh:
        n = 0
        for line in fh:
            if not line.startswith(b"%"):
                break
            n += len(line)
    return n


def evt3_time_problem(path: str | os.PathLike, words_per_chunk: int = 1 << 24) -> str | None:
    """Why faery 0.7, the EVT reader here, would decode an EVT 3 file's times wrong (one line), or None.

    - Time-low words (12 bits, us) that wrap around with no time-high word between them. Prophesee's
      EVT 3 writes a time-high word whenever bits 12-23 of the time change, so they never do; a writer
      that leaves the time-high words out (expelliarmus 1.1 does) makes files that faery decodes with
      every time stuck in the first 4096 us. A step back of more than half the period counts as a
      wrap, so a few microseconds of jitter between events is not refused.
    - A time-high word that wraps from below 4095 to 0 (the 24-bit time passing 2^24 us, 16.8 s, across
      a gap of over 4 ms with no event, as sparse files written by faery have): faery notices the wrap
      only after 4095 and decodes every later time as earlier ones; a camera writes every time-high."""
    p = Path(path)
    start = _header_bytes(p)
    words = np.memmap(p, dtype="<u2", mode="r", offset=start, shape=((p.stat().st_size - start) // 2,))
    last_low, last_high = -1, -1  # the previous time-low of this time-high period (-1 after a time-high word)
    for i in range(0, len(words), words_per_chunk):
        w = np.asarray(words[i:i + words_per_chunk])
        kind = w >> 12
        marks = np.flatnonzero((kind == 6) | (kind == 8))  # EVT_TIME_LOW, EVT_TIME_HIGH
        low = np.where(kind[marks] == 6, (w[marks] & 0xFFF).astype(np.int64), -1)
        before = np.concatenate([[last_low], low[:-1]])
        bad = np.flatnonzero((low >= 0) & (before - low > 2048))
        if len(bad):
            k = int(bad[0])
            return (f"time-low word {i + int(marks[k])} wraps from {before[k]} to {low[k]} us with no time-high "
                    "word between them, which Prophesee's EVT 3 does not allow (expelliarmus writes such files; "
                    "save them as EVT 2)")
        highs = np.flatnonzero(kind == 8)
        high = (w[highs] & 0xFFF).astype(np.int64)
        prev = np.concatenate([[last_high], high[:-1]])
        bad = np.flatnonzero((high < prev) & (prev != 0xFFF))
        if len(bad):
            k = int(bad[0])
            return (f"time-high word {i + int(highs[k])} wraps from {prev[k]} to {high[k]} (the time passing "
                    "2^24 us across a gap with no event), which faery, dvsot's EVT reader, decodes to wrong "
                    "times; convert the file to EVT 2 with the tool that wrote it")
        if len(low):
            last_low = int(low[-1])
        if len(high):
            last_high = int(high[-1])
    return None


def _first_step_back(t: np.ndarray, last: int, period: int) -> int | None:
    """Index in t (us, wrapping at `period`) of the first time earlier than the one before it (`last` before t[0]).

    A step back of more than half the period is the clock wrapping, which the readers count forward."""
    d = np.diff(np.concatenate([[last], t]).astype(np.int64))
    bad = np.flatnonzero((d < 0) & (-d <= period // 2))
    return int(bad[0]) if len(bad) else None


def raw_time_problem(path: str | os.PathLike, kind: str, evt_version: str | None,
                     chunk: int = 1 << 22) -> str | None:
    """Why a DAT, EVT 2 or EVT 3 file's stored times are out of order or its last record is cut (one line), or None.

    faery clamps a time that steps back to the time before it, so the events would be stored at times the file
    does not hold: the raw words are read here. Events are named by their index among the file's events (DAT,
    EVT 2) or by their 16-bit word (EVT 3, whose events carry no time of their own)."""
    p = Path(path)
    start = _header_bytes(p)
    size = p.stat().st_size
    if kind == "dat":
        if size < start + 2:
            return None  # faery's header check names a file with no event type
        with open(p, "rb") as fh:
            fh.seek(start)
            record = fh.read(2)[1]
        body = size - start - 2
        if record < 4:
            return f"the DAT header gives events of {record} bytes; expected at least 4"
        if body % record:
            return (f"the file ends {body % record} bytes into event {body // record} (events of {record} bytes): "
                    "the file is truncated")
        words = np.memmap(p, dtype="<u4", mode="r", offset=start + 2, shape=(body // 4,)) if body else np.empty(0)
        last, step = -1, record // 4 if record % 4 == 0 else None
        if step is None:
            return f"the DAT header gives events of {record} bytes; expected a multiple of 4"
        for i in range(0, body // record, chunk):
            t = np.asarray(words[i * step:(i + chunk) * step:step], np.int64)
            k = _first_step_back(t, last if last >= 0 else int(t[0]) if len(t) else 0, 1 << 32)
            if k is not None:
                prev = last if k == 0 else int(t[k - 1])
                return (f"event {i + k}: its stored time ({int(t[k])} us after the header's T0) is earlier than "
                        f"the event before it ({prev} us); events must be in time order")
            if len(t):
                last = int(t[-1])
        return None
    if evt_version not in EVT_VERSIONS:
        return None  # EVT 2.1 (64-bit words) is read as faery reads it
    unit = 4 if evt_version == "evt2" else 2
    if (size - start) % unit:
        return f"the file ends {(size - start) % unit} bytes into a {unit * 8}-bit word: the file is truncated"
    count = (size - start) // unit
    if not count:
        return None
    words = np.memmap(p, dtype="<u4" if unit == 4 else "<u2", mode="r", offset=start, shape=(count,))
    high, last, seen = 0, -1, 0  # the time-high in force, the last event time, events before this chunk
    for i in range(0, count, chunk):
        w = np.asarray(words[i:i + chunk]).astype(np.int64)
        if unit == 4:  # EVT 2: a 28-bit time-high word (type 8); CD events (types 0, 1) carry 6 low bits
            kind_of = w >> 28
            marks = kind_of == 8
            values = w & 0xFFFFFFF
            events = (kind_of == 0) | (kind_of == 1)
            low = (w >> 22) & 63
            shift, period = 6, 1 << 34
        else:  # EVT 3: time-high (type 8) and time-low (type 6) words, 12 bits each; name the time-low words
            kind_of = w >> 12
            marks = kind_of == 8
            values = w & 0xFFF
            events = kind_of == 6
            low = w & 0xFFF
            shift, period = 12, 1 << 24
        idx = np.where(marks, np.arange(len(w)), -1)
        np.maximum.accumulate(idx, out=idx)
        current = np.where(idx >= 0, values[np.maximum(idx, 0)], high)
        where = np.flatnonzero(events)
        t = (current[where] << shift) | low[where]
        k = _first_step_back(t, last if last >= 0 else int(t[0]) if len(t) else 0, period)
        if k is not None:
            prev = last if k == 0 else int(t[k - 1])
            name = f"event {seen + k}" if unit == 4 else f"time-low word {i + int(where[k])}"
            return (f"{name}: its stored time ({int(t[k])} us after the header's t0) is earlier than the event "
                    f"before it ({prev} us); events must be in time order")
        if len(t):
            last = int(t[-1])
        if marks.any():
            high = int(values[np.flatnonzero(marks)[-1]])
        seen += len(where)
    return None


_SIZE_WORDS = (b"width", b"height")


def header_text_size(path: str | os.PathLike) -> tuple[int, int] | None:
    """(width, height) a Prophesee header's text states ('% Width N', 'width=N', '% geometry WxH'), or None."""
    import re

    found: dict[bytes, int] = {}
    with open(path, "rb") as fh:
        for line in fh:
            if not line.startswith(b"%"):
                break
            low = line.lower()
            m = re.search(rb"geometry\s+(\d+)\s*x\s*(\d+)", low)
            if m:
                found.setdefault(b"width", int(m[1]))
                found.setdefault(b"height", int(m[2]))
            for word in _SIZE_WORDS:
                m = re.search(word + rb"(?:\s+|\s*=\s*)(\d+)", low)
                if m:
                    found.setdefault(word, int(m[1]))
    if len(found) < 2:
        return None
    return found[b"width"], found[b"height"]


def _dat_2d_events(path: Path, size: tuple[int, int]) -> np.ndarray:
    """The events of a DAT file of type 0x00 ("2D", as expelliarmus writes): the CD layout, polarity in the payload."""
    from faery.extension import dat

    with dat.Decoder(path, size, "dat2") as decoder:
        parts = list(decoder)
    a = np.concatenate(parts) if parts else np.empty(0, [("t", "<u8"), ("x", "<u2"), ("y", "<u2"), ("payload", "u1")])
    out = np.empty(len(a), [("t", np.int64), ("x", np.uint16), ("y", np.uint16), ("on", np.uint8)])
    out["t"], out["x"], out["y"], out["on"] = a["t"], a["x"], a["y"], a["payload"]
    return out


def _read_with_faery(path: Path, kind: str, size: tuple[int, int] | None, evt_version: str,
                     size_label: str = "size") -> EventFile:
    import faery

    try:
        header_size, event_type = _header(path, kind, evt_version) if kind in ("evt", "dat") else (None, None)
    except Exception as exc:  # faery's decoders raise bare Exceptions with their own messages
        raise UserError(f"{path}: cannot read {kind.upper()} events ({exception_line(exc, kind=False)})") from None
    if event_type == "evt3":
        problem = evt3_time_problem(path)
        if problem:
            raise UserError(f"{path}: {problem}")
    if kind in ("evt", "dat"):
        problem = raw_time_problem(path, kind, event_type if kind == "evt" else None)
        if problem:
            raise UserError(f"{path}: {problem}")
    if kind in ("evt", "dat") and header_size is None:
        stated = header_text_size(path)
        problem = (sensor_size_problem(*stated) or (None if max(stated) < 1 << 16 else
                   "faery, dvsot's reader of these files, holds at most 65535 pixels a side")) if stated else None
        if problem:  # faery's decoders read a size beyond 16 bits as none
            raise UserError(f"{path}: the {kind.upper()} header says {stated[0]}x{stated[1]} pixels: {problem}")
    if kind in ("evt", "dat") and header_size is None and size is None:
        raise UserError(f"{path}: the {kind.upper()} header gives no sensor size; give {size_label} WIDTHxHEIGHT")
    if header_size is not None and size is not None and header_size != tuple(size):
        raise UserError(f"{path}: the file says {header_size[0]}x{header_size[1]} pixels, "
                        f"{size_label} says {size[0]}x{size[1]}")
    try:
        if event_type == "2d":
            width, height = header_size or size
            a = _dat_2d_events(path, (width, height))
        else:
            stream = faery.events_stream_from_file(path, dimensions_fallback=header_size or size or (1, 1),
                                                   version_fallback=evt_version if kind == "evt" else None)
            width, height = stream.dimensions()
            a = stream.to_array()
    except Exception as exc:
        raise UserError(f"{path}: cannot read {kind.upper()} events ({exception_line(exc, kind=False)})") from None
    if size is not None and (width, height) != tuple(size):  # an AEDAT4 file's track
        raise UserError(f"{path}: the file says {width}x{height} pixels, {size_label} says {size[0]}x{size[1]}")
    return EventFile(a["t"].astype(np.int64), a["x"], a["y"], a["on"].astype(np.uint8), int(width), int(height), path)


def frame_times(path: str | os.PathLike) -> np.ndarray:
    """The timestamps (us, the file's clock) of the frames of an AEDAT4 file's first frame track, in file order."""
    p = Path(path)
    if event_format(p, "events file") != "aedat":
        raise UserError(f"{p}: frame times come from an AEDAT4 file's frame track; this is not a .aedat4 file")
    from faery.extension import aedat

    try:
        with aedat.Decoder(p) as decoder:
            tracks = [t.id for t in decoder.tracks() if t.data_type == "frame"]
            if not tracks:
                raise UserError(f"{p}: the file has no frame track (tracks: "
                                f"{', '.join(t.data_type for t in decoder.tracks()) or 'none'})")
            times = [packet.t for track, packet in decoder if track.id == tracks[0]]
    except UserError:
        raise
    except Exception as exc:
        raise UserError(f"{p}: cannot read the AEDAT4 frame track ({exception_line(exc, kind=False)})") from None
    return np.asarray(times, np.int64)


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
                     width: int, height: int, evt_version: str = EXPORT_EVT_VERSION,
                     objects: np.ndarray | None = None) -> None:
    """Write events (t us >= 0 in time order, pixels, polarity 0/1) in the format of the path's suffix; objects
    (an id per event) goes into a CSV as a fifth column, and no other format has a place for it."""
    kind = event_format(path, "output")
    if kind in ("csv", "txt"):
        from dvsot.interop.text_events import write_text

        write_text(path, t, x, y, p, width, height, kind, objects)
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


# An export's side files: named from the output's full name (x.csv -> x.csv.boxes.csv), so outputs that share a
# stem never share a side file; each starts with its own first line, by which a file there is known to be one.
SIDE_FILES = {"boxes": (".boxes.csv", "# t_s,x,y,w,h"), "objects": (".objects.csv", "id,name,role"),
              "gt": (".gt.csv", "segment,t_s,")}
# the event formats with a field for per-event object labels
LABELLED_FORMATS = ("csv",)


class LabelsLeftOut(UserWarning):
    """An export's event format has no field for the dataset file's per-event object labels: they are left out."""


def side_path(events_out: str | os.PathLike, kind: str) -> Path:
    """Where an export's side table of `kind` (a SIDE_FILES key) goes: OUT.csv -> OUT.csv.boxes.csv."""
    p = Path(events_out)
    return p.with_name(p.name + SIDE_FILES[kind][0])


def objects_path(events_out: str | os.PathLike) -> Path:
    """Where the object table goes beside a CSV export with object labels: OUT.csv -> OUT.csv.objects.csv."""
    return side_path(events_out, "objects")


def boxes_path(events_out: str | os.PathLike) -> Path:
    """Where the box track goes beside an exported events file: OUT.aedat4 -> OUT.aedat4.boxes.csv."""
    return side_path(events_out, "boxes")


def gt_path(events_out: str | os.PathLike) -> Path:
    """Where the per-segment ground truth goes beside an exported events file: OUT.aedat4 -> OUT.aedat4.gt.csv."""
    return side_path(events_out, "gt")


def _side_kind(path: Path) -> str | None:
    """Which side table an existing regular file is, by its first line ("boxes", "objects", "gt"), else None."""
    from dvsot.runtime.inputs import open_input

    with open_input(path, "rb", "an export's side file") as fh:
        first = fh.readline(256).decode("utf-8", "replace")
    return next((kind for kind, (_, head) in SIDE_FILES.items() if first.startswith(head)), None)


def _sides(out: Path, flag: str, boxes: bool) -> dict[str, Path]:
    """{kind: path} of the side tables an export to `out` may write: the object table (CSV), boxes and gt."""
    kinds = (["objects"] if event_format(out, flag) in LABELLED_FORMATS else []) + (["boxes", "gt"] if boxes else [])
    return {kind: side_path(out, kind) for kind in kinds}


def check_export_outputs(out_path: str | os.PathLike, flag: str, inputs=(), boxes: bool = True) -> list[Path]:
    """Check an export's output and its side files before any work (UserError); the side files it may write.

    Refused: an output that is another output's side file (`x.csv.boxes.csv` beside `x.csv`), and a side file that
    would replace a file that is not that kind of side table (another export's events file, a user's file)."""
    from dvsot.runtime.outputs import output_file

    out = Path(out_path)
    for kind, (suffix, _) in SIDE_FILES.items():
        owner = out.with_name(out.name[: -len(suffix)]) if out.name.endswith(suffix) else None
        if owner is not None and owner.name and os.path.lexists(owner):
            raise UserError(f"{out_path}: {flag} names the {kind} table of the export {owner}; name another output")
    output_file(out_path, flag, inputs)
    sides = _sides(out, flag, boxes)
    for kind, side in sides.items():
        output_file(side, f"{flag} (its {kind} table {side.name})", inputs)
        if side.is_file() and _side_kind(side) != kind:
            raise UserError(f"{side}: {flag}: the {kind} table of {out.name} would replace this file, which is not "
                            f"an export's {kind} table (another output's file?); move it or name another output")
    return list(sides.values())


def _seconds(t_us: np.ndarray) -> list[str]:
    """Microseconds as seconds with 6 decimals, exact (no float rounding), a minus sign before negative times."""
    out = []
    for ti in np.asarray(t_us, np.int64).tolist():
        sign, ti = ("-", -ti) if ti < 0 else ("", ti)
        out.append(f"{sign}{ti // 1_000_000}.{ti % 1_000_000:06d}")
    return out


def write_box_csv(path: str | os.PathLike, t_us: np.ndarray, xywh: np.ndarray) -> None:
    """Box rows as CSV t_s,x,y,w,h (seconds with 6 decimals, float32 values that read back exactly, nan = absent)."""
    with open(path, "w") as fh:
        fh.write(SIDE_FILES["boxes"][1] + " (pixels; nan = no target)\n")
        for ts, row in zip(_seconds(t_us), np.asarray(xywh, np.float32)):
            fh.write(ts + "," + ",".join(f"{v:.9g}" for v in row) + "\n")


def ground_truth_columns(ds: Dataset, t_offset_us: int = 0) -> dict[str, np.ndarray]:
    """The gt table of a dataset file, {column: per-segment values}: segment, t (its end, us, + t_offset_us), the
    amodal and visible boxes (pixels), then visibility, truncation and absent where the file has them, and the tags
    of dvsot.dataset.tags that it can decide (bool)."""
    from dvsot.dataset.tags import segment_tags

    box, vis = ds.segment_boxes(), ds.segment_visible_boxes()
    cols: dict[str, np.ndarray] = {"segment": np.arange(ds.num_segments),
                                   "t": (np.arange(ds.num_segments, dtype=np.int64) + 1) * ds.segment_us + t_offset_us}
    cols.update({name: box[:, k] for k, name in enumerate("xywh")})
    cols.update({f"visible_{name}": vis[:, k] for k, name in enumerate("xywh")})
    for name, values in (("visibility", ds.segment_visibility()), ("truncation", ds.segment_truncation()),
                         ("absent", ds.segment_absent())):
        if values is not None:
            cols[name] = values
    cols.update({name: flags for name, flags in segment_tags(ds).items() if name not in cols})
    return cols


def write_gt_csv(path: str | os.PathLike, columns: Mapping[str, np.ndarray]) -> None:
    """The gt table as CSV with a header line: t as t_s (seconds, 6 decimals), flags as 0/1, float32 values that
    read back exactly (nan = none)."""
    text = {}
    for name, values in columns.items():
        a = np.asarray(values)
        if name == "t":
            name, cells = "t_s", _seconds(a)
        elif a.dtype == bool or a.dtype.kind in "iu":
            cells = [str(int(v)) for v in a.tolist()]
        else:
            cells = [f"{v:.9g}" for v in a.astype(np.float32).tolist()]
        text[name] = cells
    with open(path, "w") as fh:
        fh.write(",".join(text) + "\n")
        fh.writelines(",".join(row) + "\n" for row in zip(*text.values()))


def export_dataset(dataset_path: str | os.PathLike, out_path: str | os.PathLike,
                   evt_version: str = EXPORT_EVT_VERSION, boxes: bool = True,
                   labels: Mapping[str, str] | None = None) -> list[Path]:
    """Write a dataset file's events (t + t_offset) to out_path, its box track to OUT.boxes.csv and its per-segment
    ground truth with challenge tags to OUT.gt.csv (OUT the output's full name: x.csv -> x.csv.boxes.csv,
    x.csv.gt.csv); the paths written.

    A CSV export of a file with per-event labels gets the object column and the object table in OUT.objects.csv
    (id,name,role); any other format has no field for them, and a LabelsLeftOut warning says they are left out.
    Every output is checked before anything is read (UserError: an unknown suffix, a directory, a device or FIFO,
    an output that is the dataset file, a side file that is another output's); the side files are replaced with
    the events in one commit, and one the new export does not write (no labels, boxes=False) that the previous
    export of this output left is removed in it. boxes: write the box track and the gt table. labels: how
    messages name out_path (a command's flag)."""
    import warnings

    from dvsot.dataset import Dataset
    from dvsot.runtime.outputs import output_file, replacing, run_outputs

    out = Path(out_path)
    flag = label("out_path", labels)
    kind = event_format(out, flag)  # an unknown suffix fails before anything is read
    output_file(out_path, flag, [dataset_path])  # as given: a trailing slash names a directory, refused
    sides = _sides(out, flag, boxes)
    for side_kind, side in sides.items():
        output_file(side, f"{flag} (its {SIDE_FILES[side_kind][0]})", [dataset_path])
    if evt_version not in EVT_VERSIONS:
        raise UserError(f"evt_version {evt_version!r}: expected one of {', '.join(EVT_VERSIONS)}")
    check_export_outputs(out, flag, [dataset_path], boxes)
    with Dataset(dataset_path) as ds:
        parts = list(ds.chunks())
        track = ds.boxes()
        width, height, offset = ds.width, ds.height, ds.t_offset_us
        table = ds.objects if kind in LABELLED_FORMATS else None
        dropped = ds.objects is not None and kind not in LABELLED_FORMATS
        truth = ground_truth_columns(ds, offset) if boxes else None
    t = np.concatenate([b.t for b in parts]) + offset if parts else np.empty(0, np.int64)
    if len(t) and t[0] < 0:
        raise UserError(f"{dataset_path}: /t_offset {offset} makes timestamps negative, which event files cannot hold")
    x, y, p = (np.concatenate([getattr(b, k) for b in parts]) if parts else np.empty(0, np.uint16) for k in "xyp")
    objects = None
    if table is not None:
        objects = np.concatenate([b.object for b in parts]) if parts else np.empty(0, np.uint8)
    if dropped:
        warnings.warn(f"{out}: a .{out.suffix.lstrip('.').lower()} file has no field for {dataset_path}'s per-event "
                      "object labels, so they are left out (a .csv export keeps them)", LabelsLeftOut, stacklevel=2)
    written = {}
    with run_outputs() as run:  # all written to temp names, renamed together when all are complete
        with replacing(out) as tmp_events:
            write_event_file(tmp_events, t, x, y, p, width, height, evt_version, objects)
        if table is not None:
            import csv

            with replacing(sides["objects"]) as tmp_table, open(tmp_table, "w", newline="") as fh:
                w = csv.writer(fh, lineterminator="\n")
                w.writerow(["id", "name", "role"])
                w.writerows([r["id"], r["name"], r["role"]] for r in table)
            written["objects"] = sides["objects"]
        if boxes:
            with replacing(sides["boxes"]) as tmp_boxes:
                write_box_csv(tmp_boxes, track.t + offset, track.xywh)
            with replacing(sides["gt"]) as tmp_gt:
                write_gt_csv(tmp_gt, truth)
            written.update(boxes=sides["boxes"], gt=sides["gt"])
        for side_kind in SIDE_FILES:
            side = side_path(out, side_kind)
            if side_kind not in written and side.is_file() and _side_kind(side) == side_kind:
                run.remove(side)  # the previous export's: it goes in the same commit
    return [out, *written.values()]
