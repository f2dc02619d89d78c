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
"""

from __future__ import annotations

from typing import Any, Callable

from dvsot.events.batch import STRUCTURED_DTYPE
from dvsot.dataset.torchdata import SegmentDataset


class TonicDataset(SegmentDataset):
    """Segments of dvsot dataset files as a tonic dataset: items (events, target), target the box xywh (pixels)."""

    ordering = "xytp"
    dtype = STRUCTURED_DTYPE

    def __init__(self, data: Any, split: str | None = None, transform: Callable | None = None,
                 target_transform: Callable | None = None, transforms: Callable | None = None,
                 with_box: bool = True, verify: bool = False) -> None:
        super().__init__(data, split=split, transform=transform, target_transform=target_transform,
                         with_box=with_box, verify=verify)
        self.transforms = transforms
        _ = self.sensor_size  # a tonic dataset has one: files of several sizes are a ValueError here

    def __getitem__(self, i: int) -> tuple[Any, Any]:
        events, target = super().__getitem__(i)
        if self.transforms is not None:
            events, target = self.transforms(events, target)
        return events, target
