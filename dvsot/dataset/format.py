"""The dvsot dataset file (HDF5, format version 2): its layout, constants and attribute encoding.

The writer is dvsot.dataset.writer, the reader dvsot.dataset.reader, the reader's checks dvsot.dataset.checks.

Layout (DSEC-compatible events, see docs/ARCHITECTURE.md):

    /events/x, /events/y   u2  pixel
    /events/t              i8  microseconds since the sequence start
    /events/p              u1  1 = brighter, 0 = darker
    /events/signal         u1  1 = signal, 0 = noise event (present when the generator flags them)
    /events/noise_kind     u1  0 = signal, 1 = shot noise, 2 = leak, 3 = hot pixel (present when a sensor model
                               beyond `ideal` made the events: dvsot.events.batch.NOISE_KINDS)
    /events/object         u1  id of the object that made the event (rendered scenes; dvsot.events.labels)
    /events/ms_to_idx      u8  index of the first event with t >= ms * 1000, for ms = 0 .. duration_ms
    /boxes/t               i8  microseconds, one row per rendered sample
    /boxes/xywh            f4  (N, 4) amodal target box (target rendered alone); NaN = absent
    /boxes/xywh_visible    f4  (N, 4) visible part of the target (occluders kept)
    /segments/t            i8  (M,) end time of each segment, microseconds
    /segments/xywh         f4  (M, 4) ground truth per segment, at the segment's end time
    /segments/xywh_visible f4  (M, 4) visible-part ground truth per segment
    /boxes/visibility      f4  (N,) rendered scenes: visible target pixels / amodal target pixels (on the sensor)
    /segments/visibility   f4  (M,) the same at each segment's end, linear between samples (NaN outside the track)
    /segments/absent       u1  (M,) 1 = nothing of the target visible at the segment's end (its visible box NaN)
                               or no amodal box (outside the sensor)
    /boxes/truncation      f4  (N,) rendered scenes: the share of the target's whole (amodal) silhouette off the sensor
    /segments/truncation   f4  (M,) the same at each segment's end, linear between samples (NaN outside the track)
    /objects/boxes_amodal  f4  (N, K, 4) per sample and object table row: the object's amodal box on the sensor
                               (NaN for rows without geometry: background, noise)
    /objects/boxes_visible f4  (N, K, 4) the box of the object's pixels in the render's object index pass
    /objects/px_amodal     u4  (N, K) amodal pixels on the sensor; /objects/px_visible u4 (N, K) visible pixels
    /objects/visibility    f4  (N, K) px_visible / px_amodal (0..1, 0 where no amodal pixel; NaN: no geometry)
    /objects/truncation    f4  (N, K) share of the object's whole silhouette off the sensor (0..1; NaN: no geometry)
    /masks/objects         u1  (N, H, W) the object index pass of every sample (ids of /objects/id), one gzip chunk
                               per sample (`dvsot generate` writes them by default); its attribute `ids` (u1)
                               lists the ids the images hold, checked against /objects/id on open
    /segments/annotation   i8  (M,) recordings only: the /boxes row matched to each segment, -1 = none
    /ms_to_idx                 a hard link to /events/ms_to_idx (where DSEC's and tonic's readers look)
    /objects/id            u1  (K,) the ids /events/object uses (present exactly when it is)
    /objects/name          S   (K,) each object's name (UTF-8)
    /objects/role          S   (K,) background, target, distractor, occluder or noise
    /t_offset              i8  scalar, microseconds added to /events/t to get the recording's own clock
                               (0 for synthetic data)

Event columns are byte-shuffled and gzip (level 1) compressed, filters every HDF5 library has, so
h5dump and readers outside h5py open them
(the writer encodes those chunks itself, with ISA-L's deflate: dvsot.dataset.h5chunks). Version 1 files (LZF, no root
link, no /t_offset) still load, with offset 0.

The writer appends events in chunks and computes `ms_to_idx` as it goes, so a sequence of hundreds
of millions of events never sits in memory. It writes to a temporary name beside the target and
renames on success, so an interrupted run leaves no file that looks complete. Every dataset carries
HDF5's Fletcher-32 checksum, so flipped bits in a chunk fail the read instead of returning garbage.

The reader checks the layout and attributes when it opens a file, and the invariants of every batch
of events it loads (time order, time window, pixel range, 0/1 flags) on the data already in memory;
`Dataset.chunks` streams and checks the whole file. Any violation is a one-line UserError naming the
file and the dataset or attribute. Files written before checksums were added still load.

Box values are checked on open too (finite, w, h > 0 or four NaNs, near the sensor: dvsot.dataset.boxes),
and the writer stores a SHA-256 of the root attributes' canonical JSON as root attribute
`attrs_sha256`, so a changed or corrupted attribute is an error on open; files written before the
digest (no `attrs_sha256`) load without that check. /t_offset, a scalar HDF5 cannot checksum, is
repeated as root attribute `t_offset_us`, which the digest covers; the reader compares the two (files
written before that attribute load without the comparison). Whole datasets read into memory are bounded in
rows (dvsot.core.bounds), and every dataset must store all the chunks its shape declares (a chunk never
written reads as zeros), so a damaged or hostile file cannot make the reader allocate gigabytes.

A text root attribute longer than TEXT_ATTR_BYTES (a scene file of up to 1 MB, stored verbatim) is a
fixed-length string dataset /attrs/<key> instead, since an HDF5 attribute holds at most 64 kB; the
reader's attributes (and their digest) include it as if it were one.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from dvsot.core import bounds
from dvsot.events import EventBatch

FORMAT = "dvsot"
FORMAT_VERSION = 2
# name -> h5py filter options for event columns. gzip and shuffle are built into every HDF5 library; gzip 1
# after the byte shuffle is smaller than LZF and as fast to read (benchmarks/perf/bench_compression.py;
# figures: docs/results.md)
COMPRESSIONS: dict[str | None, dict[str, Any]] = {
    "gzip": {"compression": "gzip", "compression_opts": 1, "shuffle": True},
    "gzip-noshuffle": {"compression": "gzip", "compression_opts": 1},
    "lzf": {"compression": "lzf"},  # version 1's choice: h5py-only, h5dump and hdf5plugin cannot read it
    None: {},
}
# Datasets every file has.
REQUIRED = ("events/x", "events/y", "events/t", "events/p", "events/ms_to_idx",
            "boxes/t", "boxes/xywh", "boxes/xywh_visible", "segments/t", "segments/xywh")
# Each known dataset's allowed numpy dtype kinds ('u'/'i' integer, 'b' bool, 'f' float) and shape: 1 (N,), 2 (N, 4),
# "NK4" (N, K, 4) and "NK" (N, K) with K the object table's rows, "NHW" (N, height, width).
LAYOUT: dict[str, tuple[str, int]] = {
    "events/x": ("ui", 1), "events/y": ("ui", 1), "events/t": ("ui", 1), "events/p": ("uib", 1),
    "events/signal": ("uib", 1), "events/noise_kind": ("ui", 1), "events/ms_to_idx": ("ui", 1), "ms_to_idx": ("ui", 1),
    "boxes/t": ("ui", 1), "boxes/xywh": ("uif", 2), "boxes/xywh_visible": ("uif", 2),
    "segments/t": ("ui", 1), "segments/xywh": ("uif", 2), "segments/xywh_visible": ("uif", 2),
    "segments/annotation": ("i", 1), "events/object": ("ui", 1), "objects/id": ("ui", 1),
    "objects/name": ("S", 1), "objects/role": ("S", 1),
    "boxes/visibility": ("f", 1), "segments/visibility": ("f", 1), "segments/absent": ("uib", 1),
    "boxes/truncation": ("f", 1), "segments/truncation": ("f", 1),
    "objects/boxes_amodal": ("f", "NK4"), "objects/boxes_visible": ("f", "NK4"), "objects/px_amodal": ("ui", "NK"),
    "objects/px_visible": ("ui", "NK"), "objects/visibility": ("f", "NK"), "objects/truncation": ("f", "NK"),
    "masks/objects": ("u", "NHW"),
}
# The per-object ground truth: a file has all of these or none.
OBJECT_TRUTH = ("boxes_amodal", "boxes_visible", "px_amodal", "px_visible", "visibility", "truncation")
MAX_PIXELS = 1 << 16  # x and y are stored as u2
# Datasets that must have as many rows as the first one of their group.
SAME_ROWS = (("events/t", "events/x", "events/y", "events/p", "events/signal", "events/noise_kind", "events/object"),
             ("objects/id", "objects/name", "objects/role"),
             ("boxes/t", "boxes/xywh", "boxes/xywh_visible", "boxes/visibility", "boxes/truncation",
              *(f"objects/{name}" for name in OBJECT_TRUTH), "masks/objects"),
             ("segments/xywh", "segments/t", "segments/xywh_visible", "segments/annotation", "segments/visibility",
              "segments/absent", "segments/truncation"))


@dataclass(frozen=True)
class BoxTrack:
    """The target's box at every rendered sample: t (microseconds), xywh and xywh_visible (pixels, NaN = absent),
    visibility (visible / amodal target pixels on the sensor, 0..1) and truncation (the share of the target's whole
    silhouette off the sensor, 0..1); None where the file has none."""

    t: np.ndarray
    xywh: np.ndarray
    xywh_visible: np.ndarray
    visibility: np.ndarray | None = None
    truncation: np.ndarray | None = None


@dataclass(frozen=True)
class ObjectTrack:
    """Every object's ground truth at every rendered sample (/objects): ids (K,) the object table's ids, in the
    order of the K axis; t (N,) microseconds; boxes_amodal, boxes_visible (N, K, 4) xywh pixels (NaN = none);
    px_amodal, px_visible (N, K) pixels on the sensor; visibility, truncation (N, K) 0..1 (NaN for the rows without
    geometry: background, noise)."""

    ids: np.ndarray
    t: np.ndarray
    boxes_amodal: np.ndarray
    boxes_visible: np.ndarray
    px_amodal: np.ndarray
    px_visible: np.ndarray
    visibility: np.ndarray
    truncation: np.ndarray


@dataclass(frozen=True)
class Segment:
    """The events of [t0_us, t1_us) and the ground-truth box (pixels, NaN if absent) at t1_us."""

    index: int
    t0_us: int
    t1_us: int
    events: EventBatch
    box: np.ndarray
    box_visible: np.ndarray | None = None
    visibility: float | None = None  # visible / amodal target pixels at t1_us (None: not in the file)
    absent: bool | None = None  # nothing of the target visible at t1_us, or outside the sensor
    truncation: float | None = None  # share of the target's silhouette off the sensor at t1_us (None: not in file)


def encode_attr(value: Any) -> Any:
    """An HDF5-storable attribute value: containers and None become JSON text."""
    if isinstance(value, (dict, list, tuple)) or value is None:
        return json.dumps(value, sort_keys=True, default=str)
    if isinstance(value, Path):
        return str(value)
    return value


def write_attr(attrs: h5py.AttributeManager, key: str, value: Any) -> None:
    """Store an attribute; text as fixed-length UTF-8, whose bytes sit in the attribute itself: a damaged
    variable-length string points into a heap, and HDF5 can crash the process following it."""
    if isinstance(value, str):
        data = value.encode("utf-8")
        attrs.create(key, np.array(data, dtype=h5py.string_dtype("utf-8", max(1, len(data)))))
    else:
        attrs[key] = value


TEXT_GROUP = "attrs"  # root attributes whose text is too long for an attribute, one scalar dataset each
TEXT_ATTR_BYTES = 16 << 10  # longer text goes to TEXT_GROUP: an HDF5 attribute message holds at most 64 kB


def attrs_problem(attrs: dict[str, Any]) -> str | None:
    """What keeps root attributes from being stored (text over bounds.MAX_TEXT_ATTR_BYTES, a long text under a
    name that cannot be a dataset's), or None."""
    for key, value in attrs.items():
        value = encode_attr(value)
        size = len(value.encode("utf-8")) if isinstance(value, str) else 0
        if size > bounds.MAX_TEXT_ATTR_BYTES:
            return (f"root attribute {key!r} holds {size} bytes of text, more than the bound of "
                    f"{bounds.MAX_TEXT_ATTR_BYTES} for one attribute")
        if size > TEXT_ATTR_BYTES and ("/" in key or key in (".", "")):
            return f"root attribute {key!r}: a long text needs a name without '/'"
    return None


def write_attrs(f: h5py.File, attrs: dict[str, Any]) -> None:
    """Store root attributes (encoded by encode_attr); text over TEXT_ATTR_BYTES as a fixed-length string dataset
    /attrs/<key>, which read_attrs puts back among the others."""
    problem = attrs_problem(attrs)
    if problem:
        raise ValueError(problem)
    for key, value in attrs.items():
        value = encode_attr(value)
        data = value.encode("utf-8") if isinstance(value, str) else None
        if data is None or len(data) <= TEXT_ATTR_BYTES:
            write_attr(f.attrs, key, value)
            continue
        text = np.array(data, dtype=h5py.string_dtype("utf-8", len(data)))
        f.require_group(TEXT_GROUP).create_dataset(key, data=text)


def read_attrs(f: h5py.File) -> dict[str, Any]:
    """Every root attribute decoded, those stored as /attrs/<key> datasets (write_attrs) among them.

    Raises ValueError naming the dataset when /attrs holds something write_attrs does not write."""
    attrs = {k: decode_attr(v) for k, v in f.attrs.items()}
    if TEXT_GROUP not in f:
        return attrs
    group = f[TEXT_GROUP]
    if not isinstance(group, h5py.Group):
        raise ValueError(f"/{TEXT_GROUP} is not a group")
    for key in group:
        obj = group.get(key)
        where = f"/{TEXT_GROUP}/{key}"
        if not isinstance(obj, h5py.Dataset) or obj.shape != () or obj.dtype.kind != "S":
            raise ValueError(f"{where} is not a fixed-length text scalar")
        if obj.dtype.itemsize > bounds.MAX_TEXT_ATTR_BYTES:  # before reading it
            raise ValueError(f"{where} holds {obj.dtype.itemsize} bytes, more than the bound of "
                             f"{bounds.MAX_TEXT_ATTR_BYTES} for a text attribute")
        if key in attrs:
            raise ValueError(f"{where} repeats root attribute {key!r}")
        attrs[key] = decode_attr(obj[()])
    return attrs


def decode_attr(value: Any) -> Any:
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

