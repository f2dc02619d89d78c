"""Exports carry the ground truth: `OUT.gt.csv` beside the events, and the GOT-10k, LaSOT and VOT layouts' tag files,
read back by got10k's own GOT10k and LaSOT readers and by the VOT toolkit's own sequence reader."""

from __future__ import annotations

import csv
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from dvsot.cli import main
from dvsot.core.errors import UserError
from dvsot.core.file_names import file_stem
from dvsot.dataset import Dataset, DatasetWriter
from dvsot.dataset.tags import cover_label, tags_from_truth
from dvsot.events import EventBatch
from dvsot.interop.event_files import LabelsLeftOut, export_dataset, gt_path
from dvsot.interop.toolkit_layouts import TagsLeftOut, export_layout

W, H = 32, 24
NAN = [np.nan] * 4
# samples every 10 ms, so segment i (10 ms) ends on sample i + 1 and takes its values exactly
AMODAL = [[2, 2, 8, 8]] * 4 + [[0, 2, 6, 8], [0, 2, 3, 8], NAN, [2, 2, 8, 8], [2, 2, 8, 8]]
VISIBLE = [[2, 2, 8, 8], [2, 2, 8, 5], [2, 2, 8, 3], NAN, [0, 2, 6, 8], [0, 2, 3, 8], NAN, [2, 2, 8, 8], [2, 2, 8, 8]]
VISIBILITY = [1, 0.6, 0.3, 0, 1, 1, 0, 1, 1]
TRUNCATION = [0, 0, 0, 0, 0.2, 0.7, 1, 0, 0]
# per segment (samples 1..8): partly hidden, mostly hidden, wholly hidden, cut, mostly cut, gone, back, back
WANT = {"absent": [0, 0, 1, 0, 0, 1, 0, 0], "occlusion": [1, 1, 1, 0, 0, 0, 0, 0],
        "full_occlusion": [0, 0, 1, 0, 0, 0, 0, 0], "out_of_view": [0, 0, 0, 0, 0, 1, 0, 0],
        "cut_by_image": [0, 0, 0, 1, 1, 0, 0, 0]}
WANT_COVER = [4, 2, 0, 6, 2, 0, 8, 8]  # seen shares 0.6, 0.3, -, 0.8, 0.3, -, 1, 1


def truth_file(path: Path, name: str = "walls", truth: bool = True) -> Path:
    """A 32x24 file of 8 segments whose target is hidden, cut by the image's edge and leaves it (WANT)."""
    n = 40
    ev = EventBatch(np.arange(n, dtype=np.uint16) % W, np.full(n, 5, np.uint16), np.arange(n, dtype=np.int64) * 2000,
                    np.arange(n, dtype=np.uint8) % 2)
    with DatasetWriter(path, W, H, 10_000, {"name": name, "split": "test"}, t_offset_us=1_000_000) as w:
        w.append_events(ev)
        w.append_boxes(np.arange(9) * 10_000, AMODAL, VISIBLE, VISIBILITY if truth else None,
                       TRUNCATION if truth else None)
        w.close(80_000)
    return path


def test_tags_and_cover_follow_their_definitions():
    tags = tags_from_truth(np.array(AMODAL[1:], np.float32), np.array(VISIBILITY[1:], np.float32),
                           np.isnan(np.array(VISIBLE[1:])).any(axis=1), np.array(TRUNCATION[1:], np.float32))
    assert {k: v.astype(int).tolist() for k, v in tags.items()} == WANT
    # GOT-10k's bins: 0 none, 1 (0, 15%], 2 (15%, 30%], ..., 7 (90%, 100%), 8 all of it
    shares = np.array([0, 1e-4, 0.15, 0.16, 0.3, 0.45, 0.6, 0.75, 0.9, 0.91, 0.999, 1.0], np.float32)
    assert cover_label(shares, np.zeros(len(shares), bool)).tolist() == [0, 1, 1, 2, 2, 3, 4, 5, 6, 7, 7, 8]
    assert cover_label(np.ones(2), np.array([True, False]), np.array([0.0, 0.5])).tolist() == [0, 4]
    # a file without visibility or truncation decides no tag
    assert tags_from_truth(np.array(AMODAL[1:]), None, None, None) == {}


