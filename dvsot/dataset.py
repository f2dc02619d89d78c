"""The dvsot dataset file (HDF5, format version 1): a streaming writer and a lazy reader.

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

The writer appends events in chunks and computes `ms_to_idx` as it goes, so a sequence of hundreds
of millions of events never sits in memory. It writes to a temporary name beside the target and
renames on success, so an interrupted run leaves no file that looks complete.
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

from dvsot.errors import UserError
from dvsot.events import EventBatch

FORMAT = "dvsot"
FORMAT_VERSION = 1
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


class DatasetWriter:
    """Streams events and boxes into a new dataset file; renames it into place only on success."""

    def __init__(self, path: str | os.PathLike, width: int, height: int, segment_us: int = 10_000,
                 attrs: dict[str, Any] | None = None, compression: str | None = "lzf") -> None:
        if width <= 0 or height <= 0:
            raise ValueError(f"width and height must be positive, got {width}x{height}")
        if segment_us <= 0:
            raise ValueError(f"segment_us must be positive, got {segment_us}")
        self.path = Path(path)
        if not self.path.parent.is_dir():
            raise UserError(f"{self.path}: output directory {self.path.parent} does not exist")
        self.width, self.height, self.segment_us = int(width), int(height), int(segment_us)
        self.tmp_path = self.path.with_name(f".{self.path.name}.tmp-{os.getpid()}")
        self._file = h5py.File(self.tmp_path, "w")
        self._compression = compression
        self._attrs: dict[str, Any] = dict(attrs or {})
        ev = self._file.create_group("events")
        for name, dtype in (("x", np.uint16), ("y", np.uint16), ("t", np.int64), ("p", np.uint8)):
            ev.create_dataset(name, shape=(0,), maxshape=(None,), dtype=dtype, chunks=(_EVENT_CHUNK,),
                              compression=compression)
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
        self._closed = False

    def __enter__(self) -> "DatasetWriter":
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None and not self._closed:
            self.close()
        elif exc_type is not None:
            self.abort()

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
        if self._has_signal is None:
            self._has_signal = batch.signal is not None
            if self._has_signal:
                self._file["events"].create_dataset("signal", shape=(0,), maxshape=(None,), dtype=np.uint8,
                                                    chunks=(_EVENT_CHUNK,), compression=self._compression)
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
        if not self._buffer:
            return
        joined = EventBatch.concatenate(self._buffer)
        n0, n1 = self._count, self._count + len(joined)
        ev = self._file["events"]
        columns = {"x": joined.x.astype(np.uint16), "y": joined.y.astype(np.uint16),
                   "t": joined.t.astype(np.int64), "p": joined.p.astype(np.uint8)}
        if self._has_signal:
            columns["signal"] = joined.signal.astype(np.uint8)
        for name, values in columns.items():
            ev[name].resize((n1,))
            ev[name][n0:n1] = values
        self._count = n1
        self._buffer, self._buffered = [], 0

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
            box_t = np.concatenate(self._box_t) if self._box_t else np.empty(0, np.int64)
            box_xywh = np.concatenate(self._box_xywh) if self._box_xywh else np.empty((0, 4), np.float32)
            box_vis = np.concatenate(self._box_vis) if self._box_vis else np.empty((0, 4), np.float32)
            if len(box_t) > 1 and np.any(np.diff(box_t) <= 0):
                raise ValueError("box sample times must be strictly increasing")
            if duration_us is None:
                candidates = [self._last_t + 1 if self._count else 0, int(box_t[-1]) if len(box_t) else 0]
                duration_us = max(candidates)
            duration_us = int(duration_us)
            if self._count and self._last_t >= duration_us:
                raise ValueError(f"an event at {self._last_t} us lies beyond the duration {duration_us} us")
            duration_ms = -(-duration_us // 1000)
            tail = np.full(max(0, duration_ms + 1 - self._next_ms), self._count, dtype=np.uint64)
            ms_to_idx = np.concatenate(self._ms_to_idx + [tail])[: duration_ms + 1]
            f = self._file
            f["events"].create_dataset("ms_to_idx", data=ms_to_idx.astype(np.uint64))
            g = f.create_group("boxes")
            g.create_dataset("t", data=box_t, maxshape=(None,))
            g.create_dataset("xywh", data=box_xywh, maxshape=(None, 4))
            g.create_dataset("xywh_visible", data=box_vis, maxshape=(None, 4))
            n_seg = duration_us // self.segment_us
            seg_t = (np.arange(n_seg, dtype=np.int64) + 1) * self.segment_us
            if len(box_t):
                seg_box = _interpolate_boxes(box_t, box_xywh, seg_t).astype(np.float32)
                seg_vis = _interpolate_boxes(box_t, box_vis, seg_t).astype(np.float32)
            else:
                seg_box = np.full((n_seg, 4), np.nan, np.float32)
                seg_vis = seg_box.copy()
            s = f.create_group("segments")
            s.create_dataset("t", data=seg_t)
            s.create_dataset("xywh", data=seg_box.reshape(-1, 4))
            s.create_dataset("xywh_visible", data=seg_vis.reshape(-1, 4))
            attrs = {"name": self.path.name.removesuffix(".h5"), "split": ""}
            attrs.update(self._attrs)
            attrs.update(format=FORMAT, format_version=FORMAT_VERSION, width=self.width, height=self.height,
                         segment_us=self.segment_us, duration_us=duration_us, num_events=self._count)
            for key, value in attrs.items():
                f.attrs[key] = _encode_attr(value)
            f.close()
            os.replace(self.tmp_path, self.path)
        except BaseException:
            self.abort()
            raise
        self._closed = True
        return self.path

    def abort(self) -> None:
        """Discard the temporary file; nothing at the target path is touched."""
        self._closed = True
        try:
            self._file.close()
        except Exception:
            pass
        self.tmp_path.unlink(missing_ok=True)


class Dataset:
    """A dataset file opened lazily: events by time, fixed-length segments with ground truth, boxes, metadata."""

    def __init__(self, path: str | os.PathLike) -> None:
        self.path = Path(path)
        if not self.path.is_file():
            raise UserError(f"{self.path}: no such dataset file")
        try:
            self._file = h5py.File(self.path, "r")
        except OSError as exc:
            raise UserError(f"{self.path}: not a readable HDF5 file ({_short(exc)})") from None
        try:
            self._validate()
        except UserError:
            self._file.close()
            raise
        except (OSError, KeyError, ValueError, TypeError) as exc:
            self._file.close()
            raise UserError(f"{self.path}: damaged dvsot file ({_short(exc)})") from None

    def _validate(self) -> None:
        f = self._file
        if _decode_attr(f.attrs.get("format", "")) != FORMAT:
            raise UserError(f"{self.path}: not a dvsot dataset file (root attribute 'format' is not '{FORMAT}')")
        version = int(f.attrs.get("format_version", -1))
        if not 1 <= version <= FORMAT_VERSION:
            raise UserError(f"{self.path}: format_version {version} is not supported (this dvsot reads 1..{FORMAT_VERSION})")
        missing = [name for name in _REQUIRED if name not in f]
        if missing:
            raise UserError(f"{self.path}: damaged dvsot file (missing /{missing[0]})")
        self.attrs: dict[str, Any] = {k: _decode_attr(v) for k, v in f.attrs.items()}
        self.width = int(self.attrs["width"])
        self.height = int(self.attrs["height"])
        self.segment_us = int(self.attrs["segment_us"])
        self.duration_us = int(self.attrs["duration_us"])
        self.format_version = version
        self.name = str(self.attrs.get("name") or self.path.stem)
        self.split = str(self.attrs.get("split") or "")
        ev = f["events"]
        self.num_events = int(ev["t"].shape[0])
        lengths = {ev[k].shape[0] for k in ("x", "y", "t", "p")}
        if "signal" in ev:
            lengths.add(ev["signal"].shape[0])
        if len(lengths) != 1 or self.num_events != int(self.attrs.get("num_events", self.num_events)):
            raise UserError(f"{self.path}: damaged dvsot file (event columns differ in length)")
        self._ms_to_idx = ev["ms_to_idx"][()]
        if len(self._ms_to_idx) != -(-self.duration_us // 1000) + 1 or (
                len(self._ms_to_idx) and int(self._ms_to_idx[-1]) > self.num_events):
            raise UserError(f"{self.path}: damaged dvsot file (/events/ms_to_idx does not match the events)")
        self._seg_box = f["segments/xywh"][()].astype(np.float32).reshape(-1, 4)
        vis = f["segments/xywh_visible"][()] if "segments/xywh_visible" in f else None
        self._seg_vis = None if vis is None else vis.astype(np.float32).reshape(-1, 4)
        self.num_segments = int(self._seg_box.shape[0])
        if self.num_segments != self.duration_us // self.segment_us:
            raise UserError(f"{self.path}: damaged dvsot file (/segments/xywh has {self.num_segments} rows, "
                            f"expected {self.duration_us // self.segment_us})")

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
        return lo + int(np.searchsorted(ts, t_us, side="left"))

    def _read(self, column: str, i0: int, i1: int) -> np.ndarray:
        try:
            return self._file["events"][column][i0:i1]
        except (OSError, ValueError) as exc:
            raise UserError(f"{self.path}: damaged dvsot file (cannot read /events/{column}: {_short(exc)})") from None

    def events(self, t0_us: int, t1_us: int) -> EventBatch:
        """The events with t0_us <= t < t1_us (microseconds), found via ms_to_idx without a full scan."""
        i0, i1 = self._index_at(int(t0_us)), self._index_at(int(t1_us))
        if i1 <= i0:
            return EventBatch.empty()
        sig = self._read("signal", i0, i1).astype(bool) if "signal" in self._file["events"] else None
        return EventBatch(self._read("x", i0, i1), self._read("y", i0, i1), self._read("t", i0, i1),
                          self._read("p", i0, i1), sig)

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

    def boxes(self) -> BoxTrack:
        """The box track at every rendered sample."""
        g = self._file["boxes"]
        return BoxTrack(g["t"][()], g["xywh"][()].reshape(-1, 4), g["xywh_visible"][()].reshape(-1, 4))


def _short(exc: BaseException) -> str:
    """An exception's message on one line."""
    return " ".join(str(exc).split()) or type(exc).__name__


def open_dataset(path: str | os.PathLike) -> Dataset:
    """Open a dataset file for reading; a foreign or damaged file raises UserError."""
    return Dataset(path)


def find_datasets(spec: str | os.PathLike | list, split: str | None = None) -> list[Path]:
    """Dataset files named by a directory, a glob, a file or a list of those, optionally of one split."""
    specs = [spec] if isinstance(spec, (str, os.PathLike)) else list(spec)
    paths: list[Path] = []
    for item in specs:
        p = Path(item)
        if p.is_dir():
            found = sorted(p.glob("*.h5"))
        elif any(ch in str(item) for ch in "*?["):
            found = sorted(Path(x) for x in globmod.glob(str(item)))
        elif p.is_file():
            found = [p]
        else:
            raise UserError(f"{item}: no such file or directory")
        paths.extend(found)
    result: list[Path] = []
    for p in dict.fromkeys(paths):
        with Dataset(p) as ds:
            if split is None or ds.split == split:
                result.append(p)
    if not result:
        where = ", ".join(str(s) for s in specs)
        raise UserError(f"{where}: no dvsot dataset files" + (f" of split '{split}'" if split else ""))
    return result
