"""SegmentDataset: picklable, opened lazily per worker, tonic-style structured events, in a DataLoader with 2
workers."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

from dvsot.dataset import Dataset
from dvsot.dataset.torchdata import SegmentDataset, collate_segments
from dvsot.events import STRUCTURED_DTYPE, EventBatch
from tests.dvsot.dataset.test_round_trip import random_events, write_file


def event_count(events: np.ndarray) -> int:
    """A transform (module level, so that it pickles): the number of events."""
    return len(events)


@pytest.fixture
def files(tmp_path):
    rng = np.random.default_rng(11)
    for name in ("a", "b"):
        write_file(tmp_path / f"{name}.h5", random_events(rng, 3_000, 95_000), 100_000, split="train")
    return tmp_path


def test_structured_round_trip():
    ev = random_events(np.random.default_rng(0), 100, 10_000, signal=False)
    s = ev.to_structured()
    assert s.dtype == STRUCTURED_DTYPE and s.dtype.names == ("x", "y", "t", "p")
    back = EventBatch.from_structured(s)
    for col in "xytp":
        np.testing.assert_array_equal(getattr(back, col), getattr(ev, col))
    assert s["p"].dtype == np.int8 and set(np.unique(s["p"])) == {0, 1}  # tonic's signed p
    tonic_like = np.zeros(3, np.dtype([("x", int), ("y", int), ("t", int), ("p", bool)]))
    assert EventBatch.from_structured(tonic_like).p.dtype == np.uint8
    signed = np.zeros(3, np.dtype([("x", int), ("y", int), ("t", int), ("p", np.int8)]))
    signed["p"] = [-1, 1, 0]
    np.testing.assert_array_equal(EventBatch.from_structured(signed).p, [0, 1, 0])
    signed["p"][2] = 2
    with pytest.raises(ValueError, match="field p of event 2 is 2"):
        EventBatch.from_structured(signed)
    with pytest.raises(ValueError, match="missing p"):
        EventBatch.from_structured(np.zeros(2, np.dtype([("x", int), ("y", int), ("t", int)])))


def test_items_match_the_reader_and_pickle(files):
    data = SegmentDataset(files)
    assert len(data) == 20 and data.sensor_size == (64, 48, 2)
    events, box = data[13]
    path, s = data.locate(13)
    with Dataset(path) as ds:
        seg = ds.segment(s)
    np.testing.assert_array_equal(events["t"], seg.events.t)
    np.testing.assert_array_equal(box, seg.box)
    clone = pickle.loads(pickle.dumps(data))  # with a file open in this process
    assert clone._open == {}
    np.testing.assert_array_equal(clone[13][0], events)
    data.close()
    clone.close()


def test_dataloader_with_two_workers(files):
    import torch
    from torch.utils.data import DataLoader

    data = SegmentDataset(files, transform=event_count)
    _ = data[0]  # a handle opened in the parent before the workers start
    loader = DataLoader(data, batch_size=3, num_workers=2, collate_fn=collate_segments)
    counts, boxes = [], []
    for n, b in loader:
        counts.extend(n)
        boxes.append(b)
    assert counts == [data[i][0] for i in range(len(data))]  # the workers' items, in order
    assert sum(counts) == 6_000  # every event of both files lies in a segment with a box
    assert all(isinstance(b, torch.Tensor) and b.dtype == torch.float32 for b in boxes)
    assert torch.cat(boxes).shape == (20, 4)