def test_gt_csv_holds_every_segment_and_its_tags(tmp_path):
    src = truth_file(tmp_path / "walls.h5")
    written = export_dataset(src, tmp_path / "w.aedat4")
    assert [p.name for p in written] == ["w.aedat4", "w.aedat4.boxes.csv", "w.aedat4.gt.csv"]
    with open(gt_path(tmp_path / "w.aedat4"), newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert list(rows[0]) == ["segment", "t_s", "x", "y", "w", "h", "visible_x", "visible_y", "visible_w", "visible_h",
                             "visibility", "truncation", "absent", "occlusion", "full_occlusion", "out_of_view",
                             "cut_by_image"]
    with Dataset(src) as ds:
        box, vis_box = ds.segment_boxes(), ds.segment_visible_boxes()
        vis, trunc = ds.segment_visibility(), ds.segment_truncation()
    assert [r["t_s"] for r in rows] == [f"1.0{k}0000" for k in range(1, 9)]  # segment ends + /t_offset
    got = {name: np.array([float(r[name]) for r in rows], np.float32) for name in rows[0] if name != "t_s"}
    np.testing.assert_array_equal(np.stack([got[k] for k in "xywh"], 1), box)  # exact, NaN where none
    np.testing.assert_array_equal(np.stack([got[f"visible_{k}"] for k in "xywh"], 1), vis_box)
    np.testing.assert_array_equal(got["visibility"], vis)
    np.testing.assert_array_equal(got["truncation"], trunc)
    assert {k: got[k].astype(int).tolist() for k in WANT} == WANT
    # read as a table by numpy too: one header line, the rest numbers
    table = np.genfromtxt(gt_path(tmp_path / "w.aedat4"), delimiter=",", names=True)
    assert len(table) == 8 and table["segment"].tolist() == list(range(8))


def test_gt_csv_of_a_file_without_visibility_has_the_boxes_only(tmp_path):
    src = truth_file(tmp_path / "plain.h5", truth=False)
    export_dataset(src, tmp_path / "p.csv")
    header = gt_path(tmp_path / "p.csv").read_text().splitlines()[0].split(",")
    assert header == ["segment", "t_s", "x", "y", "w", "h", "visible_x", "visible_y", "visible_w", "visible_h"]


def test_gt_csv_is_refused_over_another_file_and_goes_with_no_boxes(tmp_path, capsys):
    src = truth_file(tmp_path / "walls.h5")
    (tmp_path / "y.csv.gt.csv").write_text("t,x,y,p\n1,2,3,1\n")  # another export's events
    with pytest.raises(UserError, match="is not an export's gt table"):
        export_dataset(src, tmp_path / "y.csv")
    assert not (tmp_path / "y.csv").exists() and not (tmp_path / "y.csv.boxes.csv").exists()
    assert main(["export", str(src), "-o", str(tmp_path / "z.csv")]) == 0
    assert main(["export", str(src), "-o", str(tmp_path / "z.csv.gt.csv")]) == 2
    assert "names the gt table of the export" in capsys.readouterr().err
    assert gt_path(tmp_path / "z.csv").is_file()
    assert main(["export", str(src), "-o", str(tmp_path / "z.csv"), "--no-boxes"]) == 0
    assert not gt_path(tmp_path / "z.csv").exists() and not (tmp_path / "z.csv.boxes.csv").exists()


def _labelled(path: Path) -> Path:
    from dvsot.events import EventParams, EventSimulator
    from dvsot.events.labels import TARGET_ID, LabelledFrame, object_table
    from dvsot.pipeline.sequence import write_sequence

    frames = []
    for k in range(9):
        level, ids = np.zeros((16, 24)), np.zeros((16, 24), np.uint8)
        level[6:10, 2 + 2 * k:6 + 2 * k], ids[6:10, 2 + 2 * k:6 + 2 * k] = 0.6, TARGET_ID
        frames.append(LabelledFrame(level, ids))
    sim = EventSimulator(24, 16, EventParams(cp=0.2, cn=0.2), seed=1)
    out, _ = write_sequence(path, frames, np.arange(9) * 1000, sim, {}, 4000, is_log=True, objects=object_table([]))
    return out


@pytest.mark.parametrize("suffix", [".txt", ".aedat4", ".raw", ".dat"])
def test_formats_without_labels_say_so_in_one_line(tmp_path, capsys, suffix):
    src = _labelled(tmp_path / "l.h5")
    with pytest.warns(LabelsLeftOut, match="per-event object labels"):
        export_dataset(src, tmp_path / f"a{suffix}")
    assert main(["export", str(src), "-o", str(tmp_path / f"b{suffix}")]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("dvsot export: note: ") and f"b{suffix}" in err[0], err
    # a CSV keeps them, and a file without labels loses nothing: no note
    assert main(["export", str(src), "-o", str(tmp_path / "c.csv")]) == 0
    assert main(["export", str(truth_file(tmp_path / "walls.h5")), "-o", str(tmp_path / f"d{suffix}")]) == 0
    assert capsys.readouterr().err == ""


# --- the toolkits' readers, as they parse these files ---------------------------------------------------------

def got10k_sequences(subset_dir: Path) -> dict[str, tuple[np.ndarray, dict]]:
    """got10k's own GOT10k(root, subset, return_meta=True): list.txt, groundtruth.txt, meta_info.ini and the labels.

    GOT10k takes subset_dir's name for its subset (train or val: its test subset reads no labels) and asserts one
    frame image per groundtruth line; the export keeps the events in the dataset files, so empty stand-ins
    (`00000001.jpg`, ...) are put beside the labels first."""
    from got10k.datasets import GOT10k

    for name in (subset_dir / "list.txt").read_text().split():
        lines = len((subset_dir / name / "groundtruth.txt").read_text().splitlines())
        for k in range(lines):
            (subset_dir / name / f"{k + 1:08d}.jpg").touch()
    data = GOT10k(str(subset_dir.parent), subset=subset_dir.name, return_meta=True)
    out = {}
    for name in data.seq_names:
        frames, anno, meta = data[name]
        assert len(frames) == len(anno)
        out[name] = anno, meta
    return out


def lasot_sequence(seq: Path) -> tuple[np.ndarray, dict]:
    """got10k's LaSOT reading of <cat>/<cat>-<n>/ (its _fetch_meta and np.loadtxt), and pytracking's (csv, first
    row). got10k's LaSOT class lists the sequences of its own split file, so its per-sequence reader is called."""
    from got10k.datasets import LaSOT

    meta = LaSOT._fetch_meta(None, str(seq / "img"))  # it takes the sequence's img/ directory and reads its parent
    for att in ("full_occlusion", "out_of_view"):
        with open(seq / f"{att}.txt", newline="") as fh:
            assert [int(v) for v in list(csv.reader(fh))[0]] == meta[att].astype(int).tolist()
    return np.loadtxt(seq / "groundtruth.txt", delimiter=","), meta


def vot_sequence(seq: Path) -> tuple[np.ndarray, dict[str, list[int]], dict[str, np.ndarray], Any]:
    """The VOT toolkit's own vot.dataset.common.read_sequence: `sequence` (key=value; without `length` the toolkit
    looks for frame images), groundtruth.txt's regions as x,y,w,h (an empty one, NaN in the export, is the toolkit's
    Special code 0: state unknown), and per frame the *.tag names set and the *.value numbers.

    vot-toolkit comes from requirements-vot.txt with --no-deps: its opencv-python would replace the opencv-contrib
    build that dvsot's KCF and CSRT baselines need."""
    from vot.dataset import Sequence
    from vot.dataset.common import read_sequence
    from vot.region import Rectangle, Special

    sequence = read_sequence(str(seq))
    n = len(sequence)
    boxes = []
    for k in range(n):
        region = sequence.groundtruth(k)
        if isinstance(region, Special):
            assert region.code == Sequence.UNKNOWN, (k, region)
            boxes.append([np.nan] * 4)
        else:
            assert isinstance(region, Rectangle), (k, region)
            boxes.append([region.x, region.y, region.width, region.height])
    tags = {t: [int(t in sequence.tags(k)) for k in range(n)] for t in sequence.tags()}
    values = {v: np.array([sequence.values(k)[v] for k in range(n)], np.float32) for v in sequence.values()}
    # the toolkit pads a short tag or value file with False or 0.0: each file holds one line per frame itself
    for path in [seq / "groundtruth.txt", *seq.glob("*.tag"), *seq.glob("*.value")]:
        assert len(path.read_text().splitlines()) == n, path.name
    return np.array(boxes, np.float32), tags, values, sequence


def test_layouts_read_back_as_the_toolkits_read_them(tmp_path):
    data = tmp_path / "data"
    data.mkdir()
    truth_file(data / "walls.h5")
    truth_file(data / "other.h5", name="../odd name")
    with Dataset(data / "walls.h5") as ds:
        box, vis, trunc = ds.segment_boxes(), ds.segment_visibility(), ds.segment_truncation()

    export_layout(data, tmp_path / "got10k" / "val", "got10k")
    seqs = got10k_sequences(tmp_path / "got10k" / "val")
    assert sorted(seqs) == sorted(["walls", file_stem("../odd name")])  # as bench names its result files
    anno, meta = seqs["walls"]
    np.testing.assert_array_equal(anno.astype(np.float32), box)
    assert meta["cover"].astype(int).tolist() == WANT_COVER
    assert meta["absence"].astype(int).tolist() == WANT["absent"]
    assert meta["cut_by_image"].astype(int).tolist() == WANT["cut_by_image"]
    assert meta["resolution"] == f"({W}, {H})" and meta["anno_fps"] == "100Hz"
    # GOT-10k's evaluation scores frames with cover > 0: the hidden and the gone segments are left out
    assert np.flatnonzero(meta["cover"] == 0).tolist() == [2, 5]

    export_layout(data / "walls.h5", tmp_path / "lasot", "lasot")
    anno, meta = lasot_sequence(tmp_path / "lasot" / "walls" / "walls-1")
    np.testing.assert_array_equal(anno.astype(np.float32), box)
    assert meta["full_occlusion"].astype(int).tolist() == WANT["full_occlusion"]
    assert meta["out_of_view"].astype(int).tolist() == WANT["out_of_view"]
    assert meta["nlp"] == "target"

    export_layout(str(data / "walls.h5"), tmp_path / "vot", "vot")
    from vot.dataset.common import list_sequences

    assert list_sequences(str(tmp_path / "vot")) == ["walls"]
    regions, tags, values, sequence = vot_sequence(tmp_path / "vot" / "walls")
    np.testing.assert_array_equal(regions, box)  # exact, NaN where the target is gone
    assert tags == WANT
    np.testing.assert_array_equal(values["visibility"], vis)
    np.testing.assert_array_equal(values["truncation"], trunc)
    assert sorted(values) == ["truncation", "visibility"]
    assert (sequence.name, sequence.metadata("name"), sequence.metadata("fps")) == ("walls", "walls", 100)
    assert (len(sequence), sequence.width, sequence.height) == (8, W, H)


def test_a_layout_of_a_file_without_visibility_leaves_its_tags_out_and_says_so(tmp_path, capsys):
    src = truth_file(tmp_path / "plain.h5", name="plain", truth=False)
    with pytest.warns(TagsLeftOut, match="absence.label, cover.label, cut_by_image.label"):
        export_layout(src, tmp_path / "g", "got10k")
    assert sorted(p.name for p in (tmp_path / "g" / "plain").iterdir()) == ["groundtruth.txt", "meta_info.ini"]
    assert main(["export", str(src), "--layout", "vot", "-o", str(tmp_path / "v")]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("dvsot export: note: ") and "plain.h5" in err[0], err


def test_layout_exports_refuse_clashes_and_strangers_before_writing(tmp_path, capsys):
    a, b = tmp_path / "a", tmp_path / "b"
    a.mkdir(), b.mkdir()
    truth_file(a / "x.h5", name="same")
    truth_file(b / "y.h5", name="same")
    with pytest.raises(UserError, match="would share the directory"):
        export_layout([a, b], tmp_path / "out", "vot")
    assert not (tmp_path / "out").exists()
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "notes.txt").write_text("mine")
    assert main(["export", str(a), "--layout", "got10k", "-o", str(tmp_path / "mine")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "-o holds files that are not an earlier run's" in err[0], err
    assert sorted(p.name for p in (tmp_path / "mine").iterdir()) == ["notes.txt"]
    # an export again replaces the earlier one's files; the sequences it no longer has go
    assert main(["export", str(a), "--layout", "vot", "-o", str(tmp_path / "v")]) == 0
    truth_file(tmp_path / "z.h5", name="other")
    assert main(["export", str(tmp_path / "z.h5"), "--layout", "vot", "-o", str(tmp_path / "v")]) == 0
    assert (tmp_path / "v" / "list.txt").read_text() == "other\n" and not (tmp_path / "v" / "same").exists()
    assert main(["export", str(a), "--layout", "vot", "-o", str(tmp_path / "w"), "--no-boxes"]) == 2
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert main(["export", str(a), "--layout", "lasot", "-o", str(tmp_path / "l")]) == 0


@pytest.mark.blender
def test_the_hide_and_leave_example_is_tagged_as_it_plays(tmp_path):
    from dvsot.dataset.tags import segment_tags
    from dvsot.pipeline.generate import generate
    from dvsot.scene import load_scene

    scene = Path(__file__).resolve().parents[3] / "blender_scenes" / "examples" / "hide_and_leave.yaml"
    tiny = {"sensor.width": 64, "sensor.height": 48, "sampling.max_displacement_px": 3.0,
            "sampling.min_rate_hz": 10.0, "render.samples": 1}
    out = tmp_path / "hide.h5"
    generate(load_scene(scene, tiny), out, scene.read_text(), progress=False, masks=False)
    with Dataset(out) as ds:
        tags = segment_tags(ds)
        t = (np.arange(ds.num_segments) + 1) * ds.segment_us / 1e6
    early, hidden, gone = t < 0.3, (t > 0.8) & (t < 1.1), t > 2.4  # the wall reaches the cube at 0.3 s
    assert not any(tags[k][early].any() for k in tags)  # seen whole, on the sensor: no tag
    assert tags["full_occlusion"][hidden].all() and tags["occlusion"][hidden].all()
    assert not tags["out_of_view"][hidden].any() and not tags["cut_by_image"][hidden].any()
    assert tags["out_of_view"][gone].all() and not tags["full_occlusion"][gone].any()
    assert not tags["occlusion"][gone].any()  # off the sensor is out of view, not occluded
    leaving = (t > 1.85) & (t < 2.25)
    assert tags["cut_by_image"][leaving].any() and not tags["cut_by_image"][hidden | gone].any()
    export_layout(out, tmp_path / "g" / "val", "got10k")
    _, meta = got10k_sequences(tmp_path / "g" / "val")["hide_and_leave"]
    assert (meta["cover"][hidden] == 0).all() and (meta["cover"][t < 0.3] == 8).all()  # the wall nears by 0.4 s
    assert (meta["cover"][leaving] < 8).any()
