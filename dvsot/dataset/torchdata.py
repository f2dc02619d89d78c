"""Segments of dataset files for PyTorch's DataLoader (and tonic's transforms), opened lazily in each worker.

    from torch.utils.data import DataLoader
    from dvsot.dataset.torchdata import SegmentDataset, collate_segments

    data = SegmentDataset("data/dvsot21", split="train", transform=my_transform)
    loader = DataLoader(data, batch_size=8, shuffle=True, num_workers=2, collate_fn=collate_segments)
    for events, boxes in loader:      # a list of structured (x, y, t, p) arrays, boxes a (B, 4) float32 tensor
        ...

An item is (events, box): the segment's events as a structured array with fields x, y, t, p
(tonic's layout, `dvsot.events.STRUCTURED_DTYPE`; t in microseconds of the file's clock minus
/t_offset; p signed, 1 brighter and 0 darker, as tonic's transforms expect) and its ground-truth
box xywh (pixels, float32). `transform` maps the events (a tonic transform such as
`tonic.transforms.ToFrame(sensor_size=data.sensor_size, n_time_bins=10)` works), `target_transform`
the box. With `labels=True` (files with per-event labels, docs/events.md) an item is (events, box,
objects, target_mask, truth): objects the id of the object that made each event (u1, as long as the events,
before any transform), target_mask a bool (height, width) array of the pixels where a target event fired
in the segment, and truth a dict of the rendered ground truth at the segment's end (docs/dataset-files.md):
`silhouette` the target's rendered (visible) silhouette, bool (height, width), from the object index pass of
the sample nearest the segment's end (/masks/objects; None for a file without masks), `visibility` and
`truncation` (float, 0..1; NaN where the file has none) and `absent` (bool; False where the file has none).
`collate_segments` gives the masks as one (B, H, W) tensor, the ids as a list, and truth as a dict of
tensors (silhouettes stacked when every item has one, else a list).
The object holds only paths and an index, so it pickles; each process
opens the files it reads on first use and keeps them open (HDF5 handles must not cross a fork).
No torch import at module level: DataLoader takes any object with __len__ and __getitem__, and only
collate_segments, which builds tensors, imports torch. `dvsot.dataset.tonic_dataset.TonicDataset` adds tonic's
dataset attributes (ordering, dtype, transforms).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import Any

import numpy as np

from dvsot.dataset import Dataset, find_datasets


class SegmentDataset:
    """Map-style dataset of every segment with a ground-truth box (or every segment) of some dataset files."""

    def __init__(self, data: Any, split: str | None = None, transform: Callable | None = None,
                 target_transform: Callable | None = None, with_box: bool = True, verify: bool = False,
                 labels: bool = False) -> None:
        self.paths = [str(p) for p in find_datasets(data, split=split, verify=verify)]
        self.transform, self.target_transform = transform, target_transform
        self.labels = bool(labels)
        rows, sizes = [], set()
        for k, path in enumerate(self.paths):
            with Dataset(path) as ds:
                if self.labels and ds.objects is None:
                    from dvsot.core.errors import UserError

                    raise UserError(f"{path}: no per-event labels (/events/object), which labels=True asks for")
                keep = ds.segment_scored()
                if with_box:
                    keep = keep & np.isfinite(ds.segment_boxes()).all(axis=1)
                rows.append(np.stack([np.full(int(keep.sum()), k), np.flatnonzero(keep)], axis=1))
                sizes.add((ds.width, ds.height))
        self._index = np.concatenate(rows).astype(np.int64) if rows else np.empty((0, 2), np.int64)
        self._sizes = sizes
        self._open: dict[int, Dataset] = {}
        self._pid: int | None = None

    @property
    def sensor_size(self) -> tuple[int, int, int]:
        """(width, height, 2), tonic's sensor_size, when every file has one sensor size."""
        if len(self._sizes) != 1:
            raise ValueError(f"the files have {len(self._sizes)} sensor sizes: {sorted(self._sizes)}")
        w, h = next(iter(self._sizes))
        return (w, h, 2)

    def __len__(self) -> int:
        return int(len(self._index))

    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        state["_open"], state["_pid"] = {}, None  # open files stay with the process that opened them
        return state

    def _dataset(self, k: int) -> Dataset:
        if self._pid != os.getpid():  # a fresh process (or a fork): open files of our own
            self._open, self._pid = {}, os.getpid()
        if k not in self._open:
            self._open[k] = Dataset(self.paths[k])
        return self._open[k]

    def locate(self, i: int) -> tuple[str, int]:
        """(file path, segment index) of item i."""
        k, s = self._index[i]
        return self.paths[int(k)], int(s)

    def __getitem__(self, i: int) -> tuple[Any, ...]:
        if not -len(self) <= i < len(self):
            raise IndexError(f"item {i} out of range for {len(self)} segments")
        k, s = self._index[i]
        ds = self._dataset(int(k))
        seg = ds.segment(int(s))
        events: Any = seg.events.to_structured()
        box: Any = seg.box.astype(np.float32)
        if self.transform is not None:
            events = self.transform(events)
        if self.target_transform is not None:
            box = self.target_transform(box)
        if not self.labels:
            return events, box
        return (
            events,
            box,
            seg.events.object,
            target_mask(seg.events, ds.width, ds.height, ds.target_id),
            segment_labels(ds, seg),
        )

    def close(self) -> None:
        """Close the files this process opened."""
        if self._pid == os.getpid():
            for ds in self._open.values():
                ds.close()
        self._open = {}


