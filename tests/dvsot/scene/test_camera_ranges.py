"""A scene's camera is refused where Blender would change it (lens and sensor sizes below 1 mm are clamped to 1 mm,
and the ground-truth boxes would no longer fit the render), and kept exactly where it is accepted."""

import pytest

from dvsot.cli import main
from dvsot.scene import parse_scene
from dvsot.scene.schema import CAMERA_MM

SCENE = """name: lens
duration_s: 0.2
sensor: {{width: 160, height: 120, {lens}}}
camera:
  keyframes: [{{t: 0, location: [0, -10, 0], look_at: [0, 0, 0]}}]
target:
  shape: cube
  size_m: 1.5
  trajectory:
    keyframes: [{{t: 0, location: [0, 0, 0]}}]
render: {{threads: 1}}
"""


@pytest.mark.parametrize("lens, words", [
    ("focal_mm: 0.5", ["sensor.focal_mm", "between 1 and", "mm", "got 0.5"]),
    ("focal_mm: 0.999", ["sensor.focal_mm", "between 1 and", "got 0.999"]),
    ("focal_mm: 1e39", ["sensor.focal_mm", "between 1 and 3.403e+38 mm"]),
    ("focal_mm: 0", ["sensor.focal_mm", "between 1 and"]),
    ("sensor_width_mm: 0.5", ["sensor.sensor_width_mm", "between 1 and", "got 0.5"]),
    ("focal_mm: 4, sensor_width_mm: 0.9", ["sensor.sensor_width_mm", "got 0.9"]),
    ("fx: 3", ["'sensor'", "fx must be between 4.444", "px", "sensor_width_mm 36", "got 3"]),
    ("fx: 30, sensor_width_mm: 2", ["'sensor'", "fx must be between 80 and", "got 30"]),
    ("fx: 100, cy: -1e39", ["sensor.cy", "between -3.403e+38 and 3.403e+38 px", "got -1e+39"]),
])
def test_a_camera_blender_would_clamp_is_refused_naming_the_field_and_range(tmp_path, capsys, lens, words):
    scene = tmp_path / "s.yaml"
    scene.write_text(SCENE.format(lens=lens))
    assert main(["generate", str(scene), "-o", str(tmp_path / "o.h5"), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and all(w in err[0] for w in ["s.yaml", *words]), err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.yaml"]


@pytest.mark.parametrize("lens, expected_mm", [("focal_mm: 1, sensor_width_mm: 1", 1.0), ("focal_mm: 35", 35.0),
                                                ("fx: 4.45", 4.45 * 36 / 160), ("fx: 80, sensor_width_mm: 2", 1.0)])
def test_an_accepted_camera_gives_the_lens_it_states(lens, expected_mm):
    sensor = parse_scene(SCENE.format(lens=lens)).sensor
    assert sensor.lens_mm() == pytest.approx(expected_mm, rel=1e-12)
    assert CAMERA_MM[0] <= sensor.lens_mm() and CAMERA_MM[0] <= sensor.sensor_width_mm


@pytest.mark.blender
def test_blender_keeps_the_smallest_accepted_camera_as_given():
    """Blender's camera holds the lens and sensor size the schema accepted at its lower bound (nothing clamped)."""
    from dvsot.render.blender import BlenderScene

    cfg = parse_scene(SCENE.format(lens="focal_mm: 1, sensor_width_mm: 1"))
    with BlenderScene(cfg) as sc:
        cam = sc.camera.data
        assert (cam.lens, cam.sensor_width, cam.sensor_height) == (1.0, 1.0, 1.0)
    cfg = parse_scene(SCENE.format(lens="fx: 80, sensor_width_mm: 2"))
    with BlenderScene(cfg) as sc:
        assert sc.camera.data.lens == pytest.approx(1.0, rel=1e-6) and sc.camera.data.sensor_width == 2.0
