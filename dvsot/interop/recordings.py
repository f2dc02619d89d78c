"""Recorded sequences into dataset files: an events file plus FE108/VisEvent-style boxes at annotation times.

A sequence is an events file (AEDAT4, EVT2/3, DAT, CSV, TXT: dvsot.interop.event_files) and optionally
- a box file, one box per annotated frame: `x,y,w,h` (FE108's groundtruth_rect.txt, VisEvent's
  groundtruth.txt; commas, tabs or spaces) with the annotation times given apart (`box_times`, one
  integer microsecond per line on the events' clock), or `t_s,x,y,w,h` with the time in seconds
  (what `dvsot export` writes beside the events); a row of NaNs or of four zeros is "no target";
- an absent file, one 0/1 per box (1 = target absent, GOT-10k's absence.label convention).
With `box_times_from_frames`, the annotation times are the timestamps of the AEDAT4 events file's
frame track, one per box (FE108: one box per APS frame of the same recording).

Timestamps are rebased to the earliest event or annotation: that time goes to `/t_offset`, so an
epoch-microsecond recording gives a file as small as any other. Boxes are kept at their annotation
times and the file is marked annotated: `dvsot bench` scores a segment only against an annotation
matched to it (dvsot.dataset.boxes.match_annotations), never an interpolated box. `interpolate=True` instead
treats the boxes as a dense track (a rendered one exported by dvsot) and interpolates as `generate` does.
Every input is read and checked before the output is opened; each error names file, line and field.
"""

from __future__ import annotations

import os
import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dvsot.core.defaults import IMPORT_EVT_VERSION, SEGMENT_US
from dvsot.core.errors import UserError, label
from dvsot.interop.event_files import EventFile, frame_times, read_event_file

_SPLIT = re.compile(r"[,\t ]+")
_CHUNK = 1 << 20  # events handed to the writer at a time


@dataclass(frozen=True)
class BoxFile:
    """Boxes read from a box file: xywh (N, 4) pixels (NaN = absent), t_us (N,) or None, and each row's line."""

    xywh: np.ndarray
    t_us: np.ndarray | None
    lines: list[int]
    path: Path


def _numbers(path: Path, what: str, fields: tuple[int, ...]) -> tuple[np.ndarray, list[int]]:
    """Rows of numbers of a text file (all with one of `fields` counts), and their line numbers; errors name the
    line."""
    from dvsot.interop.text_inputs import text_lines

    numbered = text_lines(path, what)
    if not numbered:
        raise UserError(f"{path}: no {what}")
    rows, count = [], None
    for no, text in numbered:
        cells = [c for c in _SPLIT.split(text) if c]
        if len(cells) not in fields or (count is not None and len(cells) != count):
            want = count or " or ".join(map(str, fields))
            raise UserError(f"{path}:{no}: {len(cells)} fields, expected {want} ({what})")
        count = len(cells)
        try:
            rows.append([float(c) for c in cells])
        except ValueError:
            bad = next(c for c in cells if not _is_number(c))
            raise UserError(f"{path}:{no}: field {cells.index(bad) + 1} is {bad!r}, not a number ({what})") from None
    return np.array(rows, np.float64), [no for no, _ in numbered]


def _is_number(text: str) -> bool:
    try:
        float(text)
        return True
    except ValueError:
        return False


def read_box_file(path: str | os.PathLike, width: int, height: int) -> BoxFile:
    """Boxes of a box file (x,y,w,h or t_s,x,y,w,h per line), checked against a width x height sensor."""
    from dvsot.dataset.boxes import box_problem

    p = Path(path)
    rows, lines = _numbers(p, "boxes x,y,w,h or t_s,x,y,w,h", (4, 5))
    t = None
    if rows.shape[1] == 5:
        from dvsot.interop.text_events import exact_microseconds

        t, bad, why = exact_microseconds(rows[:, 0], "txt")  # seconds, exact to the microsecond or refused
        if bad is not None:
            raise UserError(f"{p}:{lines[bad]}: {why.replace('field t ', 'field t_s ', 1)}")
        rows = rows[:, 1:]
    xywh = rows.copy()
    xywh[(xywh == 0).all(axis=1)] = np.nan  # FE108 and VisEvent write 0,0,0,0 for "no target"
    problem = box_problem(xywh, width, height, lambda i: f"line {lines[i]}: the box")
    if problem:
        m = re.match(r"line (\d+): (.*)", problem)
        raise UserError(f"{p}:{m.group(1)}: {m.group(2)}" if m else f"{p}: {problem}")
    # an annotation is of a target seen in the frame: some of it must lie on the sensor
    with np.errstate(invalid="ignore"):
        off = ~np.isnan(xywh).any(axis=1) & ((xywh[:, 0] >= width) | (xywh[:, 1] >= height)
                                              | (xywh[:, 0] + xywh[:, 2] <= 0) | (xywh[:, 1] + xywh[:, 3] <= 0))
    if off.any():
        i = int(np.flatnonzero(off)[0])
        x, y, w, h = (f"{v:g}" for v in xywh[i])
        raise UserError(f"{p}:{lines[i]}: the box x={x} y={y} w={w} h={h} lies outside the {width}x{height} sensor")
    return BoxFile(xywh.astype(np.float32), t, lines, p)