def segment_labels(ds: Dataset, seg: Any) -> dict[str, Any]:
    """The rendered ground truth of a segment (dvsot.dataset.format.Segment) of ds: the target's silhouette at the
    sample nearest its end (bool (height, width), None without /masks/objects), visibility, truncation, absent."""
    silhouette = ds.mask(ds.sample_at(seg.t1_us)) == ds.target_id if ds.has_masks else None
    nan = float("nan")
    return {"silhouette": silhouette, "visibility": nan if seg.visibility is None else seg.visibility,
            "truncation": nan if seg.truncation is None else seg.truncation, "absent": bool(seg.absent)}


def target_mask(events, width: int, height: int, target_id: int) -> np.ndarray:
    """bool (height, width): the pixels where at least one of the events (an EventBatch with labels) is the target's
    (target_id: the id the file's object table gives the role 'target', Dataset.target_id)."""
    mask = np.zeros((height, width), bool)
    hit = events.object == target_id
    mask[events.y[hit], events.x[hit]] = True
    return mask


def collate_segments(batch: list[tuple[Any, ...]]) -> tuple[Any, ...]:
    """DataLoader collate_fn: boxes as a (B, 4) float32 tensor (pixels); events stacked to one tensor when every
    item is a numeric array or tensor of one shape (a transform's frames or voxel grids), else a list (structured
    events differ in length and torch holds no structured arrays; numeric ones become tensors)."""
    import torch

    def tensor(value: Any) -> Any:
        if isinstance(value, torch.Tensor):
            return value
        a = np.asarray(value)
        return torch.from_numpy(np.ascontiguousarray(a)) if a.dtype.kind in "biuf" else value

    events = [tensor(item[0]) for item in batch]
    if events and all(isinstance(e, torch.Tensor) and e.shape == events[0].shape for e in events):
        events = torch.stack(events)
    boxes = [b if isinstance(b, torch.Tensor) else torch.as_tensor(np.asarray(b, np.float32)) for _, b, *_ in batch]
    if batch and len(batch[0]) == 5:  # labels=True: per-event ids (a list: lengths differ), masks stacked, truth
        return (events, torch.stack(boxes), [tensor(item[2]) for item in batch],
                torch.stack([tensor(item[3]) for item in batch]), collate_truth([item[4] for item in batch]))
    return events, torch.stack(boxes)


def collate_truth(items: list[dict[str, Any]]) -> dict[str, Any]:
    """segment_labels' dicts as one: visibility, truncation (float32) and absent (bool) tensors (B,), silhouettes a
    (B, H, W) bool tensor when every item has one, else a list (None for a file without masks)."""
    import torch

    sil = [item["silhouette"] for item in items]
    return {"silhouette": torch.from_numpy(np.stack(sil)) if all(m is not None for m in sil) else sil,
            "visibility": torch.tensor([item["visibility"] for item in items], dtype=torch.float32),
            "truncation": torch.tensor([item["truncation"] for item in items], dtype=torch.float32),
            "absent": torch.tensor([item["absent"] for item in items], dtype=torch.bool)}
