"""The reader's checks of a dataset file: layout, root links and attributes, table lengths, and the invariants
of loaded events. Each raises Damaged or returns a one-line problem; dvsot.dataset.reader names the file."""

from __future__ import annotations

from typing import Any

import h5py
import numpy as np

from dvsot.core import bounds
from dvsot.core.errors import exception_line
from dvsot.dataset.format import LAYOUT, REQUIRED, SAME_ROWS

_KIND_WORDS = {"ui": "integers", "uib": "integers or booleans", "uif": "numbers", "S": "fixed-length byte strings",
               "f": "floats"}


# LAYOUT's shape codes: (how a message writes it, the number of axes)
_SHAPES = {1: ("(N,)", 1), 2: ("(N, 4)", 2), "NK4": ("(N, K, 4)", 3), "NK": ("(N, K)", 2), "NHW": ("(N, H, W)", 3)}


class Damaged(Exception):
    """A broken invariant of the file format; Dataset turns it into a UserError naming the file."""


def rows_problem(name: str, rows: int, bound: int, why: str) -> str | None:
    """A message if dataset /name has more than `bound` rows (a bound on what one file can make us read), or None."""
    if rows > bound:
        return f"/{name} has {rows} rows, more than the bound of {bound} ({why})"
    return None


def check_layout(f: h5py.File) -> None:
    """Raise Damaged unless the required datasets exist and every known one has the right type, dtype, shape, rows."""
    missing = [name for name in REQUIRED if name not in f]
    if missing:
        raise Damaged(f"missing /{missing[0]}")
    for name, (kinds, rank) in LAYOUT.items():
        if name not in f:
            continue
        try:
            obj = f[name]
        except (KeyError, OSError) as exc:  # e.g. a dangling link: listed, but nothing behind it
            raise Damaged(f"/{name} cannot be opened ({exception_line(exc, kind=False)})") from None
        if not isinstance(obj, h5py.Dataset):
            raise Damaged(f"/{name} is a {type(obj).__name__.lower()}, not a dataset")
        if obj.dtype.kind not in kinds:
            raise Damaged(f"/{name} has dtype {obj.dtype}, expected {_KIND_WORDS[kinds]}")
        want, ndim = _SHAPES[rank]
        if obj.ndim != ndim or (obj.shape[-1] != 4 and rank in (2, "NK4")):
            raise Damaged(f"/{name} has shape {obj.shape}, expected {want}")
    for group in SAME_ROWS:
        rows = {name: f[name].shape[0] for name in group if name in f}
        first = group[0]
        for name, n in rows.items():
            if n != rows[first]:
                raise Damaged(f"/{name} has {n} rows, /{first} has {rows[first]}")