def _per_box(p: Path, what: str, plural: str, count: int) -> tuple[np.ndarray, list[int]]:
    """One number per line of a text file, one line per box: the values and their line numbers; UserError if the
    file holds another count."""
    rows, lines = _numbers(p, what, (1,))
    if len(rows) != count:
        raise UserError(f"{p}: {len(rows)} {plural} for {count} boxes (one per line, one per box)")
    return rows[:, 0], lines


def read_box_times(path: str | os.PathLike, count: int) -> np.ndarray:
    """Annotation times, one integer microsecond per line, strictly increasing, one per box."""
    p = Path(path)
    t, lines = _per_box(p, "annotation times (integer microseconds)", "annotation times", count)
    bad = np.flatnonzero(~(t == np.floor(t)) | ~(np.abs(t) < 2 ** 53))  # NaN too; float64 holds integers to 2**53
    if len(bad):
        raise UserError(f"{p}:{lines[bad[0]]}: {t[bad[0]]:g} is not an integer number of microseconds")
    return t.astype(np.int64)


def read_absent(path: str | os.PathLike, count: int) -> np.ndarray:
    """Absent flags, one 0/1 per line and box (1 = the target is absent)."""
    p = Path(path)
    flags, lines = _per_box(p, "absent flags (0 or 1)", "absent flags", count)
    bad = np.flatnonzero((flags != 0) & (flags != 1))
    if len(bad):
        raise UserError(f"{p}:{lines[bad[0]]}: {flags[bad[0]]:g}, expected 0 (present) or 1 (absent)")
    return flags.astype(bool)


def _check_times(ev: EventFile, boxes: BoxFile | None, box_t: np.ndarray | None, times_path: Path | None,
                 row: str = "row") -> int:
    """The time origin (us): the earliest event or annotation; UserError when the times cannot share one file.

    row: what the times file's entries are called in messages (a row of a text file, a frame of a frame track)."""
    from dvsot.core.bounds import MAX_DURATION_S, MAX_DURATION_US

    source = times_path or (boxes.path if boxes else None)
    if box_t is not None:
        bad = np.flatnonzero(np.diff(box_t) <= 0)
        if len(bad):
            where = f"{source}:{boxes.lines[bad[0] + 1]}" if times_path is None else f"{source}: {row} {bad[0] + 2}"
            raise UserError(f"{where}: annotation time {int(box_t[bad[0] + 1])} us does not come after "
                            f"{int(box_t[bad[0]])} us; annotation times must increase")
        if box_t[-1] < ev.t[0] or box_t[0] > ev.t[-1]:
            raise UserError(f"{source}: the annotation times ({int(box_t[0])}..{int(box_t[-1])} us) do not overlap "
                            f"the events of {ev.path} ({int(ev.t[0])}..{int(ev.t[-1])} us); are they on one clock?")
    start = int(ev.t[0]) if box_t is None else min(int(ev.t[0]), int(box_t[0]))
    end = int(ev.t[-1]) if box_t is None else max(int(ev.t[-1]), int(box_t[-1]))
    if end - start >= MAX_DURATION_US:
        gaps = np.diff(ev.t)
        i = int(np.argmax(gaps)) + 1 if len(gaps) else 0
        raise UserError(f"{ev.where(i)}: field t jumps by {gaps[i - 1] / 1e6:.0f} s (from {int(ev.t[i - 1])} us to "
                        f"{int(ev.t[i])} us): the sequence would span {(end - start) / 1e6:.0f} s, more than the "
                        f"{MAX_DURATION_S} s a dataset file holds (epoch and relative timestamps mixed?)"
                        if len(gaps) and gaps[i - 1] >= MAX_DURATION_US else
                        f"{ev.path}: events and annotations span {(end - start) / 1e6:.0f} s, more than the "
                        f"{MAX_DURATION_S} s a dataset file holds")
    return start


