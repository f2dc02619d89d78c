"""Crafted label tables and ground truth are refused on open, naming the file and the dataset: the object table's
target, the absent flags, visibility beside a visible box, visible boxes outside the amodal ones, segment times."""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
import pytest

from dvsot.core.errors import UserError
from dvsot.dataset import Dataset, DatasetWriter
from dvsot.events import EventParams, EventSimulator
from dvsot.events.labels import LabelledFrame, object_table
from dvsot.pipeline.sequence import write_sequence

W, H = 24, 16


def _labelled(path: Path) -> Path:
    """A 4 px target square moving right over a background, with per-event labels (ids 0, 1, 2, 255)."""
    frames = []
    for k in range(9):
        level, ids = np.zeros((H, W)), np.zeros((H, W), np.uint8)
        level[6:10, 2 + 2 * k:6 + 2 * k], ids[6:10, 2 + 2 * k:6 + 2 * k] = 0.6, 1
        frames.append(LabelledFrame(level, ids))
    sim = EventSimulator(W, H, EventParams(cp=0.2, cn=0.2), seed=1)
    out, _ = write_sequence(path, frames, np.arange(9) * 1000, sim, {}, 4000, is_log=True,
                            objects=object_table([("ball", "distractor")]))
    return out


def _visible(path: Path) -> Path:
    """Boxes every 10 ms with visibility; the target hidden at 20 and 30 ms."""
    t = np.arange(5) * 10_000
    box = np.tile([10.0, 10.0, 8.0, 8.0], (5, 1))
    vis_box = box.copy()
    vis_box[2:4] = np.nan
    with DatasetWriter(path, 64, 48, segment_us=5_000) as w:
        w.append_boxes(t, box, vis_box, (1.0, 0.5, 0.0, 0.0, 1.0))
        w.close(40_001)
    return path


def _replace(path: Path, name: str, change) -> None:
    """Rewrite dataset `name` of the file as change(its values) gives it (dtype kept unless change sets one)."""
    with h5py.File(path, "r+") as f:
        values = change(f[name][()])
        group, leaf = name.rsplit("/", 1)
        del f[name]
        f[group].create_dataset(leaf, data=values)


def _roles(*roles: str):
    return lambda old: np.array([r.encode() for r in roles], old.dtype)


@pytest.mark.parametrize("roles, words", [
    (("background", "distractor", "distractor", "noise"), r"/objects/role names 0 targets"),
    (("background", "target", "target", "noise"), r"/objects/role names 2 targets \(ids 1, 2\)"),
])
def test_object_table_needs_exactly_one_target(tmp_path: Path, roles, words) -> None:
    path = _labelled(tmp_path / "l.h5")
    _replace(path, "objects/role", _roles(*roles))
    with pytest.raises(UserError, match=rf"l\.h5: damaged dvsot file \({words}"):
        Dataset(path)


def test_the_target_id_comes_from_the_table(tmp_path: Path) -> None:
    from dvsot.dataset.torchdata import SegmentDataset

    path = _labelled(tmp_path / "l.h5")
    _replace(path, "objects/role", _roles("background", "distractor", "target", "noise"))  # id 1 a distractor
    with Dataset(path) as ds:
        assert ds.target_id == 2
        seg = ds.segment(1)
    assert (seg.events.object == 1).any()
    _, _, objects, mask, _ = SegmentDataset(path, labels=True, with_box=False)[1]
    assert not mask.any()  # id 1's events are the distractor's, not the target's
    with Dataset(_labelled(tmp_path / "plain.h5")) as ds:
        assert ds.target_id == 1


@pytest.mark.parametrize("name, change, words", [
    ("segments/absent", lambda a: np.where(a == 1, -1, 0).astype(np.int8),
     r"/segments/absent holds -1 at segment \d+, expected 0 or 1"),
    ("segments/absent", lambda a: np.ones_like(a), r"/segments/absent is 1 at segment 0, but its boxes are both there"),
    ("boxes/visibility", lambda v: np.where(np.arange(len(v)) == 0, 0, v).astype(np.float32),
     r"/boxes/visibility is 0 at row 0, beside a visible box"),
    ("segments/visibility", lambda v: np.zeros_like(v),
     r"/segments/visibility is 0 at row 0, beside a visible box"),
    ("boxes/xywh_visible", lambda b: np.where(np.arange(len(b))[:, None] == 1, [30, 30, 8, 8], b).astype(np.float32),
     r"/boxes/xywh_visible row 1 \(x=30 y=30 w=8 h=8\) lies outside the amodal box /boxes/xywh"),
    ("segments/t", lambda t: t[::-1].copy(), r"/segments/t is \d+ us at segment 1, not after segment 0's"),
])
def test_crafted_ground_truth_is_refused_naming_the_dataset(tmp_path: Path, name, change, words) -> None:
    path = _visible(tmp_path / "v.h5")
    Dataset(path).close()  # as written, it opens
    _replace(path, name, change)
    with pytest.raises(UserError, match=rf"v\.h5: damaged dvsot file \({words}"):
        Dataset(path)


def test_a_visible_box_within_the_pixel_filter_reach_opens(tmp_path: Path) -> None:
    path = _visible(tmp_path / "v.h5")
    _replace(path, "boxes/xywh_visible", lambda b: (b + [-1, -1, 2, 2]).astype(np.float32))  # a pixel each side
    Dataset(path).close()
