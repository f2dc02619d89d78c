"""Segment attributes from ground truth (benchmarks/evaluation/attributes.py) and scores per attribute (their tables:
tests/benchmarks/analysis/test_attribute_tables.py)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from benchmarks.evaluation.attributes import attribute_ope, attribute_scores, segment_attributes
from benchmarks.evaluation.protocol import SequenceResult
from dvsot.dataset import Dataset, DatasetWriter
from dvsot.events import EventBatch
from dvsot.events.labels import NOISE_ID, TARGET_ID, object_table
from dvsot.scene import parse_scene

SEG = 10_000  # us


def _events(rng, n, x0, y0, w, h, t0, ids):
    x = rng.integers(x0, x0 + w, n).astype(np.uint16)
    y = rng.integers(y0, y0 + h, n).astype(np.uint16)
    t = np.sort(rng.integers(t0, t0 + SEG, n)).astype(np.int64)
    return EventBatch(x, y, t, np.ones(n, np.uint8), object=np.full(n, ids, np.uint8))


def _file(path, scene=None):
    # samples at the segment ends 0, 10, ..., 60 ms; segment i is scored on row i + 1
    t = np.arange(7) * SEG
    box = np.array([[10, 10, 30, 20]] * 4 + [[20, 10, 10, 10]] * 3, np.float32)  # row 4: jump 10 px, shrink
    vis_box = box.copy()
    vis_box[2] = np.nan  # nothing of the target seen at 20 ms
    visibility = [1, 1, 0, 0.2, 1, 1, 1]
    rng = np.random.default_rng(0)
    attrs = {} if scene is None else {"scene_resolved": json.loads(scene.model_dump_json())}
    with DatasetWriter(path, 64, 48, SEG, attrs, objects=object_table([("ball", "distractor")])) as w:
        w.append_events(_events(rng, 100, 10, 10, 30, 20, 0, TARGET_ID))  # segment 0: 100 in 600 px x 10 ms
        w.append_events(_events(rng, 5, 10, 10, 30, 20, SEG, NOISE_ID))  # segment 1: sparse
        # segment 4 (box 20,10,10,10): 30 target events inside, 30 distractor events just beside it
        both = EventBatch.concatenate([_events(rng, 30, 20, 10, 10, 10, 4 * SEG, TARGET_ID),
                                       _events(rng, 30, 30, 10, 4, 10, 4 * SEG, 2)])
        w.append_events(both.select(np.argsort(both.t, kind="stable")))
        w.append_boxes(t, box, vis_box, visibility)
        w.close(60_001)
    return path


def test_attributes_from_a_files_ground_truth(tmp_path):
    with Dataset(_file(tmp_path / "a.h5")) as ds:
        tags = segment_attributes(ds)
    assert set(tags) == {"occlusion", "absent", "fast_motion", "small_target", "low_event_density",
                         "distractor_nearby"}  # no scene: no rotation or camera motion; no truncation dataset
    seg = lambda name: np.flatnonzero(tags[name]).tolist()  # noqa: E731
    assert seg("occlusion") == [1, 2]  # visibility 0 and 0.2 at 20 and 30 ms
    assert seg("absent") == [1]  # the visible box is NaN at 20 ms only
    # centres: (25, 20) for rows 0-3, (25, 15) after: 5 px in one segment, half the 10 px target > 0.05 sizes
    assert seg("fast_motion") == [3]
    assert seg("small_target") == []  # 10 x 10 px of 64 x 48 is 10^4 px^2 at 640 x 480, over 400
    # 100 events / 600 px / 10 ms = 0.017 > 0.01 at segment 0; segment 4: 30 / 100 px / 10 ms = 0.03
    assert seg("low_event_density") == [1, 2, 3, 5]
    assert seg("distractor_nearby") == [4]  # 30 of 60 events in the grown box are the ball's


def test_rotation_and_camera_motion_from_the_scene(tmp_path):
    scene = parse_scene("""name: spin
duration_s: 0.06
camera:
  keyframes: [{t: 0, location: [0, -10, 0], look_at: [0, 0, 0]}]
target:
  shape: cube
  trajectory:
    interpolation: linear
    keyframes:
      - {t: 0, location: [0, 0, 0], rotation_deg: [0, 0, 0]}
      - {t: 0.06, location: [0, 0, 0], rotation_deg: [0, 0, 18]}
""")
    with Dataset(_file(tmp_path / "s.h5", scene)) as ds:
        tags = segment_attributes(ds)
    # 18 degrees in 60 ms about the vertical axis, seen from the front: about 200 deg/s of projected turn > 45
    assert tags["rotation"].all() and not tags["camera_motion"].any()


def _result(tracker, seq, iou, tags, centre=None):
    r = SequenceResult(tracker, seq, np.asarray(iou, float), np.zeros((len(iou), 4), np.float32), [0], 1.0, len(iou))
    r.extra["attributes"] = {k: np.asarray(v, bool) for k, v in tags.items()}
    if centre is not None:
        r.extra["centre_error"] = np.asarray(centre, float)
    return r


def test_scores_per_attribute_pool_the_counted_segments_with_it():
    a = _result("t", "a", [np.nan, 0.8, 0.2, 0.6], {"occlusion": [0, 0, 1, 1], "small_target": [1, 1, 1, 1]})
    b = _result("t", "b", [np.nan, 0.4, 1.0], {"small_target": [0, 0, 1]})  # no visibility: no occlusion tag
    s = attribute_scores([a, b])["t"]
    assert s["all"].segments == 5 and s["all"].accuracy == pytest.approx(3.0 / 5)
    assert s["occlusion"].segments == 2 and s["occlusion"].accuracy == pytest.approx(0.4)
    assert s["occlusion"].robustness == pytest.approx(0.5)
    assert s["small_target"].segments == 4 and s["small_target"].robustness == pytest.approx(0.75)


def test_ope_success_per_attribute():
    a = _result("t", "a", [np.nan, 0.8, 0.2, 0.6], {"occlusion": [0, 0, 1, 1]}, centre=[np.nan, 1, 30, 5])
    s = attribute_ope([a])["t"]
    # success: fraction of IoU > threshold over 21 thresholds, mean -> AUC; 0.2 and 0.6 in the occluded ones
    want = np.mean([(np.array([0.2, 0.6]) > th).mean() for th in np.linspace(0, 1, 21)])
    assert s["occlusion"]["AUC"] == pytest.approx(want) and s["occlusion"]["segments"] == 2
    assert s["occlusion"]["P@20"] == pytest.approx(0.5)
