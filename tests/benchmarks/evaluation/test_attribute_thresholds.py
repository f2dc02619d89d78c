"""Each attribute threshold crossed once: two crafted files, one just over the cut and one just under, at two
sensor resolutions, so an attribute fires on one file and not on the other whatever the resolution
(benchmarks/evaluation/attributes.py)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from benchmarks.evaluation.attributes import THRESHOLDS, segment_attributes, segment_measures
from dvsot.dataset import Dataset, DatasetWriter
from dvsot.scene import parse_scene

SEG = 10_000  # us
N = 6  # segments
SIZES = ((640, 480), (160, 120))  # the reference sensor and a quarter of it


def _boxes_file(path: Path, size: tuple[int, int], box, truncation=None, scene: str | None = None) -> Path:
    """Boxes at 0, 10, ..., 60 ms (xywh per row, or one row repeated) and no events; optional truncation and scene."""
    box = np.broadcast_to(np.asarray(box, np.float32), (N + 1, 4))
    attrs = {} if scene is None else {"scene_resolved": json.loads(parse_scene(scene).model_dump_json())}
    with DatasetWriter(path, *size, SEG, attrs) as w:
        w.append_boxes(np.arange(N + 1) * SEG, box, truncation=truncation)
        w.close(N * SEG + 1)
    return path


def _tags(path: Path) -> dict[str, np.ndarray]:
    with Dataset(path) as ds:
        return segment_attributes(ds)


@pytest.mark.parametrize("size", SIZES)
def test_fast_motion_in_target_sizes_per_segment(tmp_path, size):
    k = size[0] / 640  # the same image motion at either resolution
    side = 40 * k
    for factor, fires in ((1.2, True), (0.8, False)):
        step = factor * THRESHOLDS.fast_sizes_per_segment * side  # pixels per segment
        rows = [[10 * k + step * i, 10 * k, side, side] for i in range(N + 1)]
        tags = _tags(_boxes_file(tmp_path / f"f{factor}.h5", size, rows))
        assert tags["fast_motion"].all() == fires and tags["fast_motion"].any() == fires


@pytest.mark.parametrize("size", SIZES)
def test_small_target_relative_to_the_sensor(tmp_path, size):
    scale = size[0] / 640  # a side scaled with the sensor: the same share of it
    for area, fires in ((350.0, True), (450.0, False)):
        side = np.sqrt(area) * scale
        tags = _tags(_boxes_file(tmp_path / f"s{area}.h5", size, [5, 5, side, side]))
        assert tags["small_target"].all() == fires and tags["small_target"].any() == fires


def test_out_of_view_and_cut_by_image_from_truncation(tmp_path):
    trunc = [0.0, 0.0, 0.2, 0.5, 0.9, 0.49, 0.0]  # segment i ends at row i + 1
    tags = _tags(_boxes_file(tmp_path / "t.h5", (64, 48), [0, 5, 20, 20], truncation=trunc))
    assert np.flatnonzero(tags["cut_by_image"]).tolist() == [1, 2, 3, 4]
    assert np.flatnonzero(tags["out_of_view"]).tolist() == [2, 3]
    assert "occlusion" not in tags  # truncation says nothing of occluders: no visibility, no occlusion


def test_a_file_without_truncation_leaves_both_out(tmp_path):
    tags = _tags(_boxes_file(tmp_path / "n.h5", (64, 48), [0, 5, 20, 20]))
    assert "out_of_view" not in tags and "cut_by_image" not in tags


def _scene(size: tuple[int, int], camera: str, target_turn_deg: float = 0.0) -> str:
    """A cube 18 m in front of the default background plane (y = 8 m), the camera looking along +y from y = -10."""
    fx = 500.0 * size[0] / 640
    return f"""name: crafted
duration_s: 0.06
sensor: {{width: {size[0]}, height: {size[1]}, fx: {fx}}}
camera:
  interpolation: linear
  keyframes: {camera}
