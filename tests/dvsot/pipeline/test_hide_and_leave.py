"""The shipped example scene blender_scenes/examples/hide_and_leave.yaml, rendered tiny: the target is absent while the
wall hides it, its truncation rises to 1 as it leaves the sensor, and every object's truth and mask is kept."""

from pathlib import Path

import numpy as np
import pytest

from dvsot.dataset import Dataset
from dvsot.events.labels import TARGET_ID
from dvsot.pipeline.generate import generate
from dvsot.scene import load_scene

SCENE = Path(__file__).resolve().parents[3] / "blender_scenes" / "examples" / "hide_and_leave.yaml"
# 64x48 px (the lens's field of view kept), few samples, few Cycles samples: a few seconds
TINY = {"sensor.width": 64, "sensor.height": 48, "sampling.max_displacement_px": 3.0, "sampling.min_rate_hz": 10.0,
        "render.samples": 1}


def test_the_example_is_in_no_split_and_not_among_the_nine():
    cfg = load_scene(SCENE)
    assert cfg.split == "" and SCENE not in set(SCENE.parents[1].glob("*.yaml"))
    assert cfg.objects[0].role == "occluder"


@pytest.mark.blender
def test_hidden_stretch_is_absent_and_leaving_truncates(tmp_path):
    cfg = load_scene(SCENE, TINY)
    out = tmp_path / "hide.h5"
    summary = generate(cfg, out, SCENE.read_text(), progress=False, masks=True)
    assert summary["masks"]
    with Dataset(out) as ds:
        track, objects = ds.boxes(), ds.object_track()
        t = track.t / 1e6
        hidden = (t > 0.75) & (t < 1.15)  # the wall covers the whole target (the scene file's comment)
        assert hidden.sum() >= 2 and np.all(track.visibility[hidden] == 0)
        assert np.all(np.isnan(track.xywh_visible[hidden])) and not np.isnan(track.xywh[hidden]).any()
        assert np.all(track.truncation[hidden] == 0)  # hidden is not truncated: on the sensor, behind the wall
        early = t < 0.4
        assert np.all(track.visibility[early] > 0.9) and np.all(track.truncation[early] == 0)
        leaving = (t > 1.8) & (t < 2.3)
        trunc = track.truncation[leaving]
        assert trunc[0] < 0.3 and trunc[-1] > 0.8 and np.all(np.diff(trunc) >= -0.05)
        assert np.all(track.truncation[t > 2.35] == 1) and np.all(np.isnan(track.xywh[t > 2.35]))
        seg_t = (np.arange(ds.num_segments) + 1) * ds.segment_us / 1e6
        absent, seg_trunc = ds.segment_absent(), ds.segment_truncation()
        assert absent[(seg_t > 0.8) & (seg_t < 1.1)].all() and not absent[seg_t < 0.4].any()
        assert seg_trunc[seg_t > 2.4].min() == 1.0 and absent[seg_t > 2.4].all()
        # the wall: always in view and never hidden; the target's row is the target's track
        wall = [r["id"] for r in ds.objects].index(2)
        target = [r["id"] for r in ds.objects].index(TARGET_ID)
        assert np.all(objects.visibility[:, wall] > 0.8) and np.all(objects.truncation[:, wall] == 0)
        np.testing.assert_array_equal(objects.visibility[:, target], track.visibility)
        np.testing.assert_array_equal(objects.truncation[:, target], track.truncation)
        i = int(np.flatnonzero(hidden)[0])
        assert not (ds.mask(i) == TARGET_ID).any() and (ds.mask(i) == 2).sum() == objects.px_visible[i, wall]
