"""The dataset file's streaming writer: events appended in chunks (ms_to_idx computed as they come), boxes,
then at close the per-segment ground truth (dvsot.dataset.segment_truth) and attributes; staged under a temporary
name and renamed on success."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from dvsot.core import bounds
from dvsot.core.defaults import SEGMENT_US
from dvsot.core.errors import RunError, UserError
from dvsot.dataset.boxes import box_problem
from dvsot.dataset.digest import DIGEST_ATTR, attrs_digest
from dvsot.dataset.format import (
    COMPRESSIONS,
    FORMAT,
    FORMAT_VERSION,
    OBJECT_TRUTH,
    BoxTrack,
    attrs_problem,
    read_attrs,
    write_attr,
    write_attrs,
)
from dvsot.dataset.h5chunks import encode_chunk
from dvsot.dataset.reader import Dataset, chunk_digest
from dvsot.dataset.segment_truth import SegmentTruth, segment_truth
from dvsot.events import EventBatch
from dvsot.events.batch import NOISE_KINDS
from dvsot.runtime.threads import OrderedWorker

_EVENT_CHUNK = 1 << 18  # events per HDF5 chunk and per flush of the write buffer


def _mask_filter(event_filter: dict[str, Any]) -> dict[str, Any]:
    """The filters of /masks/objects given the event columns': gzip at level 4 without the shuffle (one byte per
    pixel: nothing to shuffle; level 4 stores half of level 1's bytes at 0.9 ms per 320x240 sample, docs/results.md),
    else the same filter."""
    if event_filter.get("compression") == "gzip":
        return {"compression": "gzip", "compression_opts": 4}
    return dict(event_filter)


def _readlink(path: str) -> str | None:
    """The target of a symbolic link (a /proc/self/fd entry), or None."""
    try:
        return os.readlink(path)
    except OSError:
        return None


class DatasetWriter:
    """Streams events and boxes into a new dataset file; renames it into place only on success."""

    def __init__(self, path: str | os.PathLike, width: int, height: int, segment_us: int = SEGMENT_US,
                 attrs: dict[str, Any] | None = None, compression: str | None = "gzip",
                 checksum: bool = True, t_offset_us: int = 0, annotated: bool = False,
                 objects: list[dict] | None = None) -> None:
        if width <= 0 or height <= 0 or width * height > bounds.MAX_SENSOR_PIXELS:
            raise ValueError(f"width and height must be positive, at most {bounds.MAX_SENSOR_PIXELS} pixels in "
                             f"all, got {width}x{height}")
        if segment_us < bounds.MIN_SEGMENT_US:
            raise ValueError(f"segment_us must be at least {bounds.MIN_SEGMENT_US}, got {segment_us}")
        self.path = Path(path)
        problem = attrs_problem(attrs or {})
        if problem:  # before any work: a scene's text is known before its frames are rendered
            raise UserError(f"{self.path}: {problem}")
        if not self.path.parent.is_dir():
            raise UserError(f"{self.path}: output directory {self.path.parent} does not exist")
        self.width, self.height, self.segment_us = int(width), int(height), int(segment_us)
        from dvsot.runtime.outputs import RunOutputs, current_run

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
        # segment (dvsot.dataset.boxes.match_annotations), never interpolated; else a rendered track, interpolated
        self.annotated = bool(annotated)
        self._checksum = bool(checksum)  # Fletcher-32 per chunk: about 0.1% of size, detects flipped bits on read
        self._attrs: dict[str, Any] = dict(attrs or {})
        # objects: the table of object ids (dvsot.events.labels.object_table); then every event carries its id
        self._objects = None if objects is None else [dict(row) for row in objects]
        if self._objects is not None:
            from dvsot.events.labels import table_problem

            problem = table_problem(np.array([r["id"] for r in self._objects]), [r["name"] for r in self._objects],
                                    [r["role"] for r in self._objects])
            if problem:
                raise ValueError(f"object table: {problem}")
            self._known_ids = np.zeros(256, bool)
            self._known_ids[[r["id"] for r in self._objects]] = True
        self._file = None
        try:
            self._file = h5py.File(self.tmp_path, "w")
            ev = self._file.create_group("events")
            columns = [("x", np.uint16), ("y", np.uint16), ("t", np.int64), ("p", np.uint8)]
            if self._objects is not None:
                columns.append(("object", np.uint8))
            for name, dtype in columns:
                ev.create_dataset(name, shape=(0,), maxshape=(None,), dtype=dtype, chunks=(_EVENT_CHUNK,),
                                  fletcher32=self._checksum, **self._filter)
        except BaseException as exc:
            self._io = None
            self.__exit__(type(exc), exc, None)  # the temp removed; a full disk is one RunError line
            raise
        self._has_signal: bool | None = None
        self._has_kind: bool | None = None
        self._buffer: list[EventBatch] = []
        self._buffered = 0
        self._count = 0
        self._last_t = -(1 << 62)
        self._ms_to_idx: list[np.ndarray] = []
        self._next_ms = 0  # the first millisecond boundary whose index is not known yet
        self._box_t: list[np.ndarray] = []
        self._box_xywh: list[np.ndarray] = []
        self._box_vis: list[np.ndarray] = []
        self._visibility: list[np.ndarray | None] = []
        self._truncation: list[np.ndarray | None] = []
        self._object_rows: dict[str, list[np.ndarray]] = {name: [] for name in OBJECT_TRUTH}
        self._masks = 0  # object index images appended (/masks/objects rows)
        self._mask_ids = np.zeros(256, bool)  # the ids those images hold: attribute 'ids' of /masks/objects
        self._io: OrderedWorker | None = None  # the writer thread, started by the first flush
        # per gzip column, the digest of every chunk handed to HDF5, in order: the read-back compares them
        self._digests: dict[str, list[bytes]] = {}
        self._closed = False

    def __enter__(self) -> DatasetWriter:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None and not self._closed:
            self.close()
        elif exc_type is not None:
            self.abort()
            from dvsot.runtime.outputs import disk_error

            reason = None if isinstance(exc, RunError) else disk_error(exc)  # a RunError names its own output
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
        # checked here, not only by the read-back: that compares the stored chunks with the ones written
        columns = [("x", batch.x, self.width), ("y", batch.y, self.height), ("p", batch.p, 2)]
        if batch.signal is not None:
            columns.append(("signal", batch.signal, 2))
        if batch.noise_kind is not None:
            columns.append(("noise_kind", batch.noise_kind, len(NOISE_KINDS)))
        if (batch.object is not None) != (self._objects is not None):
            raise ValueError("events carry object ids exactly when the writer has an object table")
        if batch.object is not None:
            ids = np.asarray(batch.object)
            if ids.shape != t.shape:
                raise ValueError(f"event object ids: {ids.shape[0]} for {n} events")
            known = (ids >= 0) & (ids <= 255) & self._known_ids[np.clip(ids, 0, 255).astype(np.intp)]
            if not known.all():
                raise ValueError(f"event object id {int(ids[~known][0])} is not in the object table")
        for name, values, limit in columns:
            v = np.asarray(values)
            if v.max() >= limit or (v.dtype.kind in "if" and v.min() < 0):
                raise ValueError(f"event {name} must lie in 0..{limit - 1}, got {v.min()}..{v.max()}")
        if t[-1] >= bounds.MAX_DURATION_US:  # before ms_to_idx grows: an epoch time would ask for terabytes
            raise ValueError(f"an event at {int(t[-1])} us lies beyond the {bounds.MAX_DURATION_S} s a file holds; "
                             f"rebase the timestamps and keep the start in t_offset_us")
        if self._has_signal is None:
            self._has_signal = batch.signal is not None
            if self._has_signal:
                self._on_writer(self._create_column, "signal")
        elif self._has_signal != (batch.signal is not None):
            raise ValueError("either every event batch carries signal flags or none does")
        if self._has_kind is None:
            self._has_kind = batch.noise_kind is not None
            if self._has_kind:
                self._on_writer(self._create_column, "noise_kind")
        elif self._has_kind != (batch.noise_kind is not None):
            raise ValueError("either every event batch carries noise kinds or none does")
        # ms boundaries up to the newest timestamp are now decided by this batch or earlier ones.
        last_ms = int(t[-1] // 1000)
        if last_ms >= self._next_ms:
            ms_starts = np.arange(self._next_ms, last_ms + 1, dtype=np.int64) * 1000
            idx = self.num_events + np.searchsorted(t, ms_starts, side="left")
            self._ms_to_idx.append(idx.astype(np.uint64))
            self._next_ms = last_ms + 1
        self._last_t = int(t[-1])
        self._buffer.append(batch)
        self._buffered += n
        if self._buffered >= _EVENT_CHUNK:
            self._flush()

    def _flush(self, final: bool = False) -> None:
        """Hand the buffered events to the writer thread in whole chunks (all if final); the rest stays buffered.

        Whole chunks let the gzip columns go to the file as chunks encoded outside HDF5 (dvsot.dataset.h5chunks),
        and their compression overlaps with the caller's work.
        """
        if not self._buffer:
            return
        joined = EventBatch.concatenate(self._buffer)
        k = len(joined) if final else len(joined) // _EVENT_CHUNK * _EVENT_CHUNK
        if k == 0:
            return
        rest = joined.select(slice(k, None))
        if k < len(joined):
            joined = joined.select(slice(0, k))
        n0, n1 = self._count, self._count + k
        columns = {"x": joined.x.astype(np.uint16, copy=False), "y": joined.y.astype(np.uint16, copy=False),
                   "t": joined.t.astype(np.int64, copy=False), "p": joined.p.astype(np.uint8, copy=False)}
        if self._has_signal:
            columns["signal"] = joined.signal.view(np.uint8) if joined.signal.dtype == bool else \
                joined.signal.astype(np.uint8)
        if self._has_kind:
            columns["noise_kind"] = joined.noise_kind.astype(np.uint8, copy=False)
        if self._objects is not None:
            columns["object"] = joined.object.astype(np.uint8, copy=False)
        self._on_writer(self._write_columns, n0, n1, columns)
        self._count = n1
        self._buffer, self._buffered = ([rest], len(rest)) if len(rest) else ([], 0)

    def _on_writer(self, fn: Any, *args: Any) -> None:
        """Run fn(*args) on the writer thread, after everything handed to it before.

        Every change to the file between opening and close goes through here, in call order, so the objects are
        created and their space allocated in the same order whatever the threads' timing: the same inputs give
        byte-identical files.
        """
        if self._io is None:
            self._io = OrderedWorker(f"write {self.path.name}")
        self._io.submit(fn, *args)

    def _create_column(self, name: str) -> None:
        """Create the empty event column `name` of uint8 (runs on the writer thread)."""
        try:
            self._file["events"].create_dataset(name, shape=(0,), maxshape=(None,), dtype=np.uint8,
                                                chunks=(_EVENT_CHUNK,), fletcher32=self._checksum, **self._filter)
        except BaseException:
            self._discard_writes()
            raise

    def _write_columns(self, n0: int, n1: int, columns: dict[str, np.ndarray]) -> None:
        """Write events n0..n1-1 (runs on the writer thread; the only thread touching the file until close).

        n0 is a multiple of the chunk length; gzip columns are written as chunks encoded by dvsot.dataset.h5chunks
        (the filters HDF5 would apply, with a faster deflate), the other compressions through HDF5's filters.
        """
        ev = self._file["events"]
        try:
            for name, values in columns.items():
                ds = ev[name]
                ds.resize((n1,))
                if self._compression == "gzip":
                    for c0 in range(n0, n1, _EVENT_CHUNK):
                        chunk = encode_chunk(values[c0 - n0:c0 - n0 + _EVENT_CHUNK], _EVENT_CHUNK, self._checksum)
                        ds.id.write_direct_chunk((c0,), chunk)
                        self._digests.setdefault(name, []).append(chunk_digest(chunk))
                else:
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
                sink = (
                    os.memfd_create("dvsot-discarded")
                    if hasattr(os, "memfd_create")
                    else os.open(os.devnull, os.O_RDWR)
                )
                os.dup2(sink, fd)
                os.close(sink)
        except OSError:
            pass

    def append_boxes(self, t_us: Any, xywh: Any, xywh_visible: Any = None, visibility: Any = None,
                     truncation: Any = None) -> None:
        """Append box rows at times t_us (microseconds); xywh (N,4) pixels, NaN = absent; visible defaults to amodal;
        visibility (N,): visible / amodal target pixels on the sensor, 0..1; truncation (N,): the share of the
        target's whole silhouette off the sensor, 0..1 (each: every call gives it or none does)."""
        t = np.atleast_1d(np.asarray(t_us, dtype=np.int64))
        b = np.asarray(xywh, dtype=np.float32).reshape(-1, 4)
        v = b if xywh_visible is None else np.asarray(xywh_visible, dtype=np.float32).reshape(-1, 4)
        if not (len(t) == len(b) == len(v)):
            raise ValueError("box times and rows differ in length")
        shares = []
        for what, values, kept in (("visibility", visibility, self._visibility),
                                   ("truncation", truncation, self._truncation)):
            if values is not None:
                values = np.asarray(values, dtype=np.float32).reshape(-1)
                if len(values) != len(t):
                    raise ValueError(f"box times and {what} differ in length")
                if np.any(~((values >= 0) & (values <= 1))):
                    raise ValueError(f"{what} must lie in 0..1")
            if kept and (kept[0] is None) != (values is None):
                raise ValueError(f"either every box append gives {what} or none does")
            shares.append(values)
        self._box_t.append(t)
        self._box_xywh.append(b)
        self._box_vis.append(v)
        self._visibility.append(shares[0])
        self._truncation.append(shares[1])

    def append_object_rows(self, rows: dict[str, Any]) -> None:
        """Append every object's ground truth at n samples (dvsot.dataset.boxes.object_rows, stacked: (n, K, ...)),
        K the object table's rows in its order; the file's /objects/<name> for each of OBJECT_TRUTH."""
        if self._objects is None:
            raise ValueError("per-object ground truth needs the writer's object table")
        if set(rows) != set(OBJECT_TRUTH):
            raise ValueError(f"object rows need exactly {', '.join(OBJECT_TRUTH)}, got {', '.join(sorted(rows))}")
        k = len(self._objects)
        n = None
        for name in OBJECT_TRUTH:
            a = np.asarray(rows[name])
            tail = (k, 4) if name.startswith("boxes") else (k,)
            if a.ndim == len(tail):
                a = a[None]
            if a.shape[1:] != tail or (n is not None and len(a) != n):
                raise ValueError(f"object rows {name}: shape {a.shape}, expected (n, {', '.join(map(str, tail))})")
            n = len(a)
            if name in ("visibility", "truncation") and np.any((a < 0) | (a > 1)):
                raise ValueError(f"object rows {name} must lie in 0..1 (NaN: no geometry)")
            if name == "px_visible" and np.any(a.astype(np.int64).sum(axis=1) != self.width * self.height):
                raise ValueError("object rows px_visible do not add up to the sensor's pixels: the index image "
                                 "holds an id outside the object table")
            dtype = np.uint32 if name.startswith("px") else np.float32
            self._object_rows[name].append(a.astype(dtype))

    def append_mask(self, index_image: Any) -> None:
        """Append the next sample's object index image (u1 height x width, ids of the object table) to /masks/objects;
        written on the writer thread, one gzip chunk per sample, so a long sequence's masks never sit in memory."""
        if self._objects is None:
            raise ValueError("masks need the writer's object table")
        img = np.asarray(index_image)
        if img.shape != (self.height, self.width):
            raise ValueError(f"mask of shape {img.shape}, expected ({self.height}, {self.width})")
        img = img.astype(np.uint8, copy=False)
        if not self._known_ids[img].all():
            raise ValueError(f"mask id {int(img[~self._known_ids[img]][0])} is not in the object table")
        self._mask_ids |= np.bincount(img.ravel(), minlength=256).astype(bool)
        self._on_writer(self._write_mask, self._masks, img.copy())
        self._masks += 1

    def _write_mask(self, row: int, img: np.ndarray) -> None:
        """Write mask row `row` (runs on the writer thread, in order with the event columns; the first creates the
        dataset there, so no other thread touches the file)."""
        try:
            if row == 0:
                self._file.create_group("masks").create_dataset(
                    "objects", shape=(0, self.height, self.width), maxshape=(None, self.height, self.width),
                    dtype=np.uint8, chunks=(1, self.height, self.width), fletcher32=self._checksum,
                    **_mask_filter(self._filter))
            ds = self._file["masks/objects"]
            ds.resize((row + 1, self.height, self.width))
            ds[row] = img
        except BaseException:
            self._discard_writes()
            raise

    def close(self, duration_us: int | None = None) -> Path:
        """Finish the file (ms_to_idx, per-segment ground truth, attributes) and rename it into place."""
        if self._closed:
            return self.path
        try:
            self._finish_events()
            track = self._box_track()
            duration_us = self._duration(duration_us, track.t)
            truth = segment_truth(track, duration_us, self.segment_us, self.annotated)
            self._write_tables(duration_us, track, truth)
            self._write_attributes(duration_us)
            self._commit()
        except BaseException:
            self.abort()
            raise
        self._closed = True
        return self.path

    def _finish_events(self) -> None:
        """Write the buffered events and wait for the writer thread (its error, a full disk, raises here)."""
        self._flush(final=True)
        if self._io is not None:
            self._io.wait()
            self._io.stop()

    def _box_track(self) -> BoxTrack:
        """Every box appended, joined and checked: times strictly increasing, rows within the sensor."""
        t = np.concatenate(self._box_t) if self._box_t else np.empty(0, np.int64)
        xywh = np.concatenate(self._box_xywh) if self._box_xywh else np.empty((0, 4), np.float32)
        visible = np.concatenate(self._box_vis) if self._box_vis else np.empty((0, 4), np.float32)
        if len(t) > 1 and np.any(np.diff(t) <= 0):
            raise ValueError("box sample times must be strictly increasing")
        for what, rows in (("xywh", xywh), ("xywh_visible", visible)):
            problem = box_problem(rows, self.width, self.height)
            if problem:
                raise ValueError(f"boxes {what}: {problem}")
        visibility = np.concatenate(self._visibility) if self._visibility and self._visibility[0] is not None else None
        truncation = np.concatenate(self._truncation) if self._truncation and self._truncation[0] is not None else None
        for what, rows in (("masks", self._masks), ("object rows", sum(map(len, self._object_rows["visibility"])))):
            if rows and rows != len(t):
                raise ValueError(f"{rows} {what} for {len(t)} box samples")
        return BoxTrack(t, xywh, visible, visibility, truncation)

    def _duration(self, duration_us: int | None, box_t: np.ndarray) -> int:
        """The file's duration in microseconds: the one given, checked against the events and boxes, or else the
        later of the last event's time + 1 and the last box's time."""
        if duration_us is None:
            candidates = [self._last_t + 1 if self._count else 0, int(box_t[-1]) if len(box_t) else 0]
            duration_us = max(candidates)
        duration_us = int(duration_us)
        if duration_us > bounds.MAX_DURATION_US:
            raise ValueError(f"duration {duration_us} us exceeds the bound of {bounds.MAX_DURATION_S} s per file")
        if self._count and self._last_t >= duration_us:
            raise ValueError(f"an event at {self._last_t} us lies beyond the duration {duration_us} us")
        if len(box_t) and not (0 <= box_t[0] and box_t[-1] <= duration_us):
            raise ValueError(f"box times run from {int(box_t[0])} us to {int(box_t[-1])} us, outside the file's "
                             f"0..{duration_us} us")
        if duration_us < self.segment_us:
            raise ValueError(f"a duration of {duration_us} us holds no segment of {self.segment_us} us")
        return duration_us

    def _write_tables(self, duration_us: int, track: BoxTrack, truth: SegmentTruth) -> None:
        """Write ms_to_idx, t_offset, the box track, the per-segment ground truth and the object table."""
        duration_ms = -(-duration_us // 1000)
        tail = np.full(max(0, duration_ms + 1 - self._next_ms), self._count, dtype=np.uint64)
        ms_to_idx = np.concatenate(self._ms_to_idx + [tail])[: duration_ms + 1]
        f = self._file
        ck = {"fletcher32": self._checksum}
        f["events"].create_dataset("ms_to_idx", data=ms_to_idx.astype(np.uint64), **ck)
        f["ms_to_idx"] = f["events/ms_to_idx"]  # a hard link: one table, two names
        f.create_dataset("t_offset", data=np.int64(self.t_offset_us))
        g = f.create_group("boxes")
        g.create_dataset("t", data=track.t, maxshape=(None,), **ck)
        g.create_dataset("xywh", data=track.xywh, maxshape=(None, 4), **ck)
        g.create_dataset("xywh_visible", data=track.xywh_visible, maxshape=(None, 4), **ck)
        s = f.create_group("segments")
        s.create_dataset("t", data=truth.t, **ck)
        s.create_dataset("xywh", data=truth.xywh, **ck)
        s.create_dataset("xywh_visible", data=truth.xywh_visible, **ck)
        if truth.annotation is not None:
            s.create_dataset("annotation", data=truth.annotation, **ck)
        if track.visibility is not None:
            g.create_dataset("visibility", data=track.visibility, maxshape=(None,), **ck)
            s.create_dataset("visibility", data=truth.visibility, **ck)
            s.create_dataset("absent", data=truth.absent.astype(np.uint8), **ck)
        if track.truncation is not None:
            g.create_dataset("truncation", data=track.truncation, maxshape=(None,), **ck)
            s.create_dataset("truncation", data=truth.truncation, **ck)
        if self._objects is not None:
            o = f.create_group("objects")
            o.create_dataset("id", data=np.array([r["id"] for r in self._objects], np.uint8), **ck)
            for key in ("name", "role"):  # fixed-length UTF-8: no heap a damaged file could point into
                text = [str(r[key]).encode("utf-8") for r in self._objects]
                o.create_dataset(key, data=np.array(text, dtype=f"S{max([1, *map(len, text)])}"), **ck)
            if self._object_rows["visibility"]:
                for name in OBJECT_TRUTH:
                    o.create_dataset(name, data=np.concatenate(self._object_rows[name]), **ck, **self._filter)
        if self._masks:  # the reader checks these ids against the table on open, without reading the images
            f["masks/objects"].attrs["ids"] = np.flatnonzero(self._mask_ids).astype(np.uint8)

    def _write_attributes(self, duration_us: int) -> None:
        """Write the root attributes and their digest."""
        f = self._file
        attrs = {"name": self.path.name.removesuffix(".h5"), "split": ""}
        attrs.update(self._attrs)
        attrs.update(format=FORMAT, format_version=FORMAT_VERSION, width=self.width, height=self.height,
                     segment_us=self.segment_us, duration_us=duration_us, num_events=self._count,
                     t_offset_us=self.t_offset_us, ground_truth="annotations" if self.annotated else "rendered")
        write_attrs(f, attrs)
        # over the values as a reader decodes them, so both sides hash the same thing
        write_attr(f.attrs, DIGEST_ATTR, attrs_digest(read_attrs(f)))

    def _commit(self) -> None:
        """Close the temp file, check it read back as written, and rename it into place (or leave that to the
        enclosing run_outputs() block)."""
        f = self._file
        f.flush()  # a full disk fails here, with the file still open (HDF5 crashes on a failed close)
        f.close()
        _read_back(self.tmp_path, self.path, self._digests if self._compression == "gzip" else None)
        self._run.done(self.path)
        if self._own_run is not None:
            from dvsot.runtime.outputs import writing

            with writing(self.path):
                self._own_run.commit()

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


def _read_back(tmp: Path, path: Path, stored: dict[str, list[bytes]] | None = None) -> None:
    """Open the finished temp file as a reader would and check every event chunk: a file that fails (a chunk whose
    Fletcher-32 checksum does not match, seen once in a long render) raises RunError and never replaces path.

    stored (the gzip columns' chunk digests): each stored chunk is compared with the bytes the writer encoded,
    a tenth of the time of decoding them (their values were checked on append); else every event is decoded.
    """
    try:
        with Dataset(tmp) as ds:
            ds.verify(stored)
    except UserError as exc:
        raise RunError(f"{path}: the file just written failed its read-back check, nothing replaced "
                       f"({str(exc).removeprefix(str(tmp) + ': ')})") from None

