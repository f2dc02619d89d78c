"""Every object's ground truth, truncation and the kept object index masks: written, read back, old files unchanged."""

from __future__ import annotations

import numpy as np
import pytest

from dvsot.dataset import Dataset
from dvsot.dataset.boxes import object_rows
from dvsot.events import EventParams, EventSimulator
from dvsot.events.labels import TARGET_ID, LabelledFrame, object_table
from dvsot.pipeline.sequence import write_sequence

W, H, SAMPLES = 24, 16, 9


def scene_frames():
    """A 4 px square target moving 2 px right per ms and leaving the sensor, a still occluder (id 2) at x 10..13."""
    frames, rows, trunc = [], [], []
    for k in range(SAMPLES):
        level, ids = np.full((H, W), 0.1), np.zeros((H, W), np.uint8)
        x0 = 8 + 2 * k
        target = np.zeros((H, W), bool)
        target[6:10, x0:x0 + 4] = True
        level[target], ids[target] = 0.6, TARGET_ID
        occluder = np.zeros((H, W), bool)
        occluder[4:12, 10:14] = True
        level[occluder], ids[occluder] = 0.3, 2
        on = float(target.sum())
        trunc.append(1 - on / 16)
        frames.append(LabelledFrame(level, ids))
        rows.append(object_rows(ids, np.array([0, 1, 2, 255]), {1: (target, on, 16.0), 2: (occluder, 32.0, 32.0)}))
    return frames, rows, np.array(trunc, np.float32)


def write_scene(path, masks=True, objects=True):
    frames, rows, trunc = scene_frames()
    t = np.arange(SAMPLES) * 1000
    stacked = {name: np.stack([r[name] for r in rows]) for name in rows[0]}

    def boxes():
        out = {"t_us": t, "xywh": stacked["boxes_amodal"][:, 1], "xywh_visible": stacked["boxes_visible"][:, 1],
               "visibility": stacked["visibility"][:, 1], "truncation": trunc}
        if objects:
            out["objects"] = stacked
        return out

    sim = EventSimulator(W, H, EventParams(cp=0.2, cn=0.2), seed=1)
    out, _ = write_sequence(path, frames, t, sim, {}, 2000, is_log=True, boxes=boxes, masks=masks,
                            objects=object_table([("wall", "occluder")]))
    return out, frames, stacked, trunc


def test_masks_objects_and_truncation_read_back(tmp_path):
    path, frames, stacked, trunc = write_scene(tmp_path / "s.h5")
    with Dataset(path) as ds:
        assert ds.has_masks
        np.testing.assert_array_equal(ds.masks(0, SAMPLES), np.stack([f.objects for f in frames]))
        assert (ds.mask(0) == TARGET_ID).sum() == 8 and not (ds.mask(1) == TARGET_ID).any()  # half, wholly hidden
        track = ds.object_track()
        assert track.ids.tolist() == [0, 1, 2, 255] and track.boxes_amodal.shape == (SAMPLES, 4, 4)
        for name in stacked:
            np.testing.assert_array_equal(getattr(track, name), stacked[name])
        np.testing.assert_array_equal(ds.boxes().truncation, trunc)
        seg = ds.segment_truncation()  # segment i ends at (i + 1) * 2 ms: sample 2 (i + 1)
        np.testing.assert_allclose(seg, trunc[2::2][:len(seg)])
        assert trunc[6] == 0 and trunc[7] == 0.5 and ds.segment(3).truncation == trunc[8] == 1.0
        assert track.visibility[1, 1] == 0 and track.visibility[0, 1] == 0.5 and track.visibility[0, 2] == 1
        assert ds.sample_at(2400) == 2 and ds.sample_at(2500) == 2 and ds.sample_at(2600) == 3
        ds.verify()


def test_files_without_the_new_datasets_still_open(tmp_path):
    path, *_ = write_scene(tmp_path / "plain.h5", masks=False, objects=False)
    with Dataset(path) as ds:
        assert not ds.has_masks and ds.object_track() is None
        assert ds.segment_truncation() is not None
        with pytest.raises(Exception, match="no /masks/objects"):
            ds.mask(0)


