"""The dataset file's lazy reader: events by time through ms_to_idx, fixed-length segments with their ground
truth, boxes and attributes, every load checked (dvsot.dataset.checks); and finding the files of a split."""

from __future__ import annotations

import glob as globmod
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from dvsot.core import bounds
from dvsot.core.errors import UserError, exception_line
from dvsot.dataset.boxes import box_problem
from dvsot.dataset.checks import (
    Damaged,
    check_duration,
    check_layout,
    check_root_links,
    check_sizes,
    check_stored,
    columns_problem,
    int_attr,
    ms_to_idx_problem,
    rows_problem,
    times_problem,
    truth_problem,
)
from dvsot.dataset.digest import DIGEST_ATTR, digest_problem
from dvsot.dataset.format import (
    FORMAT,
    FORMAT_VERSION,
    MAX_PIXELS,
    OBJECT_TRUTH,
    BoxTrack,
    ObjectTrack,
    Segment,
    decode_attr,
    read_attrs,
)
from dvsot.events import EventBatch
from dvsot.events.batch import NOISE_KINDS


class Dataset:
    """A dataset file opened lazily: events by time, fixed-length segments with ground truth, boxes, metadata."""

    def __init__(self, path: str | os.PathLike) -> None:
        self.path = Path(path)
        kind = bounds.file_kind_problem(self.path)
        if kind:
            raise UserError(f"{self.path}: " + ("no such dataset file" if kind == "no such file" else
                                                f"{kind}, not a dataset file"))
        try:
            self._file = h5py.File(self.path, "r")
        except (OSError, RuntimeError) as exc:
            raise UserError(f"{self.path}: not a readable HDF5 file ({exception_line(exc, kind=False)})") from None
        try:
            self._validate()
        except UserError:
            self._file.close()
            raise
        except Damaged as exc:
            self._file.close()
            raise UserError(f"{self.path}: damaged dvsot file ({exc})") from None
        except (
            OSError,
            KeyError,
            ValueError,
            TypeError,
            RuntimeError,
        ) as exc:  # h5py: RuntimeError for broken metadata
            self._file.close()
            raise UserError(f"{self.path}: damaged dvsot file ({exception_line(exc, kind=False)})") from None

    def _validate(self) -> None:
        f = self._file
        if decode_attr(f.attrs.get("format", "")) != FORMAT:
            raise UserError(f"{self.path}: not a dvsot dataset file (root attribute 'format' is not '{FORMAT}')")
        version = int_attr({k: decode_attr(v) for k, v in f.attrs.items()}, "format_version", -(2**62))
        if not 1 <= version <= FORMAT_VERSION:
            raise UserError(
                f"{self.path}: format_version {version} is not supported (this dvsot reads 1..{FORMAT_VERSION})"
            )
        check_layout(f)
        check_stored(f)
        self.t_offset_us = check_root_links(f, version)
        try:
            self.attrs: dict[str, Any] = read_attrs(f)
        except ValueError as exc:
            raise Damaged(str(exc)) from None
        self.width = int_attr(self.attrs, "width", 1, MAX_PIXELS)
        self.height = int_attr(self.attrs, "height", 1, MAX_PIXELS)
        if self.width * self.height > bounds.MAX_SENSOR_PIXELS:
            raise Damaged(f"root attributes 'width' x 'height' are {self.width}x{self.height}, more than the bound "
                           f"of {bounds.MAX_SENSOR_PIXELS} pixels")
        self.segment_us = int_attr(self.attrs, "segment_us", 1)
        self.duration_us = int_attr(self.attrs, "duration_us", 0)
        self.format_version = version
        self.name = str(self.attrs.get("name") or self.path.stem)
        self.split = str(self.attrs.get("split") or "")
        ev = f["events"]
        self._has_signal = "signal" in ev
        self._has_kind = "noise_kind" in ev  # files of the ideal sensor model and older ones have none
        # keep the column objects open: HDF5's chunk cache lives with them, and reopening one per read
        # would decompress a whole 2 MB chunk for every query
        self._columns = {name: ev[name] for name in ("x", "y", "t", "p", "signal", "noise_kind", "object")
                         if name in ev}
        self.num_events = int(ev["t"].shape[0])
        if "num_events" in self.attrs and int_attr(self.attrs, "num_events", 0) != self.num_events:
            raise Damaged(f"root attribute 'num_events' is {self.attrs['num_events']}, "
                           f"but /events/t has {self.num_events} rows")
        check_duration(self.duration_us, self.segment_us, ev["ms_to_idx"].shape[0], f["segments/xywh"].shape[0])
        check_sizes(f)
        self._ms_to_idx = self._load("events/ms_to_idx")
        problem = ms_to_idx_problem(self._ms_to_idx, self.num_events)
        if problem:
            raise Damaged(problem)
        self._seg_box = self._load("segments/xywh").astype(np.float32)
        vis = self._load("segments/xywh_visible") if "segments/xywh_visible" in f else None
        self._seg_vis = None if vis is None else vis.astype(np.float32)
        self.num_segments = int(self._seg_box.shape[0])
        # recordings: the /boxes row each segment is scored against (-1: none), dvsot.dataset.boxes.match_annotations
        self._seg_ann = self._load("segments/annotation").astype(np.int64) if "segments/annotation" in f else None
        n_boxes = f["boxes/t"].shape[0]
        box_t = self._load("boxes/t")
        if n_boxes and not (np.all(box_t[1:] > box_t[:-1]) and 0 <= box_t[0] and box_t[-1] <= self.duration_us):
            raise Damaged(f"/boxes/t runs from {int(box_t[0])} us to {int(box_t[-1])} us, expected increasing times "
                          f"within 0..{self.duration_us} us (root attribute 'duration_us')")
        if self._seg_ann is not None and len(self._seg_ann) and not (
                -1 <= self._seg_ann.min() and self._seg_ann.max() < n_boxes):
            raise Damaged(f"/segments/annotation holds rows outside -1..{n_boxes - 1} (/boxes has {n_boxes})")
        self._seg_visibility = self._seg_absent = None
        if "segments/visibility" in f or "segments/absent" in f or "boxes/visibility" in f:
            for name in ("boxes/visibility", "segments/visibility", "segments/absent"):
                if name not in f:
                    raise Damaged(f"missing /{name} (a file with visibility has all of /boxes/visibility, "
                                  "/segments/visibility and /segments/absent)")
            for name in ("boxes/visibility", "segments/visibility"):
                v = self._load(name)
                if np.any(v < 0) or np.any(v > 1) or (name == "boxes/visibility" and np.isnan(v).any()):
                    raise Damaged(f"/{name} holds values outside 0..1")
            self._seg_visibility = self._load("segments/visibility").astype(np.float32)
            self._seg_absent = self._load("segments/absent")
            bad = np.flatnonzero((self._seg_absent != 0) & (self._seg_absent != 1))
            if len(bad):
                raise Damaged(f"/segments/absent holds {self._seg_absent[bad[0]]} at segment {int(bad[0])}, "
                              "expected 0 or 1")
            self._seg_absent = self._seg_absent.astype(bool)
        self._seg_truncation = None
        if "boxes/truncation" in f or "segments/truncation" in f:
            for name in ("boxes/truncation", "segments/truncation"):
                if name not in f:
                    raise Damaged(f"missing /{name} (a file with truncation has /boxes/truncation and "
                                  "/segments/truncation)")
                v = self._load(name)
                if np.any(v < 0) or np.any(v > 1) or (name == "boxes/truncation" and np.isnan(v).any()):
                    raise Damaged(f"/{name} holds values outside 0..1")
            self._seg_truncation = self._load("segments/truncation").astype(np.float32)
        for name in ("segments/xywh", "segments/xywh_visible", "boxes/xywh", "boxes/xywh_visible"):
            rows = self._seg_box if name == "segments/xywh" else self._load(name) if name in f else None
            problem = None if rows is None else box_problem(rows, self.width, self.height)
            if problem:
                raise Damaged(f"/{name} {problem}")
        problem = truth_problem(f, self._load)
        if problem:
            raise Damaged(problem)
        problem = digest_problem(self.attrs)
        if problem:
            raise Damaged(problem)
        # /t_offset is a scalar (no chunk, so no Fletcher-32): its copy among the digested attributes guards it
        if "t_offset_us" in self.attrs and int_attr(self.attrs, "t_offset_us", -(2**63)) != self.t_offset_us:
            raise Damaged(f"/t_offset is {self.t_offset_us} us, but root attribute 't_offset_us' (covered by "
                          f"'{DIGEST_ATTR}') is {self.attrs['t_offset_us']} us")
        self._object_table(f)
        self._object_truth(f, n_boxes)
        self._check_masks(f, n_boxes)
        self._limits = {
            "x": (self.width, f"expected 0 <= x < width {self.width}"),
            "y": (self.height, f"expected 0 <= y < height {self.height}"),
            "p": (2, "expected 0 or 1"),
            "signal": (2, "expected 0 or 1"),
            "noise_kind": (len(NOISE_KINDS), f"expected 0..{len(NOISE_KINDS) - 1} ({', '.join(NOISE_KINDS)})"),
        }
        if self.num_events:  # two chunk reads: in a sorted file the ends bound every timestamp
            first = int(self._read("t", 0, 1)[0])
            last = int(self._read("t", self.num_events - 1, self.num_events)[0])
            if not 0 <= first <= last < self.duration_us:
                raise Damaged(f"/events/t runs from {first} us to {last} us, expected "
                               f"0 <= first <= last < root attribute 'duration_us' ({self.duration_us})")

    def _object_table(self, f: h5py.File) -> None:
        """The object table and per-id event counts, the label column read through once: ids outside the table
        refused."""
        self._has_object = "object" in self._columns
        if self._has_object != ("objects" in f):
            raise Damaged("/events/object without /objects" if self._has_object else "/objects without /events/object")
        self.objects: list[dict] | None = None
        self.target_id: int | None = None  # the id of the object table's target row
        self._object_counts: np.ndarray | None = None
        if not self._has_object:
            return
        from dvsot.events.labels import table_problem, target_id

        for name in ("objects/id", "objects/name", "objects/role"):
            if name not in f:
                raise Damaged(f"missing /{name} (a file with /events/object has the whole /objects table)")
        if f["events/object"].dtype != np.uint8:
            raise Damaged(f"/events/object has dtype {f['events/object'].dtype}, expected uint8")
        ids = self._load("objects/id").astype(np.int64)
        names, roles = ([v.decode("utf-8", "replace") for v in self._load(f"objects/{k}")] for k in ("name", "role"))
        problem = table_problem(ids, names, roles)
        if problem:
            raise Damaged(problem)
        self.objects = [{"id": int(i), "name": n, "role": r} for i, n, r in zip(ids, names, roles)]
        self.target_id = target_id(self.objects)
        self._known_ids = np.zeros(256, bool)
        self._known_ids[ids] = True
        counts = np.zeros(256, np.int64)
        step = 1 << 22
        for i0 in range(0, self.num_events, step):
            counts += np.bincount(self._read("object", i0, min(i0 + step, self.num_events)), minlength=256)[:256]
        stray = np.flatnonzero((counts > 0) & ~self._known_ids)
        if len(stray):
            raise Damaged(f"/events/object holds id {int(stray[0])} ({int(counts[stray[0]])} events), "
                          f"which /objects/id does not list")
        self._object_counts = counts

    def _object_truth(self, f: h5py.File, n_boxes: int) -> None:
        """Check /objects' per-sample ground truth (all of it or none, one row per sample and table id, shares in
        0..1 or NaN, boxes near the sensor) and keep it."""
        self._objects_track: ObjectTrack | None = None
        present = [name for name in OBJECT_TRUTH if f"objects/{name}" in f]
        if not present:
            return
        if len(present) != len(OBJECT_TRUTH):
            missing = next(name for name in OBJECT_TRUTH if name not in present)
            raise Damaged(f"missing /objects/{missing} (a file with per-object ground truth has all of "
                          f"{', '.join('/objects/' + n for n in OBJECT_TRUTH)})")
        if self.objects is None:
            raise Damaged(f"/objects/{present[0]} without the object table (/objects/id, /events/object)")
        k = len(self.objects)
        for name in OBJECT_TRUTH:
            shape = f[f"objects/{name}"].shape
            if shape[1] != k:
                raise Damaged(f"/objects/{name} has {shape[1]} objects per sample, /objects/id lists {k}")
        problem = rows_problem("objects/visibility", n_boxes * k, bounds.MAX_BOX_ROWS, "object rows per file")
        if problem:
            raise Damaged(problem)
        rows = {name: self._load(f"objects/{name}") for name in OBJECT_TRUTH}
        for name in ("visibility", "truncation"):
            v = rows[name]
            if np.any(v < 0) or np.any(v > 1):
                raise Damaged(f"/objects/{name} holds values outside 0..1")
        for name in ("px_amodal", "px_visible"):
            if len(rows[name]) and int(rows[name].max()) > self.width * self.height:
                raise Damaged(f"/objects/{name} holds {int(rows[name].max())}, more than the sensor's "
                              f"{self.width * self.height} pixels")
        # every pixel of the index pass holds an id of the table, so each sample's visible counts fill the sensor
        total = rows["px_visible"].astype(np.int64).sum(axis=1)
        off = np.flatnonzero(total != self.width * self.height)
        if len(off):
            raise Damaged(f"/objects/px_visible of sample {int(off[0])} adds up to {int(total[off[0]])} pixels, "
                          f"not the sensor's {self.width * self.height} (an id outside /objects/id, or a damaged row)")
        for name in ("boxes_amodal", "boxes_visible"):
            problem = box_problem(rows[name].reshape(-1, 4), self.width, self.height,
                                  lambda i: f"sample {i // k}, object id {self.objects[i % k]['id']}")
            if problem:
                raise Damaged(f"/objects/{name} {problem}")
        ids = np.array([row["id"] for row in self.objects], np.uint8)
        self._objects_track = ObjectTrack(ids, self._load("boxes/t"), *(rows[name] for name in OBJECT_TRUTH))

    def _check_masks(self, f: h5py.File, n_boxes: int) -> None:
        """Check /masks/objects' shape against the samples and the sensor, and the ids its attribute 'ids' lists
        against the object table; the images' ids are checked against both as they are read (files written before
        the attribute: against the table only)."""
        self.has_masks = "masks/objects" in f
        self._mask_ids = None
        if not self.has_masks:
            return
        ds = f["masks/objects"]
        if self.objects is None:
            raise Damaged("/masks/objects without the object table (/objects/id, /events/object)")
        if ds.dtype != np.uint8:
            raise Damaged(f"/masks/objects has dtype {ds.dtype}, expected uint8")
        if ds.shape[1:] != (self.height, self.width):
            raise Damaged(f"/masks/objects holds {ds.shape[2]}x{ds.shape[1]} images, the sensor is "
                          f"{self.width}x{self.height}")
        if "ids" not in ds.attrs:
            return
        listed = np.asarray(ds.attrs["ids"])
        if listed.ndim != 1 or listed.dtype.kind not in "ui" or len(listed) > 256:
            raise Damaged(f"/masks/objects attribute 'ids' is {listed.dtype} of shape {listed.shape}, expected "
                          "the object ids its images hold (u1 (n,))")
        stray = listed[(listed < 0) | (listed > 255) | ~self._known_ids[np.clip(listed, 0, 255).astype(np.intp)]]
        if len(stray):
            raise Damaged(f"/masks/objects holds id {int(stray[0])} (its attribute 'ids'), which /objects/id does "
                          "not list")
        self._mask_ids = np.zeros(256, bool)
        self._mask_ids[listed.astype(np.intp)] = True

    def object_track(self) -> ObjectTrack | None:
        """Every object's boxes, pixel counts, visibility and truncation at every sample (/objects), or None."""
        o = self._objects_track
        if o is None:
            return None
        return ObjectTrack(*(np.array(getattr(o, name)) for name in ObjectTrack.__dataclass_fields__))

    def masks(self, i0: int, i1: int) -> np.ndarray:
        """The object index images of samples i0..i1-1 (u1 (n, height, width), ids of /objects/id), checked."""
        if not self.has_masks:
            raise UserError(f"{self.path}: no /masks/objects (files rendered by `dvsot generate` keep them by default)")
        n = self._file["masks/objects"].shape[0]
        if not (0 <= i0 <= i1 <= n):
            raise IndexError(f"mask samples {i0}..{i1 - 1} out of range 0..{n - 1}")
        try:
            m = self._file["masks/objects"][i0:i1]
        except (OSError, ValueError, RuntimeError) as exc:
            raise self._damaged(f"cannot read /masks/objects samples {i0}..{i1 - 1}, its stored data is corrupt "
                                f"({exception_line(exc, kind=False)})") from None
        # the attribute's ids lie in the table (checked on open), so one lookup checks both
        known = (self._known_ids if self._mask_ids is None else self._mask_ids)[m]
        if not known.all():
            j = np.argwhere(~known)[0]
            v = int(m[tuple(j)])
            raise self._damaged(f"/masks/objects holds id {v} at sample {i0 + int(j[0])}, which "
                                + ("/objects/id does not list" if not self._known_ids[v] else
                                   "its attribute 'ids' does not list"))
        return m

    def verify_masks(self) -> None:
        """Read every /masks/objects sample and check its ids (a full scan; nothing where the file has no masks)."""
        if not self.has_masks:
            return
        n = self._file["masks/objects"].shape[0]
        for i0 in range(0, n, 64):
            self.masks(i0, min(i0 + 64, n))

    def mask(self, i: int) -> np.ndarray:
        """The object index image of sample i (u1 (height, width)): the pixels of the target are `== 1`."""
        return self.masks(i, i + 1)[0]

    def sample_at(self, t_us: int) -> int:
        """The row of /boxes (and /masks, /objects) rendered nearest to t_us (microseconds; the earlier on a tie)."""
        t = self._load("boxes/t")
        if len(t) == 0:
            raise UserError(f"{self.path}: no rendered samples (/boxes/t is empty)")
        j = int(np.searchsorted(t, t_us))
        if j == len(t) or (j > 0 and t_us - t[j - 1] <= t[j] - t_us):
            j -= 1
        return j

    def object_counts(self) -> dict[int, int] | None:
        """Events per object id of the table (every id listed, zeros kept), or None for a file without labels."""
        if self.objects is None:
            return None
        return {row["id"]: int(self._object_counts[row["id"]]) for row in self.objects}

    def __enter__(self) -> Dataset:
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
        return self._stored(lambda: self._file[name][()], f"/{name}")

    def _stored(self, read, what: str) -> np.ndarray:
        """read() of stored data; a failed read (a Fletcher-32 mismatch or a broken chunk surfaces as OSError)
        becomes the damaged-file error naming `what`."""
        try:
            return read()
        except (OSError, ValueError, RuntimeError) as exc:
            raise self._damaged(f"cannot read {what}, its stored data is corrupt "
                                f"({exception_line(exc, kind=False)})") from None

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
        problem = times_problem(ts, ms * 1000, (ms + 1) * 1000, lo, f"/events/ms_to_idx[{ms}]")
        if problem:
            raise self._damaged(problem)
        return lo + int(np.searchsorted(ts, t_us, side="left"))

    def _read(self, column: str, i0: int, i1: int) -> np.ndarray:
        return self._stored(lambda: self._columns[column][i0:i1], f"/events/{column} events {i0}..{i1 - 1}")

    def _batch(self, i0: int, i1: int, t0_us: int, t1_us: int, source: str) -> EventBatch:
        """Events i0..i1-1, checked: sorted times in [t0_us, t1_us) (microseconds), pixels on the sensor, 0/1 flags."""
        columns = {name: self._read(name, i0, i1) for name in ("x", "y", "t", "p")}
        if self._has_signal:
            columns["signal"] = self._read("signal", i0, i1)
        if self._has_kind:
            columns["noise_kind"] = self._read("noise_kind", i0, i1)
        obj = self._read("object", i0, i1) if self._has_object else None
        t = columns.pop("t")
        problem = times_problem(t, t0_us, t1_us, i0, source) or columns_problem(columns, self._limits, i0)
        if not problem and obj is not None and len(obj) and not self._known_ids[obj].all():
            i = int(np.flatnonzero(~self._known_ids[obj])[0])
            problem = f"/events/object holds id {int(obj[i])} at event {i0 + i}, which /objects/id does not list"
        if problem:
            raise self._damaged(problem)
        sig = columns["signal"].astype(bool) if self._has_signal else None
        kind = columns["noise_kind"].astype(np.uint8) if self._has_kind else None
        return EventBatch(columns["x"], columns["y"], t, columns["p"], sig, kind, object=obj)

    def events(self, t0_us: int, t1_us: int) -> EventBatch:
        """The events with t0_us <= t < t1_us (microseconds), found via ms_to_idx without a full scan."""
        t0_us, t1_us = int(t0_us), int(t1_us)
        i0, i1 = self._index_at(t0_us), self._index_at(t1_us)
        if i1 <= i0:
            return EventBatch.empty()
        if i1 - i0 > bounds.MAX_WINDOW_EVENTS:  # before the columns are read: a crafted file could hold billions
            raise UserError(f"{self.path}: {t0_us}..{t1_us} us holds {i1 - i0} events, more than the bound of "
                            f"{bounds.MAX_WINDOW_EVENTS} events read at once")
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

    def verify(self, stored: dict[str, list[bytes]] | None = None) -> None:
        """Read and check every event (a full scan); a broken invariant raises UserError naming the file and dataset.

        With `stored` ({column: the chunk_digest of each of its chunks, in order}: what a writer handed to HDF5)
        the event chunks are instead read as stored and compared with those digests, undecoded: the writer's
        own check that the file holds the bytes it wrote (dvsot.dataset.writer), not a reader's of a file.
        """
        if stored is None:
            for _ in self.chunks():
                pass
            self.verify_masks()
            return
        events = self._file["events"]
        for name, digests in stored.items():
            ds = events[name]
            n_chunks = -(-ds.shape[0] // ds.chunks[0])
            if n_chunks != len(digests):
                raise self._damaged(f"/events/{name} holds {n_chunks} chunks, {len(digests)} were written")
            for k, want in enumerate(digests):
                try:
                    mask, data = ds.id.read_direct_chunk((k * ds.chunks[0],))
                except Exception as exc:  # a chunk the index does not find
                    why = exception_line(exc, 120)
                    raise self._damaged(f"cannot read chunk {k} of /events/{name} ({why})") from exc
                if mask != 0 or chunk_digest(data) != want:
                    raise self._damaged(f"chunk {k} of /events/{name} is not the one written: its stored bytes differ")

    def segment(self, i: int) -> Segment:
        """Segment i: the events of [i*segment_us, (i+1)*segment_us) and the ground truth at its end."""
        if not 0 <= i < self.num_segments:
            raise IndexError(f"segment {i} out of range 0..{self.num_segments - 1}")
        t0, t1 = i * self.segment_us, (i + 1) * self.segment_us
        vis = None if self._seg_vis is None else self._seg_vis[i].copy()
        visibility = None if self._seg_visibility is None else float(self._seg_visibility[i])
        absent = None if self._seg_absent is None else bool(self._seg_absent[i])
        truncation = None if self._seg_truncation is None else float(self._seg_truncation[i])
        return Segment(i, t0, t1, self.events(t0, t1), self._seg_box[i].copy(), vis, visibility, absent, truncation)

    def segments(self, start: int = 0, stop: int | None = None) -> Iterator[Segment]:
        """Segments start..stop-1 in order."""
        stop = self.num_segments if stop is None else min(stop, self.num_segments)
        for i in range(start, stop):
            yield self.segment(i)

    def segment_boxes(self) -> np.ndarray:
        """Ground truth of every segment, (num_segments, 4) xywh pixels, NaN = absent."""
        return self._seg_box.copy()

    def segment_visible_boxes(self) -> np.ndarray:
        """The visible part's box of every segment, (num_segments, 4) xywh pixels, NaN = none (or not in the file)."""
        if self._seg_vis is None:
            return np.full_like(self._seg_box, np.nan)
        return self._seg_vis.copy()

    @property
    def annotated(self) -> bool:
        """True for a recording whose boxes are annotations at their own times (scored only where matched)."""
        return self._seg_ann is not None

    def segment_scored(self) -> np.ndarray:
        """Per segment, whether its ground truth may be scored: every segment of a rendered file, matched ones of a
        recording."""
        if self._seg_ann is None:
            return np.ones(self.num_segments, bool)
        return self._seg_ann >= 0

    def segment_annotations(self) -> np.ndarray | None:
        """Per segment, the /boxes row of its annotation (-1: none), or None for a rendered file."""
        return None if self._seg_ann is None else self._seg_ann.copy()

    def segment_visibility(self) -> np.ndarray | None:
        """Per segment, visible / amodal target pixels at its end (0..1, NaN outside the track), or None (not in the
        file)."""
        return None if self._seg_visibility is None else self._seg_visibility.copy()

    def segment_absent(self) -> np.ndarray | None:
        """Per segment, True where nothing of the target is visible at its end or it is outside the sensor, or None."""
        return None if self._seg_absent is None else self._seg_absent.copy()

    def segment_truncation(self) -> np.ndarray | None:
        """Per segment, the share of the target's whole silhouette off the sensor at its end (0..1, NaN outside the
        track), or None (not in the file)."""
        return None if self._seg_truncation is None else self._seg_truncation.copy()

    def boxes(self) -> BoxTrack:
        """The box track at every rendered sample (or annotation): t (microseconds), xywh and xywh_visible (pixels),
        visibility and truncation (None where the file has none)."""
        vis = self._load("boxes/visibility") if self._seg_visibility is not None else None
        trunc = self._load("boxes/truncation") if self._seg_truncation is not None else None
        return BoxTrack(*(self._load(f"boxes/{name}") for name in ("t", "xywh", "xywh_visible")), vis, trunc)



def open_dataset(path: str | os.PathLike) -> Dataset:
    """Open a dataset file for reading; a foreign or damaged file raises UserError."""
    return Dataset(path)


def chunk_digest(data: bytes) -> bytes:
    """A 128-bit BLAKE2b digest of a stored chunk's bytes (what Dataset.verify(stored=...) compares)."""
    import hashlib

    return hashlib.blake2b(data, digest_size=16).digest()


def find_datasets(spec: str | os.PathLike | list, split: str | None = None, verify: bool = True,
                  need_events: bool = False) -> list[Path]:
    """Dataset files named by a directory, a glob, a file or a list of those, optionally of one split; all checked
    (need_events: a file without events is an error, e.g. for training)."""
    specs = [spec] if isinstance(spec, (str, os.PathLike)) else list(spec)
    paths: list[Path] = []
    for item in specs:
        p = Path(item)
        if p.is_dir():  # as the glob DIR/*.h5 does: no hidden files (another run's staged outputs among them)
            found = sorted(f for f in p.glob("*.h5") if not f.name.startswith("."))
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