target:
  shape: cube
  trajectory:
    interpolation: linear
    keyframes: [{{t: 0, location: [0, 0, 0], rotation_deg: [0, 0, 0]}},
                {{t: 0.06, location: [0, 0, 0], rotation_deg: [0, {target_turn_deg * 0.06}, 0]}}]
"""


def _pan(speed_m_s: float) -> str:
    """Camera keyframes translating along x at speed_m_s, looking along +y (Blender's camera at rotation 90, 0, 0)."""
    return (f"[{{t: 0, location: [0, -10, 0], rotation_deg: [90, 0, 0]}}, "
            f"{{t: 0.06, location: [{speed_m_s * 0.06}, -10, 0], rotation_deg: [90, 0, 0]}}]")


@pytest.mark.parametrize("size", SIZES)
def test_camera_motion_is_the_backgrounds_image_motion(tmp_path, size):
    # the plane 18 m away seen with fx 500 px at 640 x 480: v m/s moves it 500 v / 18 px/s; the cut, 0.1 px/ms,
    # is 3.6 m/s; 2.5 m/s (0.07 px/ms) does not fire, 5 m/s (0.14 px/ms) does
    for speed, fires in ((5.0, True), (2.5, False)):
        path = _boxes_file(tmp_path / f"c{speed}.h5", size, [10, 10, 20, 20], scene=_scene(size, _pan(speed)))
        with Dataset(path) as ds:
            moved = segment_measures(ds)["camera"]
        assert moved == pytest.approx(np.full(N, speed * 500 / 18 / 1000), rel=0.02)
        tags = _tags(path)
        assert tags["camera_motion"].all() == fires and tags["camera_motion"].any() == fires


def test_a_moving_camera_whose_image_stands_still_is_no_camera_motion(tmp_path):
    # the old rule (camera speed over 0.1 m/s) fired here; the background moves 0.014 px/ms
    path = _boxes_file(tmp_path / "slow.h5", (640, 480), [10, 10, 20, 20], scene=_scene((640, 480), _pan(0.5)))
    assert not _tags(path)["camera_motion"].any()


@pytest.mark.parametrize("size", SIZES)
def test_rotation_is_the_projected_turn(tmp_path, size):
    still = "[{t: 0, location: [0, -10, 0], rotation_deg: [90, 0, 0]}]"
    for rate, fires in ((60.0, True), (30.0, False)):  # about the line of sight: an in-plane turn, the cut 45 deg/s
        path = _boxes_file(tmp_path / f"r{rate}.h5", size, [10, 10, 20, 20], scene=_scene(size, still, rate))
        with Dataset(path) as ds:
            m = segment_measures(ds)
        assert m["rotation"] == pytest.approx(np.full(N, rate), rel=0.01)
        assert m["camera"] == pytest.approx(np.zeros(N), abs=1e-9)
        tags = _tags(path)
        assert tags["rotation"].all() == fires and tags["rotation"].any() == fires


def test_a_turning_camera_moves_an_environment_at_infinity(tmp_path):
    # no plane: every ray sees the environment, whose image moves by fx * turn rate whatever the distance, times
    # 1 + x^2 / fx^2 at x px from the centre: the grid's median |x| is 160 px (fx 500 px: 20 deg/s is 0.19 px/ms,
    # 8 deg/s 0.08)
    for rate, fires in ((20.0, True), (8.0, False)):
        camera = (f"[{{t: 0, location: [0, -10, 0], rotation_deg: [90, 0, 0]}}, "
                  f"{{t: 0.06, location: [0, -10, 0], rotation_deg: [90, 0, {rate * 0.06}]}}]")
        scene = _scene((640, 480), camera) + "background: {kind: environment}\n"
        path = _boxes_file(tmp_path / f"e{rate}.h5", (640, 480), [10, 10, 20, 20], scene=scene)
        with Dataset(path) as ds:
            moved = segment_measures(ds)["camera"]
        assert moved == pytest.approx(np.full(N, 500 * np.radians(rate) * (1 + 0.32**2) / 1000), rel=0.02)
        assert _tags(path)["camera_motion"].all() == fires and _tags(path)["camera_motion"].any() == fires
