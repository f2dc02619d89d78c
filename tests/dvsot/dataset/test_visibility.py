"""Target visibility per sample and per segment, and the absent flag, through the dataset file."""

from __future__ import annotations

import numpy as np
import pytest

from dvsot.core.errors import UserError
from dvsot.dataset import Dataset, DatasetWriter
from dvsot.dataset.boxes import mask_visibility

NAN4 = [np.nan] * 4


def test_mask_visibility_is_visible_over_amodal_pixels():
    amodal = np.zeros((10, 10), bool)
    amodal[2:6, 2:7] = True  # 20 px
    visible = amodal.copy()
    visible[2:6, 5:7] = False  # 8 px hidden by an occluder
    assert mask_visibility(amodal, visible) == pytest.approx(12 / 20)
    assert mask_visibility(amodal, np.zeros_like(amodal)) == 0.0
    assert mask_visibility(np.zeros_like(amodal), np.zeros_like(amodal)) == 0.0  # outside the sensor
    grown = amodal.copy()
    grown[6, 2:7] = True  # a visible pixel the raster left out: clipped at 1
    assert mask_visibility(amodal, grown) == 1.0


def _write(path, visibility=(1.0, 0.5, 0.0, 0.0, 1.0)):
    # samples every 10 ms; the target fully hidden at 20 and 30 ms
    t = np.arange(5) * 10_000
    box = np.tile([10.0, 10.0, 8.0, 8.0], (5, 1))
    vis_box = box.copy()
    vis_box[2:4] = np.nan
    with DatasetWriter(path, 64, 48, segment_us=5_000) as w:
        w.append_boxes(t, box, vis_box, visibility)
        w.close(40_001)
    return path


def test_segments_carry_interpolated_visibility_and_absent(tmp_path):
    with Dataset(_write(tmp_path / "v.h5")) as ds:
        vis, absent = ds.segment_visibility(), ds.segment_absent()
        # segment ends 5, 10, ..., 40 ms
        assert np.allclose(vis, [0.75, 0.5, 0.25, 0.0, 0.0, 0.0, 0.5, 1.0])
        # absent where the visible box at the end is NaN: either neighbouring sample shows nothing
        assert absent.tolist() == [False, False, True, True, True, True, True, False]
        seg = ds.segment(3)
        assert seg.visibility == 0.0 and seg.absent is True
        assert np.allclose(ds.boxes().visibility, [1.0, 0.5, 0.0, 0.0, 1.0])


def test_files_without_visibility_say_none(tmp_path):
    with DatasetWriter(tmp_path / "n.h5", 64, 48) as w:
        w.append_boxes([0, 10_000], np.tile([1.0, 1.0, 4.0, 4.0], (2, 1)))
        w.close(20_000)
    with Dataset(tmp_path / "n.h5") as ds:
        assert ds.segment_visibility() is None and ds.segment_absent() is None
        assert ds.segment(0).visibility is None and ds.boxes().visibility is None


def test_visibility_out_of_range_is_refused(tmp_path):
    with pytest.raises(ValueError, match="visibility must lie in 0..1"):
        _write(tmp_path / "bad.h5", visibility=(1.0, 1.5, 0.0, 0.0, 1.0))
    import h5py

    path = _write(tmp_path / "v.h5")
    with h5py.File(path, "r+") as f:
        del f["segments/visibility"]
        f["segments"].create_dataset("visibility", data=np.full(8, 2.0, np.float32))
    with pytest.raises(
        UserError, match=r"v\.h5: damaged dvsot file \(/segments/visibility holds values outside 0\.\.1\)"
    ):
        Dataset(path)


def test_info_counts_absent_segments(tmp_path):
    from dvsot.dataset.info import dataset_info

    info = dataset_info(_write(tmp_path / "v.h5"))
    assert info["segments_absent"] == 5
    assert info["visibility_median"] == pytest.approx(0.375)  # 0.75, 0.5, 0.25, 0, 0, 0, 0.5, 1: (0.25 + 0.5) / 2