def import_recording(events: str | os.PathLike, out: str | os.PathLike, boxes: str | os.PathLike | None = None,
                     box_times: str | os.PathLike | None = None, absent: str | os.PathLike | None = None,
                     size: tuple[int, int] | None = None, segment_us: int = SEGMENT_US,
                     evt_version: str = IMPORT_EVT_VERSION, interpolate: bool = False,
                     labels: Mapping[str, str] | None = None, box_times_from_frames: bool = False,
                     header: bool = False) -> Path:
    """Write an events file (and its boxes) into a dataset file; every input is checked before anything is written.

    box_times_from_frames: the annotation times are the events file's AEDAT4 frame timestamps, one per box.
    labels: how messages name the settings out, boxes, box_times, box_times_from_frames, size and segment_us (a
    command's flags); header: the CSV or TXT events file's first line is a header line, not an event."""
    from dvsot import __version__
    from dvsot.core.bounds import MAX_SEGMENT_US, MIN_SEGMENT_US, range_problem
    from dvsot.dataset import DatasetWriter
    from dvsot.events import EventBatch
    from dvsot.runtime.outputs import output_file

    problem = range_problem(label("segment_us", labels), segment_us, MIN_SEGMENT_US, MAX_SEGMENT_US, "us")
    if problem:
        raise UserError(problem)
    output_file(out, label("out", labels), [x for x in (events, boxes, box_times, absent) if x])

    if box_times and box_times_from_frames:
        raise UserError(f"{box_times}: give annotation times either as a file ({label('box_times', labels)}) or "
                        f"from the frame track ({label('box_times_from_frames', labels)}), not both")
    if (box_times or absent or box_times_from_frames) and not boxes:
        raise UserError(f"{box_times or absent or events}: annotation times and absent flags need a box file "
                        f"({label('boxes', labels)})")
    ev = read_event_file(events, size, evt_version, label("size", labels), header)
    track, box_t = None, None
    if boxes:
        track = read_box_file(boxes, ev.width, ev.height)
        if (box_times or box_times_from_frames) and track.t_us is not None:
            given = label("box_times_from_frames" if box_times_from_frames else "box_times", labels)
            raise UserError(f"{boxes}: the boxes carry their own times (t_s,x,y,w,h); give no {given}")
        if box_times_from_frames:
            box_t = frame_times(events)
            if len(box_t) != len(track.xywh):
                raise UserError(f"{boxes}: {len(track.xywh)} boxes for the {len(box_t)} frames of the frame track of "
                                f"{events} (one box per frame)")
        else:
            box_t = read_box_times(box_times, len(track.xywh)) if box_times else track.t_us
        if box_t is None:
            raise UserError(f"{boxes}: boxes x,y,w,h have no times; give {label('box_times', labels)} FILE "
                            "(one annotation time per line, microseconds on the events' clock) or a box file of "
                            "t_s,x,y,w,h")
        if absent:
            xywh = track.xywh.copy()
            xywh[read_absent(absent, len(xywh))] = np.nan
            track = BoxFile(xywh, track.t_us, track.lines, track.path)
    times_path = Path(events) if box_times_from_frames else Path(box_times) if box_times else None
    origin = _check_times(ev, track, box_t, times_path, "frame" if box_times_from_frames else "row")
    attrs = {"source": {"events": str(events), "boxes": str(boxes) if boxes else None,
                        "box_times": str(box_times) if box_times else ("frames" if box_times_from_frames else None),
                         "absent": str(absent) if absent else None},
             "generator": "dvsot import", "versions": {"dvsot": __version__}}
    t = ev.t - origin
    # the file covers the last event and the last box: a track's last sample, or the segment end
    # that may score the last annotation (half a segment after it)
    end = int(t[-1]) + 1
    if box_t is not None:
        end = max(end, int(box_t[-1] - origin) + (0 if interpolate else segment_us // 2))
    if end < segment_us:
        raise UserError(f"{events}: the recording spans {end} us, less than one segment of {segment_us} us "
                        f"({label('segment_us', labels)}): the file would hold no segment to track")
    with DatasetWriter(out, ev.width, ev.height, segment_us, attrs=attrs, t_offset_us=origin,
                       annotated=bool(boxes) and not interpolate) as writer:
        for i in range(0, len(t), _CHUNK):
            s = slice(i, i + _CHUNK)
            writer.append_events(EventBatch(ev.x[s].astype(np.uint16), ev.y[s].astype(np.uint16), t[s],
                                            ev.p[s].astype(np.uint8)))
        if track is not None:
            writer.append_boxes(box_t - origin, track.xywh)
        writer.close(end)
    return Path(out)
