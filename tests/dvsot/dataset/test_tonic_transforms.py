"""tonic's own transforms (ToFrame, ToVoxelGrid, Denoise) on a dvsot segment, against values computed by hand."""

from __future__ import annotations

import numpy as np
import pytest
import tonic

from dvsot.dataset.tonic_dataset import TonicDataset
from dvsot.dataset.torchdata import collate_segments
from dvsot.events.batch import STRUCTURED_DTYPE, EventBatch
from tests.dvsot.dataset.test_round_trip import write_file

# six events of segment 1 (10..20 ms) of a 64x48 file: t us, x, y, p (1 brighter, 0 darker)
EVENTS = np.array([(10_100, 3, 2, 1), (12_000, 3, 2, 1), (13_000, 4, 2, 0),
                   (15_100, 10, 10, 0), (17_000, 3, 3, 1), (19_900, 20, 5, 1)])


@pytest.fixture
def data(tmp_path):
    t, x, y, p = EVENTS.T
    write_file(tmp_path / "seq.h5", EventBatch(x.astype(np.uint16), y.astype(np.uint16), t.astype(np.int64),
                                               p.astype(np.uint8)), 30_000, batches=1)
    return tmp_path / "seq.h5"


def segment_item(dataset: TonicDataset, segment: int) -> int:
    return next(i for i in range(len(dataset)) if dataset.locate(i)[1] == segment)


def test_the_dataset_follows_tonics_conventions(data):
    ds = TonicDataset(data)
    assert ds.sensor_size == (64, 48, 2) and ds.ordering == "xytp" and ds.dtype == STRUCTURED_DTYPE
    events, box = ds[segment_item(ds, 1)]
    assert events.dtype == ds.dtype and events["p"].dtype == np.int8
    np.testing.assert_array_equal(events["p"], EVENTS[:, 3])
    np.testing.assert_array_equal(events["t"], EVENTS[:, 0])
    np.testing.assert_allclose(box, [20.0, 5.0, 10.0, 8.0])  # write_file's box at 20 ms
    import pickle

    framed = TonicDataset(data, transform=tonic.transforms.ToFrame(sensor_size=ds.sensor_size, n_time_bins=2))
    clone = pickle.loads(pickle.dumps(framed))  # as DataLoader's workers get it
    np.testing.assert_array_equal(clone[segment_item(clone, 1)][0], framed[segment_item(framed, 1)][0])
    joint = TonicDataset([data], transforms=lambda e, b: (len(e), b * 2))
    assert joint[segment_item(joint, 1)][0] == 6 and joint[segment_item(joint, 1)][1][0] == 40.0


def test_tonic_to_frame_counts_each_polarity_in_its_channel(data):
    ds = TonicDataset(data, transform=tonic.transforms.ToFrame(sensor_size=(64, 48, 2), n_time_bins=2))
    frames, _ = ds[segment_item(ds, 1)]
    # tonic's two bins: (19900 - 10100) // 2 = 4900 us each, [10100, 15000) and [15000, 19900); the last
    # event lies past them. Channel 0 darker, channel 1 brighter; a p of -1 would land in channel 1 too.
    want = np.zeros((2, 2, 48, 64), np.int16)
    want[0, 1, 2, 3] = 2
    want[0, 0, 2, 4] = 1
    want[1, 0, 10, 10] = 1
    want[1, 1, 3, 3] = 1
    np.testing.assert_array_equal(frames, want)


def test_tonic_voxel_grid_is_signed(data):
    ds = TonicDataset(data)
    events, _ = ds[segment_item(ds, 1)]
    grid = tonic.transforms.ToVoxelGrid(sensor_size=ds.sensor_size, n_time_bins=2)(events)
    # t scaled to 2 * (t - 10100) / 9800; each event splits +-1 between its bin and the next by the fraction
    want = np.zeros((2, 1, 48, 64))
    want[0, 0, 2, 3] = 1 + 30 / 49       # t 10100 (all in bin 0) and t 12000 (fraction 19/49 into bin 1)
    want[1, 0, 2, 3] = 19 / 49
    want[0, 0, 2, 4] = -20 / 49          # darker, t 13000: fraction 29/49
    want[1, 0, 2, 4] = -29 / 49
    want[1, 0, 10, 10] = -48 / 49        # darker, t 15100: 1/49 into bin 1, the rest would go to bin 2
    want[1, 0, 3, 3] = 29 / 49           # t 17000: 20/49 into bin 1
    np.testing.assert_allclose(grid, want, atol=1e-12)  # t 19900 scales to 2.0: no bin
    assert np.array_equal(events["p"], EVENTS[:, 3])  # the input is left as it was


def test_tonic_denoise_keeps_events_with_a_recent_neighbour(data):
    ds = TonicDataset(data, transform=tonic.transforms.Denoise(filter_time=2_000))
    kept, _ = ds[segment_item(ds, 1)]
    # only (4, 2) at 13000 has a 4-neighbour, (3, 2) at 12000, within 2000 us before it
    assert kept.tolist() == [(4, 2, 13_000, 0)]


def test_composed_pipeline_and_collate(data):
    to_grid = tonic.transforms.Compose([tonic.transforms.Denoise(filter_time=10_000),
                                        tonic.transforms.ToVoxelGrid(sensor_size=(64, 48, 2), n_time_bins=3)])
    ds = TonicDataset(data, transform=to_grid)
    grids, boxes = collate_segments([ds[segment_item(ds, 1)], ds[segment_item(ds, 1)]])
    import torch

    assert isinstance(grids, torch.Tensor) and grids.shape == (2, 3, 1, 48, 64)
    assert isinstance(boxes, torch.Tensor) and boxes.dtype == torch.float32 and boxes.shape == (2, 4)


def test_files_of_two_sizes_are_refused(data, tmp_path):
    from dvsot.dataset import DatasetWriter

    with DatasetWriter(tmp_path / "big.h5", 128, 96, segment_us=10_000) as w:
        w.close(10_000)
    with pytest.raises(ValueError, match="2 sensor sizes"):
        TonicDataset([data, tmp_path / "big.h5"], with_box=False)
