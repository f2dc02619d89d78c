"""The dvsot dataset file (HDF5, format version 2): a streaming writer and a lazy reader.

Layout (DSEC-compatible events, see docs/ARCHITECTURE.md and DESIGN.md):

    /events/x, /events/y   u2  pixel
    /events/t              i8  microseconds since the sequence start
    /events/p              u1  1 = brighter, 0 = darker
    /events/signal         u1  1 = signal, 0 = noise event (present when the generator flags them)
    /events/ms_to_idx      u8  index of the first event with t >= ms * 1000, for ms = 0 .. duration_ms
    /boxes/t               i8  microseconds, one row per rendered sample
    /boxes/xywh            f4  (N, 4) amodal target box (target rendered alone); NaN = absent
    /boxes/xywh_visible    f4  (N, 4) visible part of the target (occluders kept)
    /segments/t            i8  (M,) end time of each segment, microseconds
    /segments/xywh         f4  (M, 4) ground truth per segment, at the segment's end time
    /segments/xywh_visible f4  (M, 4) visible-part ground truth per segment
    /segments/annotation   i8  (M,) recordings only: the /boxes row matched to each segment, -1 = none
    /ms_to_idx                 a hard link to /events/ms_to_idx (where DSEC's and tonic's readers look)
    /t_offset              i8  scalar, microseconds added to /events/t to get the recording's own clock
                               (0 for synthetic data)

Event columns are byte-shuffled and gzip (level 1) compressed, filters every HDF5 library has, so
h5dump and readers outside h5py open them. Version 1 files (LZF, no root link, no /t_offset) still load, with offset 0.

The writer appends events in chunks and computes `ms_to_idx` as it goes, so a sequence of hundreds
of millions of events never sits in memory. It writes to a temporary name beside the target and
renames on success, so an interrupted run leaves no file that looks complete. Every dataset carries
HDF5's Fletcher-32 checksum, so flipped bits in a chunk fail the read instead of returning garbage.

The reader checks the layout and attributes when it opens a file, and the invariants of every batch
of events it loads (time order, time window, pixel range, 0/1 flags) on the data already in memory;
`Dataset.chunks` streams and checks the whole file. Any violation is a one-line UserError naming the
file and the dataset or attribute. Files written before checksums were added still load.

Box values are checked on open too (finite, w, h > 0 or four NaNs, near the sensor: dvsot.validate),
and the writer stores a SHA-256 of the root attributes' canonical JSON as root attribute
`attrs_sha256`, so a changed or corrupted attribute is an error on open; files written before the
digest (no `attrs_sha256`) load without that check. Whole datasets read into memory are bounded in
rows (dvsot.validate), so a damaged or hostile file cannot make the reader allocate gigabytes.
"""

from __future__ import annotations

import glob as globmod
import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterator

import h5py
import numpy as np

from dvsot import validate
from dvsot.background import OrderedWorker
from dvsot.errors import RunError, UserError
from dvsot.events import EventBatch

FORMAT = "dvsot"
FORMAT_VERSION = 2
# name -> h5py filter options for event columns. gzip and shuffle are built into every HDF5 library; gzip 1
# after the byte shuffle is ~0.4x LZF's size and as fast to read (benchmarks/perf/bench_compression.py)
COMPRESSIONS: dict[str | None, dict[str, Any]] = {
    "gzip": {"compression": "gzip", "compression_opts": 1, "shuffle": True},
    "gzip-noshuffle": {"compression": "gzip", "compression_opts": 1},
    "lzf": {"compression": "lzf"},  # version 1's choice: h5py-only, h5dump and hdf5plugin cannot read it
    None: {},
}
_EVENT_CHUNK = 1 << 18  # events per HDF5 chunk and per flush of the write buffer
_REQUIRED = ("events/x", "events/y", "events/t", "events/p", "events/ms_to_idx",
             "boxes/t", "boxes/xywh", "boxes/xywh_visible", "segments/t", "segments/xywh")


@dataclass(frozen=True)
class BoxTrack:
    """The target's box at every rendered sample: t (microseconds), xywh and xywh_visible (pixels, NaN = absent)."""

    t: np.ndarray
    xywh: np.ndarray
    xywh_visible: np.ndarray


@dataclass(frozen=True)
class Segment:
    """The events of [t0_us, t1_us) and the ground-truth box (pixels, NaN if absent) at t1_us."""

    index: int
    t0_us: int
    t1_us: int
    events: EventBatch
    box: np.ndarray
    box_visible: np.ndarray | None = None


def _encode_attr(value: Any) -> Any:
    """An HDF5-storable attribute value: containers and None become JSON text."""
    if isinstance(value, (dict, list, tuple)) or value is None:
        return json.dumps(value, sort_keys=True, default=str)
    if isinstance(value, Path):
        return str(value)
    return value


def _write_attr(attrs: h5py.AttributeManager, key: str, value: Any) -> None:
    """Store an attribute; text as fixed-length UTF-8, whose bytes sit in the attribute itself: a damaged
    variable-length string points into a heap, and HDF5 can crash the process following it."""
    if isinstance(value, str):
        data = value.encode("utf-8")
        attrs.create(key, np.array(data, dtype=h5py.string_dtype("utf-8", max(1, len(data)))))
    else:
        attrs[key] = value


