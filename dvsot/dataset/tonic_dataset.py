"""A tonic-style dataset of dvsot files: one item per segment, `(events, target)`, tonic's transforms applied unchanged.

    import tonic
    from dvsot.dataset.tonic_dataset import TonicDataset

    data = TonicDataset("data/dvsot21/woman_cat.h5")
    data.transform = tonic.transforms.ToVoxelGrid(sensor_size=data.sensor_size, n_time_bins=5)
    grid, box = data[0]                 # (5, 1, H, W) float voxel grid, the segment's box xywh (pixels)

tonic's dataset conventions: the class attributes `ordering` ("xytp") and `dtype` (a structured dtype
with fields x, y, t in microseconds and a signed p, 1 brighter and 0 darker, as tonic's DVS datasets
hold it), the instance attribute `sensor_size` (width, height, 2), and `transform`,
`target_transform` and `transforms` (a callable of (events, target), applied after the other two, as
tonic.Dataset does). The files are a directory, a glob, one file or a list of those, all of one
sensor size; each scored segment with a ground-truth box is one item (with_box=False: every scored
segment, its target nan where the box is unknown). dvsot does not import tonic: any callable works.

With `labels=True` (files with per-event labels) the target is a dict instead of the box: `box` (after
target_transform), `objects` (each event's object id, before any transform), `event_mask`, and the rendered
ground truth of SegmentDataset's labels (`silhouette`, `visibility`, `truncation`, `absent`); `transforms`
then gets (events, that dict).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from dvsot.dataset.torchdata import SegmentDataset
from dvsot.events.batch import STRUCTURED_DTYPE


class TonicDataset(SegmentDataset):
    """Segments of dvsot dataset files as a tonic dataset: items (events, target), target the box xywh (pixels), or
    with labels=True a dict of the box and the segment's labels."""

    ordering = "xytp"
    dtype = STRUCTURED_DTYPE

    def __init__(self, data: Any, split: str | None = None, transform: Callable | None = None,
                 target_transform: Callable | None = None, transforms: Callable | None = None,
                 with_box: bool = True, verify: bool = False, labels: bool = False) -> None:
        super().__init__(data, split=split, transform=transform, target_transform=target_transform,
                         with_box=with_box, verify=verify, labels=labels)
        self.transforms = transforms
        _ = self.sensor_size  # a tonic dataset has one: files of several sizes are a ValueError here

    def __getitem__(self, i: int) -> tuple[Any, Any]:
        item = super().__getitem__(i)
        events, target = item[0], item[1]
        if self.labels:
            target = {"box": target, "objects": item[2], "event_mask": item[3], **item[4]}
        if self.transforms is not None:
            events, target = self.transforms(events, target)
        return events, target