def check_stored(f: h5py.File) -> None:
    """Raise Damaged if a dataset declares more rows than the file stores: a chunk never written (or contiguous
    storage shorter than the shape) reads as zeros, so a small file could make a reader allocate for billions."""
    for name in LAYOUT:
        if name not in f:
            continue
        ds = f[name]
        if ds.size == 0:
            continue
        if ds.chunks is not None:
            want = int(np.prod([-(-n // c) for n, c in zip(ds.shape, ds.chunks)]))
            have = ds.id.get_num_chunks()
            if have != want:
                raise Damaged(f"/{name} declares {ds.shape[0]} rows in {want} chunks, but the file stores {have} "
                              f"of them (the file is truncated or crafted)")
        elif ds.id.get_storage_size() < ds.size * ds.dtype.itemsize:
            raise Damaged(f"/{name} declares {ds.shape[0]} rows ({ds.size * ds.dtype.itemsize} bytes), but the file "
                          f"stores {ds.id.get_storage_size()} bytes of them (the file is truncated or crafted)")


def check_root_links(f: h5py.File, version: int) -> int:
    """Raise Damaged unless root /ms_to_idx is /events/ms_to_idx and /t_offset a scalar integer; return the offset
    (us)."""
    if version >= 2:
        for name in ("ms_to_idx", "t_offset"):
            if name not in f:
                raise Damaged(f"missing /{name}")
    if "ms_to_idx" in f:
        root, events = f["ms_to_idx"], f["events/ms_to_idx"]
        # a copy that kept the values (e.g. a tool that does not preserve hard links) is as good as the link
        if root.id != events.id and (root.shape != events.shape or not np.array_equal(root[()], events[()])):
            raise Damaged("/ms_to_idx differs from /events/ms_to_idx")
    if "t_offset" not in f:
        return 0
    obj = f["t_offset"]
    if not isinstance(obj, h5py.Dataset) or obj.shape != () or obj.dtype.kind not in "ui":
        raise Damaged("/t_offset is not a scalar integer (microseconds)")
    return int(obj[()])


def int_attr(attrs: dict[str, Any], name: str, minimum: int, maximum: int | None = None) -> int:
    """Root attribute `name` as an int in [minimum, maximum]; raise Damaged naming it when it is not."""
    if name not in attrs:
        raise Damaged(f"root attribute '{name}' is missing")
    value = attrs[name]
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not float(value).is_integer():
        raise Damaged(f"root attribute '{name}' is {repr(value)[:40]}, expected an integer")
    if value < minimum:
        raise Damaged(f"root attribute '{name}' is {int(value)}, expected >= {minimum}")
    if maximum is not None and value > maximum:
        raise Damaged(f"root attribute '{name}' is {int(value)}, expected <= {maximum}")
    return int(value)


def check_sizes(f: h5py.File) -> None:
    """Raise Damaged if a dataset the reader loads whole is longer than dvsot.core.bounds allows."""
    limits = {"events/ms_to_idx": (bounds.MAX_DURATION_US // 1000 + 1, f"{bounds.MAX_DURATION_S} s per file"),
              "segments/xywh": (bounds.MAX_DURATION_US // bounds.MIN_SEGMENT_US,
                                f"{bounds.MAX_DURATION_S} s in segments of at least {bounds.MIN_SEGMENT_US} us"),
              "boxes/t": (bounds.MAX_BOX_ROWS, "box samples per file")}
    for name, (bound, why) in limits.items():
        problem = rows_problem(name, f[name].shape[0], bound, why)
        if problem:
            raise Damaged(problem)


def check_duration(duration_us: int, segment_us: int, n_ms_to_idx: int, n_segments: int) -> None:
    """Raise Damaged unless /events/ms_to_idx and /segments/xywh are as long as duration_us (microseconds) implies."""
    want_ms, want_seg = -(-duration_us // 1000) + 1, duration_us // segment_us
    ms_ok, seg_ok = n_ms_to_idx == want_ms, n_segments == want_seg
    if not ms_ok and not seg_ok:  # two tables written independently agree with each other, not with the attribute
        raise Damaged(f"root attribute 'duration_us' is {duration_us}, which disagrees with /events/ms_to_idx "
                       f"({n_ms_to_idx} entries, expected {want_ms}) and /segments/xywh ({n_segments} rows, "
                       f"expected {want_seg})")
    if not ms_ok:
        raise Damaged(f"/events/ms_to_idx has {n_ms_to_idx} entries, expected {want_ms} for duration_us {duration_us}")
    if not seg_ok:
        raise Damaged(f"/segments/xywh has {n_segments} rows, expected {want_seg} "
                       f"(duration_us {duration_us} / segment_us {segment_us})")


def ms_to_idx_problem(ms_to_idx: np.ndarray, num_events: int) -> str | None:
    """What is wrong with a whole ms_to_idx table (event indices per millisecond), or None."""
    if len(ms_to_idx) and (int(ms_to_idx[0]) != 0 or int(ms_to_idx[-1]) != num_events):
        return (f"/events/ms_to_idx runs from {int(ms_to_idx[0])} to {int(ms_to_idx[-1])}, "
                f"expected 0 to num_events {num_events}")
    down = np.flatnonzero(ms_to_idx[1:] < ms_to_idx[:-1])  # compared, not diffed: u8 differences wrap around
    if len(down):
        return f"/events/ms_to_idx decreases at ms {int(down[0]) + 1}"
    return None


def times_problem(t: np.ndarray, t0_us: int, t1_us: int, first: int, source: str) -> str | None:
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


# a rendered visible box may overhang its amodal box by the index pass's pixel filter (dvsot.dataset.boxes.
# mask_visibility): a pixel at most, so two pixels are a crafted or corrupted box
VISIBLE_INSIDE_TOL_PX = 2.0


def _inside_problem(name: str, amodal: np.ndarray, visible: np.ndarray) -> str | None:
    """What is wrong if a visible box (N, 4 xywh px) lies outside its amodal box beyond the tolerance, or None."""
    a, v = np.asarray(amodal, np.float64), np.asarray(visible, np.float64)
    both = np.isfinite(a).all(axis=1) & np.isfinite(v).all(axis=1)
    with np.errstate(invalid="ignore"):
        out = both & ((v[:, 0] < a[:, 0] - VISIBLE_INSIDE_TOL_PX) | (v[:, 1] < a[:, 1] - VISIBLE_INSIDE_TOL_PX)
                      | (v[:, 0] + v[:, 2] > a[:, 0] + a[:, 2] + VISIBLE_INSIDE_TOL_PX)
                      | (v[:, 1] + v[:, 3] > a[:, 1] + a[:, 3] + VISIBLE_INSIDE_TOL_PX))
    if not out.any():
        return None
    i = int(np.flatnonzero(out)[0])
    fmt = lambda b: "x={:g} y={:g} w={:g} h={:g}".format(*b)  # noqa: E731
    return (f"/{name}_visible row {i} ({fmt(v[i])}) lies outside the amodal box /{name} ({fmt(a[i])}) by more "
            f"than {VISIBLE_INSIDE_TOL_PX:g} px: the visible part of the target is part of the target")


def truth_problem(f: h5py.File, load) -> str | None:
    """What is wrong between a file's ground-truth tables (load(name) reads one), or None: /segments/t increasing;
    visible boxes inside their amodal boxes; a visible box only where visibility > 0; /segments/absent exactly
    where a segment's amodal or visible box is missing (dvsot.dataset.segment_truth.absent_at)."""
    seg_t = load("segments/t")
    down = np.flatnonzero(seg_t[1:] <= seg_t[:-1])
    if len(down):
        i = int(down[0]) + 1
        return (
            f"/segments/t is {int(seg_t[i])} us at segment {i}, not after segment {i - 1}'s {int(seg_t[i - 1])} us; "
            "segment end times increase"
        )
    for group in ("boxes", "segments"):
        if f"{group}/xywh_visible" not in f:
            continue
        amodal, visible = load(f"{group}/xywh"), load(f"{group}/xywh_visible")
        problem = _inside_problem(f"{group}/xywh", amodal, visible)
        if problem:
            return problem
        if f"{group}/visibility" in f:
            vis = load(f"{group}/visibility")
            seen = (np.isfinite(np.asarray(visible, np.float64)).all(axis=1)
                    & np.isfinite(np.asarray(amodal, np.float64)).all(axis=1))
            bad = np.flatnonzero(seen & (vis == 0))
            if len(bad):
                return (f"/{group}/visibility is 0 at row {int(bad[0])}, beside a visible box in "
                        f"/{group}/xywh_visible: nothing visible has no visible box")
    if "segments/absent" in f and "segments/xywh_visible" in f:
        absent = load("segments/absent").astype(np.int64)
        missing = (np.isnan(np.asarray(load("segments/xywh"), np.float64)).any(axis=1)
                   | np.isnan(np.asarray(load("segments/xywh_visible"), np.float64)).any(axis=1))
        bad = np.flatnonzero((absent == 1) != missing)
        if len(bad):
            i = int(bad[0])
            return (f"/segments/absent is {int(absent[i])} at segment {i}, but its boxes are "
                    + ("missing" if missing[i] else "both there") + " (absent is 1 exactly where the amodal or the "
                    "visible box is missing)")
    return None


def columns_problem(columns: dict[str, np.ndarray], limits: dict[str, tuple[int, str]], first: int) -> str | None:
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