def _decode_attr(value: Any) -> Any:
    """The Python value of an HDF5 attribute: JSON text of containers is parsed back."""
    if isinstance(value, bytes):
        value = value.decode("utf-8", "replace")
    if isinstance(value, str) and (value.startswith(("{", "[")) or value == "null"):
        try:
            return json.loads(value)
        except json.JSONDecodeError:
            return value
    if isinstance(value, np.generic):
        return value.item()
    return value


def _interpolate_boxes(t_samples: np.ndarray, xywh: np.ndarray, t_query: np.ndarray) -> np.ndarray:
    from dvsot.boxes import interpolate_boxes  # box geometry lives in dvsot.boxes

    return interpolate_boxes(t_samples, xywh, t_query)


def _readlink(path: str) -> str | None:
    try:
        return os.readlink(path)
    except OSError:
        return None


class DatasetWriter:
    """Streams events and boxes into a new dataset file; renames it into place only on success."""

    def __init__(self, path: str | os.PathLike, width: int, height: int, segment_us: int = 10_000,
                 attrs: dict[str, Any] | None = None, compression: str | None = "gzip",
                 checksum: bool = True, t_offset_us: int = 0, annotated: bool = False) -> None:
        if width <= 0 or height <= 0 or width * height > validate.MAX_SENSOR_PIXELS:
            raise ValueError(f"width and height must be positive, at most {validate.MAX_SENSOR_PIXELS} pixels in "
                             f"all, got {width}x{height}")
        if segment_us < validate.MIN_SEGMENT_US:
            raise ValueError(f"segment_us must be at least {validate.MIN_SEGMENT_US}, got {segment_us}")
        self.path = Path(path)
        if not self.path.parent.is_dir():
            raise UserError(f"{self.path}: output directory {self.path.parent} does not exist")
        self.width, self.height, self.segment_us = int(width), int(height), int(segment_us)
        from dvsot.outputs import RunOutputs, current_run

        # staged beside the target (host, pid and a random token in its name); renamed at close, or with the
        # other outputs of the enclosing run_outputs() block
        self._own_run = None if current_run() is not None else RunOutputs()
        self._run = current_run() or self._own_run
        if compression not in COMPRESSIONS:
            raise ValueError(f"compression must be one of {sorted(map(str, COMPRESSIONS))}, got {compression!r}")
        self.tmp_path = self._run.stage(self.path, ready=False)
        self._compression = compression
        self._filter = COMPRESSIONS[compression]
        self.t_offset_us = int(t_offset_us)  # the recording's clock minus /events/t, microseconds
        # annotated: boxes are annotations at their own times (a recording), scored only where one matches a
        # segment (dvsot.boxes.match_annotations), never interpolated; else a rendered track, interpolated
        self.annotated = bool(annotated)
        self._checksum = bool(checksum)  # Fletcher-32 per chunk: about 0.1% of size, detects flipped bits on read
        self._attrs: dict[str, Any] = dict(attrs or {})
        self._file = None
        try:
            self._file = h5py.File(self.tmp_path, "w")
            ev = self._file.create_group("events")
            for name, dtype in (("x", np.uint16), ("y", np.uint16), ("t", np.int64), ("p", np.uint8)):
                ev.create_dataset(name, shape=(0,), maxshape=(None,), dtype=dtype, chunks=(_EVENT_CHUNK,),
                                  fletcher32=self._checksum, **self._filter)
        except BaseException as exc:
            self._io = None
            self.__exit__(type(exc), exc, None)  # the temp removed; a full disk is one RunError line
            raise
        self._has_signal: bool | None = None
        self._buffer: list[EventBatch] = []
        self._buffered = 0
        self._count = 0
        self._last_t = -(1 << 62)
        self._ms_to_idx: list[np.ndarray] = []
        self._next_ms = 0  # the first millisecond boundary whose index is not known yet
        self._box_t: list[np.ndarray] = []
        self._box_xywh: list[np.ndarray] = []
        self._box_vis: list[np.ndarray] = []
        self._io: OrderedWorker | None = None  # the writer thread, started by the first flush
        self._closed = False

    def __enter__(self) -> "DatasetWriter":
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None and not self._closed:
            self.close()
        elif exc_type is not None:
            self.abort()
            from dvsot.outputs import disk_error

            reason = disk_error(exc)
            if reason is not None:  # a full disk: one line naming the output, not h5py's traceback
                raise RunError(f"{self.path}: cannot write ({reason}); nothing was replaced") from None

    @property
    def num_events(self) -> int:
        """Events appended so far."""
        return self._count + self._buffered

    def set_attrs(self, **attrs: Any) -> None:
        """Set root attributes (JSON-serialisable values; containers are stored as JSON text)."""
        self._attrs.update(attrs)

    def append_events(self, batch: EventBatch) -> None:
        """Append a time-ordered batch whose first event is not earlier than the last one appended."""
        n = len(batch)
        if n == 0:
            return
        t = np.asarray(batch.t, dtype=np.int64)
        if t[0] < self._last_t or (n > 1 and np.any(np.diff(t) < 0)):
            raise ValueError("events must be appended in time order")
        if t[0] < 0:
            raise ValueError("event timestamps must be >= 0")
        if t[-1] >= validate.MAX_DURATION_US:  # before ms_to_idx grows: an epoch time would ask for terabytes
            raise ValueError(f"an event at {int(t[-1])} us lies beyond the {validate.MAX_DURATION_S} s a file holds; "
                             f"rebase the timestamps and keep the start in t_offset_us")
        if self._has_signal is None:
            self._has_signal = batch.signal is not None
            if self._has_signal:
                self._file["events"].create_dataset("signal", shape=(0,), maxshape=(None,), dtype=np.uint8,
                                                    chunks=(_EVENT_CHUNK,), fletcher32=self._checksum,
                                                    **self._filter)
        elif self._has_signal != (batch.signal is not None):
            raise ValueError("either every event batch carries signal flags or none does")
        # ms boundaries up to the newest timestamp are now decided by this batch or earlier ones.
        last_ms = int(t[-1] // 1000)
        if last_ms >= self._next_ms:
            bounds = np.arange(self._next_ms, last_ms + 1, dtype=np.int64) * 1000
            idx = self.num_events + np.searchsorted(t, bounds, side="left")
            self._ms_to_idx.append(idx.astype(np.uint64))
            self._next_ms = last_ms + 1
        self._last_t = int(t[-1])
        self._buffer.append(batch)
        self._buffered += n
        if self._buffered >= _EVENT_CHUNK:
            self._flush()

    def _flush(self) -> None:
        """Hand the buffered events to the writer thread (compression overlaps with the caller's work)."""
        if not self._buffer:
            return
        joined = EventBatch.concatenate(self._buffer)
        n0, n1 = self._count, self._count + len(joined)
        columns = {"x": joined.x.astype(np.uint16, copy=False), "y": joined.y.astype(np.uint16, copy=False),
                   "t": joined.t.astype(np.int64, copy=False), "p": joined.p.astype(np.uint8, copy=False)}
        if self._has_signal:
            columns["signal"] = joined.signal.view(np.uint8) if joined.signal.dtype == bool else \
                joined.signal.astype(np.uint8)
        if self._io is None:
            self._io = OrderedWorker(f"write {self.path.name}")
        self._io.submit(self._write_columns, n0, n1, columns)
        self._count = n1
        self._buffer, self._buffered = [], 0

    def _write_columns(self, n0: int, n1: int, columns: dict[str, np.ndarray]) -> None:
        """Write events n0..n1-1 (runs on the writer thread; the only thread touching the file until close)."""
        ev = self._file["events"]
        try:
            for name, values in columns.items():
                ds = ev[name]
                ds.resize((n1,))
                ds[n0:n1] = values
                ds.flush()  # a write error (a full disk) raises here, not later in a destructor that cannot
        except BaseException:
            self._discard_writes()
            raise

    def _discard_writes(self) -> None:
        """Send the doomed file's further writes to memory, so HDF5's flushes at close neither fail nor crash."""
        # the descriptor found through /proc (Linux): HDF5's own accessor crashes on a file whose flush failed
        try:
            target = os.path.realpath(self.tmp_path)
            fds = [int(fd) for fd in os.listdir("/proc/self/fd") if _readlink(f"/proc/self/fd/{fd}") == target]
            for fd in fds:
                # an in-memory file takes HDF5's writes and its truncation to the file's end (sparse, no memory)
                sink = os.memfd_create("dvsot-discarded") if hasattr(os, "memfd_create") else os.open(os.devnull, os.O_RDWR)
                os.dup2(sink, fd)
                os.close(sink)
        except OSError:
            pass

    def append_boxes(self, t_us: Any, xywh: Any, xywh_visible: Any = None) -> None:
        """Append box rows at times t_us (microseconds); xywh (N,4) pixels, NaN = absent; visible defaults to amodal."""
        t = np.atleast_1d(np.asarray(t_us, dtype=np.int64))
        b = np.asarray(xywh, dtype=np.float32).reshape(-1, 4)
        v = b if xywh_visible is None else np.asarray(xywh_visible, dtype=np.float32).reshape(-1, 4)
        if not (len(t) == len(b) == len(v)):
            raise ValueError("box times and rows differ in length")
        self._box_t.append(t)
        self._box_xywh.append(b)
        self._box_vis.append(v)

    def close(self, duration_us: int | None = None) -> Path:
        """Finish the file (ms_to_idx, per-segment ground truth, attributes) and rename it into place."""
        if self._closed:
            return self.path
        try:
            self._flush()
            if self._io is not None:
                self._io.wait()  # every event chunk is written (or its error raised here)
                self._io.stop()
            box_t = np.concatenate(self._box_t) if self._box_t else np.empty(0, np.int64)
            box_xywh = np.concatenate(self._box_xywh) if self._box_xywh else np.empty((0, 4), np.float32)
            box_vis = np.concatenate(self._box_vis) if self._box_vis else np.empty((0, 4), np.float32)
            if len(box_t) > 1 and np.any(np.diff(box_t) <= 0):
                raise ValueError("box sample times must be strictly increasing")
            for what, rows in (("xywh", box_xywh), ("xywh_visible", box_vis)):
                problem = validate.box_problem(rows, self.width, self.height)
                if problem:
                    raise ValueError(f"boxes {what}: {problem}")
            if duration_us is None:
                candidates = [self._last_t + 1 if self._count else 0, int(box_t[-1]) if len(box_t) else 0]
                duration_us = max(candidates)
            duration_us = int(duration_us)
            if duration_us > validate.MAX_DURATION_US:
                raise ValueError(f"duration {duration_us} us exceeds the bound of {validate.MAX_DURATION_S} s per file")
            if self._count and self._last_t >= duration_us:
                raise ValueError(f"an event at {self._last_t} us lies beyond the duration {duration_us} us")
            duration_ms = -(-duration_us // 1000)
            tail = np.full(max(0, duration_ms + 1 - self._next_ms), self._count, dtype=np.uint64)
            ms_to_idx = np.concatenate(self._ms_to_idx + [tail])[: duration_ms + 1]
            f = self._file
            ck = {"fletcher32": self._checksum}
            f["events"].create_dataset("ms_to_idx", data=ms_to_idx.astype(np.uint64), **ck)
            f["ms_to_idx"] = f["events/ms_to_idx"]  # a hard link: one table, two names
            f.create_dataset("t_offset", data=np.int64(self.t_offset_us))
            g = f.create_group("boxes")
            g.create_dataset("t", data=box_t, maxshape=(None,), **ck)
            g.create_dataset("xywh", data=box_xywh, maxshape=(None, 4), **ck)
            g.create_dataset("xywh_visible", data=box_vis, maxshape=(None, 4), **ck)
            n_seg = duration_us // self.segment_us
            seg_t = (np.arange(n_seg, dtype=np.int64) + 1) * self.segment_us
            if self.annotated:
                from dvsot.boxes import match_annotations

                match = match_annotations(box_t, self.segment_us, n_seg)
                nan = np.full((1, 4), np.nan, np.float32)
                seg_box = np.where((match >= 0)[:, None], np.concatenate([box_xywh, nan])[match], nan)
                seg_vis = np.where((match >= 0)[:, None], np.concatenate([box_vis, nan])[match], nan)
            elif len(box_t):
                seg_box = _interpolate_boxes(box_t, box_xywh, seg_t).astype(np.float32)
                seg_vis = _interpolate_boxes(box_t, box_vis, seg_t).astype(np.float32)
            else:
                seg_box = np.full((n_seg, 4), np.nan, np.float32)
                seg_vis = seg_box.copy()
            s = f.create_group("segments")
            s.create_dataset("t", data=seg_t, **ck)
            s.create_dataset("xywh", data=seg_box.reshape(-1, 4), **ck)
            s.create_dataset("xywh_visible", data=seg_vis.reshape(-1, 4), **ck)
            if self.annotated:
                s.create_dataset("annotation", data=match, **ck)
            attrs = {"name": self.path.name.removesuffix(".h5"), "split": ""}
            attrs.update(self._attrs)
            attrs.update(format=FORMAT, format_version=FORMAT_VERSION, width=self.width, height=self.height,
                         segment_us=self.segment_us, duration_us=duration_us, num_events=self._count,
                         ground_truth="annotations" if self.annotated else "rendered")
            for key, value in attrs.items():
                _write_attr(f.attrs, key, _encode_attr(value))
            # over the values as a reader decodes them, so both sides hash the same thing
            stored = {k: _decode_attr(v) for k, v in f.attrs.items()}
            _write_attr(f.attrs, validate.DIGEST_ATTR, validate.attrs_digest(stored))
            f.flush()  # a full disk fails here, with the file still open (HDF5 crashes on a failed close)
            f.close()
            _read_back(self.tmp_path, self.path)
            self._run.done(self.path)
            if self._own_run is not None:
                from dvsot.outputs import writing

                with writing(self.path):
                    self._own_run.commit()
        except BaseException:
            self.abort()
            raise
        self._closed = True
        return self.path

    def abort(self) -> None:
        """Discard the temporary file; nothing at the target path is touched."""
        self._closed = True
        if self._io is not None:
            self._io.stop()  # the chunk being written finishes; the file is closed after it
        self._discard_writes()  # on a full disk HDF5's flushes at close fail again and again, then crash at exit
        try:
            self._file.close()
        except Exception:
            pass
        self._run.drop(self.path)


def _read_back(tmp: Path, path: Path) -> None:
    """Open the finished temp file as a reader would and read every event: a file that fails its checks (a chunk
    whose Fletcher-32 checksum does not match, seen once in a long render) raises RunError and never replaces path."""
    from dvsot.errors import RunError

    try:
        with Dataset(tmp) as ds:
            ds.verify()
    except UserError as exc:
        raise RunError(f"{path}: the file just written failed its read-back check, nothing replaced "
                       f"({str(exc).removeprefix(str(tmp) + ': ')})") from None


# Each known dataset's allowed numpy dtype kinds ('u'/'i' integer, 'b' bool, 'f' float) and shape: (N,) or (N, 4).
_LAYOUT: dict[str, tuple[str, int]] = {
    "events/x": ("ui", 1), "events/y": ("ui", 1), "events/t": ("ui", 1), "events/p": ("uib", 1),
    "events/signal": ("uib", 1), "events/ms_to_idx": ("ui", 1), "ms_to_idx": ("ui", 1),
    "boxes/t": ("ui", 1), "boxes/xywh": ("uif", 2), "boxes/xywh_visible": ("uif", 2),
    "segments/t": ("ui", 1), "segments/xywh": ("uif", 2), "segments/xywh_visible": ("uif", 2),
    "segments/annotation": ("i", 1),
}
_MAX_PIXELS = 1 << 16  # x and y are stored as u2
_KIND_WORDS = {"ui": "integers", "uib": "integers or booleans", "uif": "numbers"}
# Datasets that must have as many rows as the first one of their group.
_SAME_ROWS = (("events/t", "events/x", "events/y", "events/p", "events/signal"),
              ("boxes/t", "boxes/xywh", "boxes/xywh_visible"),
              ("segments/xywh", "segments/t", "segments/xywh_visible", "segments/annotation"))


class _Damaged(Exception):
    """A broken invariant of the file format; Dataset turns it into a UserError naming the file."""


def _check_layout(f: h5py.File) -> None:
    """Raise _Damaged unless the required datasets exist and every known one has the right type, dtype, shape, rows."""
    missing = [name for name in _REQUIRED if name not in f]
    if missing:
        raise _Damaged(f"missing /{missing[0]}")
    for name, (kinds, rank) in _LAYOUT.items():
        if name not in f:
            continue
        try:
            obj = f[name]
        except (KeyError, OSError) as exc:  # e.g. a dangling link: listed, but nothing behind it
            raise _Damaged(f"/{name} cannot be opened ({_short(exc)})") from None
        if not isinstance(obj, h5py.Dataset):
            raise _Damaged(f"/{name} is a {type(obj).__name__.lower()}, not a dataset")
        if obj.dtype.kind not in kinds:
            raise _Damaged(f"/{name} has dtype {obj.dtype}, expected {_KIND_WORDS[kinds]}")
        if obj.ndim != rank or (rank == 2 and obj.shape[1] != 4):
            raise _Damaged(f"/{name} has shape {obj.shape}, expected {'(N,)' if rank == 1 else '(N, 4)'}")
    for group in _SAME_ROWS:
        rows = {name: f[name].shape[0] for name in group if name in f}
        first = group[0]
        for name, n in rows.items():
            if n != rows[first]:
                raise _Damaged(f"/{name} has {n} rows, /{first} has {rows[first]}")


def _check_root_links(f: h5py.File, version: int) -> int:
    """Raise _Damaged unless root /ms_to_idx is /events/ms_to_idx and /t_offset a scalar integer; return the offset (us)."""
    if version >= 2:
        for name in ("ms_to_idx", "t_offset"):
            if name not in f:
                raise _Damaged(f"missing /{name}")
    if "ms_to_idx" in f:
        root, events = f["ms_to_idx"], f["events/ms_to_idx"]
        # a copy that kept the values (e.g. a tool that does not preserve hard links) is as good as the link
        if root.id != events.id and (root.shape != events.shape or not np.array_equal(root[()], events[()])):
            raise _Damaged("/ms_to_idx differs from /events/ms_to_idx")
    if "t_offset" not in f:
        return 0
    obj = f["t_offset"]
    if not isinstance(obj, h5py.Dataset) or obj.shape != () or obj.dtype.kind not in "ui":
        raise _Damaged("/t_offset is not a scalar integer (microseconds)")
    return int(obj[()])


def _int_attr(attrs: dict[str, Any], name: str, minimum: int, maximum: int | None = None) -> int:
    """Root attribute `name` as an int in [minimum, maximum]; raise _Damaged naming it when it is not."""
    if name not in attrs:
        raise _Damaged(f"root attribute '{name}' is missing")
    value = attrs[name]
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not float(value).is_integer():
        raise _Damaged(f"root attribute '{name}' is {repr(value)[:40]}, expected an integer")
    if value < minimum:
        raise _Damaged(f"root attribute '{name}' is {int(value)}, expected >= {minimum}")
    if maximum is not None and value > maximum:
        raise _Damaged(f"root attribute '{name}' is {int(value)}, expected <= {maximum}")
    return int(value)


def _check_sizes(f: h5py.File) -> None:
    """Raise _Damaged if a dataset the reader loads whole is longer than dvsot.validate's bounds allow."""
    limits = {"events/ms_to_idx": (validate.MAX_DURATION_US // 1000 + 1, f"{validate.MAX_DURATION_S} s per file"),
              "segments/xywh": (validate.MAX_DURATION_US // validate.MIN_SEGMENT_US,
                                f"{validate.MAX_DURATION_S} s in segments of at least {validate.MIN_SEGMENT_US} us"),
              "boxes/t": (validate.MAX_BOX_ROWS, "box samples per file")}
    for name, (bound, why) in limits.items():
        problem = validate.rows_problem(name, f[name].shape[0], bound, why)
        if problem:
            raise _Damaged(problem)


def _check_duration(duration_us: int, segment_us: int, n_ms_to_idx: int, n_segments: int) -> None:
    """Raise _Damaged unless /events/ms_to_idx and /segments/xywh are as long as duration_us (microseconds) implies."""
    want_ms, want_seg = -(-duration_us // 1000) + 1, duration_us // segment_us
    ms_ok, seg_ok = n_ms_to_idx == want_ms, n_segments == want_seg
    if not ms_ok and not seg_ok:  # two tables written independently agree with each other, not with the attribute
        raise _Damaged(f"root attribute 'duration_us' is {duration_us}, which disagrees with /events/ms_to_idx "
                       f"({n_ms_to_idx} entries, expected {want_ms}) and /segments/xywh ({n_segments} rows, "
                       f"expected {want_seg})")
    if not ms_ok:
        raise _Damaged(f"/events/ms_to_idx has {n_ms_to_idx} entries, expected {want_ms} for duration_us {duration_us}")
    if not seg_ok:
        raise _Damaged(f"/segments/xywh has {n_segments} rows, expected {want_seg} "
                       f"(duration_us {duration_us} / segment_us {segment_us})")


def _ms_to_idx_problem(ms_to_idx: np.ndarray, num_events: int) -> str | None:
    """What is wrong with a whole ms_to_idx table (event indices per millisecond), or None."""
    if len(ms_to_idx) and (int(ms_to_idx[0]) != 0 or int(ms_to_idx[-1]) != num_events):
        return (f"/events/ms_to_idx runs from {int(ms_to_idx[0])} to {int(ms_to_idx[-1])}, "
                f"expected 0 to num_events {num_events}")
    down = np.flatnonzero(ms_to_idx[1:] < ms_to_idx[:-1])  # compared, not diffed: u8 differences wrap around
    if len(down):
        return f"/events/ms_to_idx decreases at ms {int(down[0]) + 1}"
    return None


def _times_problem(t: np.ndarray, t0_us: int, t1_us: int, first: int, source: str) -> str | None:
    """What is wrong with sorted timestamps (microseconds) of events first.. meant to lie in [t0_us, t1_us), or None."""
    # `source` names what set the window: a time outside it may be bad data or a bad index, so both are named
    if len(t) == 0:
        return None
    if np.any(t[1:] < t[:-1]):
        i = int(np.flatnonzero(t[1:] < t[:-1])[0])
        return f"/events/t is not in time order at event {first + i + 1} ({int(t[i])} us, then {int(t[i + 1])} us)"
    if t[0] < t0_us or t[-1] >= t1_us:  # sorted, so the ends bound every value
        i = 0 if t[0] < t0_us else len(t) - 1
        return f"/events/t holds {int(t[i])} us at event {first + i}, outside [{t0_us}, {t1_us}) us given by {source}"
    return None


def _columns_problem(columns: dict[str, np.ndarray], limits: dict[str, tuple[int, str]], first: int) -> str | None:
    """What is wrong with event columns whose values must lie in [0, limit) (limits: name -> (limit, why)), or None."""
    for name, values in columns.items():
        limit, why = limits[name]
        if len(values) == 0 or values.dtype.kind == "b":
            continue
        # unsigned columns (the written dtype) cannot be negative: skip the extra pass over them
        if values.max() >= limit or (values.dtype.kind == "i" and values.min() < 0):
            i = int(np.flatnonzero((values < 0) | (values >= limit))[0])
            return f"/events/{name} holds {int(values[i])} at event {first + i}, {why}"
    return None


class Dataset:
    """A dataset file opened lazily: events by time, fixed-length segments with ground truth, boxes, metadata."""

    def __init__(self, path: str | os.PathLike) -> None:
        self.path = Path(path)
        kind = validate.file_kind_problem(self.path)
        if kind:
            raise UserError(f"{self.path}: " + ("no such dataset file" if kind == "no such file" else
                                                f"{kind}, not a dataset file"))
        try:
            self._file = h5py.File(self.path, "r")
        except (OSError, RuntimeError) as exc:
            raise UserError(f"{self.path}: not a readable HDF5 file ({_short(exc)})") from None
        try:
            self._validate()
        except UserError:
            self._file.close()
            raise
        except _Damaged as exc:
            self._file.close()
            raise UserError(f"{self.path}: damaged dvsot file ({exc})") from None
        except (OSError, KeyError, ValueError, TypeError, RuntimeError) as exc:  # h5py: RuntimeError for broken metadata
            self._file.close()
            raise UserError(f"{self.path}: damaged dvsot file ({_short(exc)})") from None

    def _validate(self) -> None:
        f = self._file
        if _decode_attr(f.attrs.get("format", "")) != FORMAT:
            raise UserError(f"{self.path}: not a dvsot dataset file (root attribute 'format' is not '{FORMAT}')")
        version = _int_attr({k: _decode_attr(v) for k, v in f.attrs.items()}, "format_version", -(2**62))
        if not 1 <= version <= FORMAT_VERSION:
            raise UserError(f"{self.path}: format_version {version} is not supported (this dvsot reads 1..{FORMAT_VERSION})")
        _check_layout(f)
        self.t_offset_us = _check_root_links(f, version)
        self.attrs: dict[str, Any] = {k: _decode_attr(v) for k, v in f.attrs.items()}
        self.width = _int_attr(self.attrs, "width", 1, _MAX_PIXELS)
        self.height = _int_attr(self.attrs, "height", 1, _MAX_PIXELS)
        if self.width * self.height > validate.MAX_SENSOR_PIXELS:
            raise _Damaged(f"root attributes 'width' x 'height' are {self.width}x{self.height}, more than the bound "
                           f"of {validate.MAX_SENSOR_PIXELS} pixels")
        self.segment_us = _int_attr(self.attrs, "segment_us", 1)
        self.duration_us = _int_attr(self.attrs, "duration_us", 0)
        self.format_version = version
        self.name = str(self.attrs.get("name") or self.path.stem)
        self.split = str(self.attrs.get("split") or "")
        ev = f["events"]
        self._has_signal = "signal" in ev
        # keep the column objects open: HDF5's chunk cache lives with them, and reopening one per read
        # would decompress a whole 2 MB chunk for every query (10x slower segment reads)
        self._columns = {name: ev[name] for name in ("x", "y", "t", "p", "signal") if name in ev}
        self.num_events = int(ev["t"].shape[0])
        if "num_events" in self.attrs and _int_attr(self.attrs, "num_events", 0) != self.num_events:
            raise _Damaged(f"root attribute 'num_events' is {self.attrs['num_events']}, "
                           f"but /events/t has {self.num_events} rows")
        _check_duration(self.duration_us, self.segment_us, ev["ms_to_idx"].shape[0], f["segments/xywh"].shape[0])
        _check_sizes(f)
        self._ms_to_idx = self._load("events/ms_to_idx")
        problem = _ms_to_idx_problem(self._ms_to_idx, self.num_events)
        if problem:
            raise _Damaged(problem)
        self._seg_box = self._load("segments/xywh").astype(np.float32)
        vis = self._load("segments/xywh_visible") if "segments/xywh_visible" in f else None
        self._seg_vis = None if vis is None else vis.astype(np.float32)
        self.num_segments = int(self._seg_box.shape[0])
        # recordings: the /boxes row each segment is scored against (-1: none), dvsot.boxes.match_annotations
        self._seg_ann = self._load("segments/annotation").astype(np.int64) if "segments/annotation" in f else None
        n_boxes = f["boxes/t"].shape[0]
        if self._seg_ann is not None and len(self._seg_ann) and not (
                -1 <= self._seg_ann.min() and self._seg_ann.max() < n_boxes):
            raise _Damaged(f"/segments/annotation holds rows outside -1..{n_boxes - 1} (/boxes has {n_boxes})")
        for name in ("segments/xywh", "segments/xywh_visible", "boxes/xywh", "boxes/xywh_visible"):
            rows = self._seg_box if name == "segments/xywh" else self._load(name) if name in f else None
            problem = None if rows is None else validate.box_problem(rows, self.width, self.height)
            if problem:
                raise _Damaged(f"/{name} {problem}")
        problem = validate.digest_problem(self.attrs)
        if problem:
            raise _Damaged(problem)
        self._limits = {"x": (self.width, f"expected 0 <= x < width {self.width}"),
                        "y": (self.height, f"expected 0 <= y < height {self.height}"),
                        "p": (2, "expected 0 or 1"), "signal": (2, "expected 0 or 1")}
        if self.num_events:  # two chunk reads: in a sorted file the ends bound every timestamp
            first = int(self._read("t", 0, 1)[0])
            last = int(self._read("t", self.num_events - 1, self.num_events)[0])
            if not 0 <= first <= last < self.duration_us:
                raise _Damaged(f"/events/t runs from {first} us to {last} us, expected "
                               f"0 <= first <= last < root attribute 'duration_us' ({self.duration_us})")

    def __enter__(self) -> "Dataset":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def close(self) -> None:
        """Close the underlying HDF5 file."""
        self._file.close()

    def __repr__(self) -> str:
        return (f"Dataset({str(self.path)!r}, {self.width}x{self.height}, {self.duration_us / 1e6:.3f} s, "
                f"{self.num_events} events, {self.num_segments} segments)")

    def _damaged(self, problem: str) -> UserError:
        """The UserError for a broken invariant found after opening."""
        return UserError(f"{self.path}: damaged dvsot file ({problem})")

    def _load(self, name: str) -> np.ndarray:
        """A whole small dataset (ms_to_idx, boxes, segments) read into memory; a failed read names it."""
        try:
            return self._file[name][()]
        except (OSError, ValueError, RuntimeError) as exc:  # a Fletcher-32 mismatch or a broken chunk surfaces as OSError
            raise self._damaged(f"cannot read /{name}, its stored data is corrupt ({_short(exc)})") from None

    def _index_at(self, t_us: int) -> int:
        """Index of the first event with t >= t_us, from ms_to_idx and a search inside one millisecond."""
        if t_us <= 0:
            return 0
        ms = t_us // 1000
        if ms >= len(self._ms_to_idx) - 1:
            return self.num_events
        lo, hi = int(self._ms_to_idx[ms]), int(self._ms_to_idx[ms + 1])
        if lo == hi or t_us % 1000 == 0:
            return lo
        ts = self._read("t", lo, hi)
        # a search in bad times finds a bad index
        problem = _times_problem(ts, ms * 1000, (ms + 1) * 1000, lo, f"/events/ms_to_idx[{ms}]")
        if problem:
            raise self._damaged(problem)
        return lo + int(np.searchsorted(ts, t_us, side="left"))

    def _read(self, column: str, i0: int, i1: int) -> np.ndarray:
        try:
            return self._columns[column][i0:i1]
        except (OSError, ValueError, RuntimeError) as exc:  # a Fletcher-32 mismatch or a broken chunk surfaces as OSError
            raise self._damaged(f"cannot read /events/{column} events {i0}..{i1 - 1}, its stored data is corrupt "
                                f"({_short(exc)})") from None

    def _batch(self, i0: int, i1: int, t0_us: int, t1_us: int, source: str) -> EventBatch:
        """Events i0..i1-1, checked: sorted times in [t0_us, t1_us) (microseconds), pixels on the sensor, 0/1 flags."""
        columns = {name: self._read(name, i0, i1) for name in ("x", "y", "t", "p")}
        if self._has_signal:
            columns["signal"] = self._read("signal", i0, i1)
        t = columns.pop("t")
        problem = _times_problem(t, t0_us, t1_us, i0, source) or _columns_problem(columns, self._limits, i0)
        if problem:
            raise self._damaged(problem)
        sig = columns["signal"].astype(bool) if self._has_signal else None
        return EventBatch(columns["x"], columns["y"], t, columns["p"], sig)

    def events(self, t0_us: int, t1_us: int) -> EventBatch:
        """The events with t0_us <= t < t1_us (microseconds), found via ms_to_idx without a full scan."""
        t0_us, t1_us = int(t0_us), int(t1_us)
        i0, i1 = self._index_at(t0_us), self._index_at(t1_us)
        if i1 <= i0:
            return EventBatch.empty()
        return self._batch(i0, i1, max(t0_us, 0), min(t1_us, self.duration_us), "/events/ms_to_idx and duration_us")

    def chunks(self, step: int = 1 << 22) -> Iterator[EventBatch]:
        """Every event in order, `step` at a time, each batch checked like events() and against ms_to_idx."""
        prev_t, next_ms = 0, 0  # the last timestamp seen (microseconds) and the first ms boundary not yet checked
        for i0 in range(0, self.num_events, step):
            i1 = min(i0 + step, self.num_events)
            batch = self._batch(i0, i1, prev_t, self.duration_us, "time order and duration_us")
            last_ms = int(batch.t[-1]) // 1000
            # boundaries after the previous batch's last event and up to this one's are decided by this batch
            ms = np.arange(next_ms, last_ms + 1)
            want = i0 + np.searchsorted(batch.t, ms * 1000, side="left")
            bad = np.flatnonzero(self._ms_to_idx[next_ms:last_ms + 1].astype(np.int64) != want)
            if len(bad):
                m = int(ms[bad[0]])
                raise self._damaged(f"/events/ms_to_idx[{m}] is {int(self._ms_to_idx[m])}, but the first event "
                                    f"at or after {m * 1000} us is event {int(want[bad[0]])}")
            prev_t, next_ms = int(batch.t[-1]), last_ms + 1
            yield batch
        if np.any(self._ms_to_idx[next_ms:] != self.num_events):  # boundaries after the last event
            raise self._damaged(f"/events/ms_to_idx points before the end after the last event ({prev_t} us)")

    def verify(self) -> None:
        """Read and check every event (a full scan); a broken invariant raises UserError naming the file and dataset."""
        for _ in self.chunks():
            pass

    def segment(self, i: int) -> Segment:
        """Segment i: the events of [i*segment_us, (i+1)*segment_us) and the ground truth at its end."""
        if not 0 <= i < self.num_segments:
            raise IndexError(f"segment {i} out of range 0..{self.num_segments - 1}")
        t0, t1 = i * self.segment_us, (i + 1) * self.segment_us
        vis = None if self._seg_vis is None else self._seg_vis[i].copy()
        return Segment(i, t0, t1, self.events(t0, t1), self._seg_box[i].copy(), vis)

    def segments(self, start: int = 0, stop: int | None = None) -> Iterator[Segment]:
        """Segments start..stop-1 in order."""
        stop = self.num_segments if stop is None else min(stop, self.num_segments)
        for i in range(start, stop):
            yield self.segment(i)

    def segment_boxes(self) -> np.ndarray:
        """Ground truth of every segment, (num_segments, 4) xywh pixels, NaN = absent."""
        return self._seg_box.copy()

    @property
    def annotated(self) -> bool:
        """True for a recording whose boxes are annotations at their own times (scored only where matched)."""
        return self._seg_ann is not None

    def segment_scored(self) -> np.ndarray:
        """Per segment, whether its ground truth may be scored: every segment of a rendered file, matched ones of a recording."""
        if self._seg_ann is None:
            return np.ones(self.num_segments, bool)
        return self._seg_ann >= 0

    def segment_annotations(self) -> np.ndarray | None:
        """Per segment, the /boxes row of its annotation (-1: none), or None for a rendered file."""
        return None if self._seg_ann is None else self._seg_ann.copy()

    def boxes(self) -> BoxTrack:
        """The box track at every rendered sample (or annotation): t (microseconds), xywh and xywh_visible (pixels)."""
        return BoxTrack(*(self._load(f"boxes/{name}") for name in ("t", "xywh", "xywh_visible")))


def _short(exc: BaseException) -> str:
    """An exception's message on one line."""
    return " ".join(str(exc).split()) or type(exc).__name__


def open_dataset(path: str | os.PathLike) -> Dataset:
    """Open a dataset file for reading; a foreign or damaged file raises UserError."""
    return Dataset(path)


def find_datasets(spec: str | os.PathLike | list, split: str | None = None, verify: bool = True,
                  need_events: bool = False) -> list[Path]:
    """Dataset files named by a directory, a glob, a file or a list of those, optionally of one split; all checked
    (need_events: a file without events is an error, e.g. for training)."""
    specs = [spec] if isinstance(spec, (str, os.PathLike)) else list(spec)
    paths: list[Path] = []
    for item in specs:
        p = Path(item)
        if p.is_dir():
            found = sorted(p.glob("*.h5"))
        elif any(ch in str(item) for ch in "*?["):
            found = sorted(Path(x) for x in globmod.glob(str(item)))
        elif p.exists():  # a file, or a FIFO or device: Dataset says what it is
            found = [p]
        else:
            raise UserError(f"{item}: no such file or directory")
        paths.extend(found)
    result: list[Path] = []
    for p in dict.fromkeys(paths):
        with Dataset(p) as ds:
            if split is None or ds.split == split:
                if verify:  # bench and train find their files here: a damaged one stops them before any output
                    ds.verify()
                if need_events and ds.num_events == 0:
                    raise UserError(f"{p}: the file holds no events (nothing to learn from)")
                result.append(p)
    if not result:
        where = ", ".join(str(s) for s in specs)
        raise UserError(f"{where}: no dvsot dataset files" + (f" of split '{split}'" if split else ""))
    return result