def test_writer_refuses_a_mask_of_an_unknown_id_or_a_share_outside_0_1(tmp_path):
    from dvsot.dataset import DatasetWriter

    with pytest.raises(ValueError, match="mask id 7"):
        with DatasetWriter(tmp_path / "m.h5", W, H, 2000, objects=object_table()) as w:
            w.append_mask(np.full((H, W), 7, np.uint8))
    with pytest.raises(ValueError, match="truncation must lie in 0..1"):
        with DatasetWriter(tmp_path / "t.h5", W, H, 2000) as w:
            w.append_boxes([0], [[1, 1, 2, 2]], truncation=[1.5])
    _, rows, _ = scene_frames()
    bad = dict(rows[0], px_visible=rows[0]["px_visible"] // 2)
    with pytest.raises(ValueError, match="do not add up to the sensor's pixels"):
        with DatasetWriter(tmp_path / "o.h5", W, H, 2000, objects=object_table([("wall", "occluder")])) as w:
            w.append_object_rows(bad)
    assert not list(tmp_path.iterdir())


def _replace(name, data):
    def damage(f):
        del f[name]
        f.create_dataset(name, data=data)
    return damage


def _edit(name, fn):
    def damage(f):
        data = f[name][()]
        _replace(name, fn(data))(f)
    return damage


DAMAGE = [
    ("masks/objects", _edit("masks/objects", lambda m: m[:-1]), "has 8 rows, /boxes/t has 9"),
    ("masks/objects", _edit("masks/objects", lambda m: np.where(m == 2, 9, m).astype(np.uint8)), "holds id 9"),
    ("masks/objects", _edit("masks/objects", lambda m: m[:, :, :-1]), "the sensor is 24x16"),
    ("objects/visibility", _edit("objects/visibility", lambda v: v * 3), "outside 0..1"),
    ("objects/truncation", _edit("objects/truncation", lambda v: v - 1), "outside 0..1"),
    ("objects/px_visible", _edit("objects/px_visible", lambda v: v[:, :3]), "3 objects per sample"),
    ("objects/px_visible", _edit("objects/px_visible", lambda v: v // 2), "not the sensor's 384"),
    ("objects/boxes_amodal", _edit("objects/boxes_amodal", lambda b: b[1:]), "has 8 rows"),
    ("objects/px_amodal", lambda f: f.__delitem__("objects/px_amodal"), "missing /objects/px_amodal"),
    ("boxes/truncation", _edit("boxes/truncation", lambda v: v + 2), "outside 0..1"),
    ("segments/truncation", _edit("segments/truncation", lambda v: v[:-1]), "has 3 rows"),
    ("boxes/truncation", lambda f: f.__delitem__("boxes/truncation"), "missing /boxes/truncation"),
]


@pytest.fixture(scope="module")
def pristine(tmp_path_factory):
    return write_scene(tmp_path_factory.mktemp("truth") / "s.h5")[0]


@pytest.mark.parametrize("field,damage,words", DAMAGE, ids=[f"{d[0]}:{d[2]}" for d in DAMAGE])
def test_damaged_truth_is_one_line_naming_file_and_dataset_exit_2(pristine, tmp_path, field, damage, words):
    import shutil

    import h5py

    from dvsot.cli import main
    from dvsot.core.errors import UserError

    path = tmp_path / "bad.h5"
    shutil.copy(pristine, path)
    with h5py.File(path, "a") as f:
        damage(f)
    with pytest.raises(UserError) as info:
        with Dataset(path) as ds:
            ds.verify()
    msg = str(info.value)
    assert str(path) in msg and f"/{field}" in msg and words in msg and "\n" not in msg, msg
    assert main(["info", str(path)]) == 2


def _set_attr(name, key, value):
    def damage(f):
        f[name].attrs[key] = value
    return damage


def _write_rows(name, rows, value):
    def damage(f):  # in place: the dataset keeps its attributes
        f[name][rows] = np.full_like(f[name][rows], value)
    return damage


# refused on open: a command that only opens the files (export --layout reads no event and no mask) exits 2
OPEN_DAMAGE = [
    ("masks/objects", _edit("masks/objects", lambda m: m[:-1]), "has 8 rows, /boxes/t has 9"),
    ("segments/absent", _edit("segments/absent", lambda v: v[:-1]), "has 3 rows, /segments/xywh has 4"),
    ("segments/visibility", _edit("segments/visibility", lambda v: np.append(v, v[-1])), "has 5 rows"),
    ("segments/truncation", _edit("segments/truncation", lambda v: v[:-1]), "has 3 rows"),
    ("boxes/visibility", _edit("boxes/visibility", lambda v: v[:-1]), "has 8 rows, /boxes/t has 9"),
    ("masks/objects", _set_attr("masks/objects", "ids", np.array([0, 1, 2, 9], np.uint8)), "holds id 9"),
    ("masks/objects", _set_attr("masks/objects", "ids", np.array([[0, 1]], np.uint8)), "attribute 'ids'"),
    ("segments/visibility", _write_rows("segments/visibility", 0, 1.5), "outside 0..1"),
    ("boxes/visibility", _write_rows("boxes/visibility", 0, -0.25), "outside 0..1"),
    ("objects/visibility", _write_rows("objects/visibility", 0, 2.0), "outside 0..1"),
    ("segments/absent", _write_rows("segments/absent", 0, 2), "expected 0 or 1"),
]


@pytest.mark.parametrize("field,damage,words", OPEN_DAMAGE, ids=[f"{d[0]}:{d[2]}" for d in OPEN_DAMAGE])
def test_bad_tags_masks_and_ids_are_refused_on_open(pristine, tmp_path, capsys, field, damage, words):
    import shutil

    import h5py

    from dvsot.cli import main
    from dvsot.core.errors import UserError

    path = tmp_path / "bad.h5"
    shutil.copy(pristine, path)
    with h5py.File(path, "a") as f:
        damage(f)
    with pytest.raises(UserError, match=words):
        Dataset(path)  # opening alone, no read of events or masks
    capsys.readouterr()
    assert main(["export", str(path), "--layout", "vot", "-o", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(path) in err[0] and f"/{field}" in err[0] and words in err[0], err
    assert not (tmp_path / "out").exists()


def test_mask_ids_are_listed_at_write_and_checked_on_read_old_files_too(pristine, tmp_path, capsys):
    import shutil

    import h5py

    from dvsot.cli import main

    with h5py.File(pristine, "r") as f:
        assert f["masks/objects"].attrs["ids"].tolist() == [0, 1, 2]  # background, target, wall: no noise id
    # an id of the table that the attribute does not list: the attribute is wrong, found when the images are read
    listed = tmp_path / "listed.h5"
    shutil.copy(pristine, listed)
    with h5py.File(listed, "a") as f:
        _write_rows("masks/objects", 4, 255)(f)
    Dataset(listed).close()
    assert main(["info", str(listed)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "/masks/objects holds id 255 at sample 4" in err[0] and "'ids' does not" in err[0], err
    # a file written before the attribute opens, and an id outside the table is still refused on read
    old = tmp_path / "old.h5"
    shutil.copy(pristine, old)
    with h5py.File(old, "a") as f:
        del f["masks/objects"].attrs["ids"]
    with Dataset(old) as ds:
        np.testing.assert_array_equal(ds.masks(0, SAMPLES), np.stack([fr.objects for fr in scene_frames()[0]]))
    with h5py.File(old, "a") as f:
        _write_rows("masks/objects", 4, 9)(f)
    Dataset(old).close()
    assert main(["info", str(old)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "holds id 9 at sample 4, which /objects/id does not list" in err[0], err


def test_segment_dataset_labels_give_the_rendered_silhouette_and_shares(tmp_path):
    from dvsot.dataset.tonic_dataset import TonicDataset
    from dvsot.dataset.torchdata import SegmentDataset, collate_segments

    path, frames, stacked, trunc = write_scene(tmp_path / "s.h5")
    data = SegmentDataset(path, labels=True, with_box=False)
    events, box, objects, event_mask, truth = data[0]  # segment 0 ends at 2 ms: sample 2
    np.testing.assert_array_equal(truth["silhouette"], frames[2].objects == TARGET_ID)
    assert truth["visibility"] == stacked["visibility"][2, 1] and truth["truncation"] == trunc[2]
    assert truth["absent"] is False and event_mask.shape == truth["silhouette"].shape == (H, W)
    last = data[3][4]  # ends at 8 ms: the target has left the sensor
    assert last["truncation"] == 1.0 and last["absent"] and not last["silhouette"].any()
    target = TonicDataset(path, labels=True, with_box=False)[3][1]
    assert set(target) == {"box", "objects", "event_mask", "silhouette", "visibility", "truncation", "absent"}
    assert np.isnan(target["box"]).all() and target["truncation"] == 1.0
    pytest.importorskip("torch")
    *_, batch = collate_segments([data[0], data[3]])
    assert tuple(batch["silhouette"].shape) == (2, H, W) and batch["absent"].tolist() == [False, True]
    assert batch["truncation"][1].item() == 1.0


def test_the_same_scene_gives_the_same_bytes_however_slow_the_writer_thread(tmp_path, monkeypatch):
    """The first frame gives no events but a mask: the file's objects are still made in one order, so a writer
    thread that lags behind the caller changes no byte."""
    import time

    from dvsot.dataset.writer import DatasetWriter

    (tmp_path / "prompt").mkdir()
    (tmp_path / "late").mkdir()
    prompt, _, _, _ = write_scene(tmp_path / "prompt" / "s.h5")
    write_mask = DatasetWriter._write_mask

    def slow(self, row, img):
        time.sleep(0.2)  # the caller meanwhile appends the next frames' events
        write_mask(self, row, img)

    monkeypatch.setattr(DatasetWriter, "_write_mask", slow)
    late, _, _, _ = write_scene(tmp_path / "late" / "s.h5")
    assert prompt.read_bytes() == late.read_bytes()
