"""Tiny real Blender renders (64x48): static scenes give no events, moving targets give events in their box."""

import json

import numpy as np
import pytest

from dvsot.cli import main
from dvsot.config import parse_scene
from dvsot.dataset import Dataset
from dvsot.trajectory import pose_matrix, project

pytestmark = pytest.mark.blender

SCENE = """name: tiny
duration_s: {duration}
sensor: {{width: 64, height: 48, focal_mm: 35}}
camera:
  keyframes: [{{t: 0, location: [0, -10, 0], look_at: [0, 0, 0]}}]
  shake_deg: {shake}
target:
  shape: cube
  size_m: 1.5
  material: {{color: [0.9, 0.9, 0.9]}}
  trajectory:
    interpolation: linear
    keyframes: [{{t: 0, location: [{x0}, 0, 0]}}, {{t: {duration}, location: [{x1}, 0, 0]}}]
background:
  material: {{color: [0.1, 0.1, 0.1], texture: {texture}, emission: 0.3}}
lights: []
world: {{color: [0.5, 0.5, 0.5], strength: 1.0}}
render: {{threads: 2}}
sampling: {{min_rate_hz: 200}}
"""


def scene(tmp_path, name="s", duration=0.04, x0=0.0, x1=0.0, shake=0.0, texture="{type: noise, scale: 20}"):
    p = tmp_path / f"{name}.yaml"
    p.write_text(SCENE.format(duration=duration, x0=x0, x1=x1, shake=shake, texture=texture))
    return p


def test_static_scene_gives_no_signal_events(tmp_path):
    out = tmp_path / "static.h5"
    assert main(["generate", str(scene(tmp_path)), "-o", str(out), "--quiet"]) == 0
    with Dataset(out) as ds:
        assert ds.num_events == 0
        track = ds.boxes()
        assert len(track.t) >= 8  # min rate 200 Hz over 40 ms
        assert np.all(track.xywh == track.xywh[0]) and not np.isnan(track.xywh[0]).any()


def test_moving_target_events_lie_in_its_box_which_follows_the_trajectory(tmp_path, capsys):
    path = scene(tmp_path, "move", duration=0.06, x0=-1.5, x1=1.5, texture="null")
    out = tmp_path / "move.h5"
    assert main(["generate", str(path), "-o", str(out), "--quiet"]) == 0
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert summary["frames"] < summary["frames_at_fixed_1kHz"] or summary["frames"] > 0
    cfg = parse_scene(path.read_text())
    k = cfg.sensor.intrinsics()
    with Dataset(out) as ds:
        ev = ds.events(0, ds.duration_us)
        assert ds.num_events > 200
        track = ds.boxes()
        # box centre follows the projected target centre
        for t_us, box in zip(track.t[::5], track.xywh[::5]):
            centre = project(np.array([[-1.5 + 3.0 * t_us / 60_000, 0, 0]]), pose_matrix(cfg.camera, t_us / 1e6), k)[0]
            np.testing.assert_allclose(box[:2] + box[2:] / 2, centre, atol=1.5)
        # events are concentrated inside the (slightly dilated) box of their time
        boxes = track.xywh[np.clip(np.searchsorted(track.t, ev.t), 0, len(track.t) - 1)]
        inside = ((ev.x >= boxes[:, 0] - 2) & (ev.x <= boxes[:, 0] + boxes[:, 2] + 2)
                  & (ev.y >= boxes[:, 1] - 2) & (ev.y <= boxes[:, 1] + boxes[:, 3] + 2))
        # the rest: Monte-Carlo noise of light bouncing off the moving cube onto the wall (1 sample)
        assert inside.mean() > 0.9
        assert np.all(np.diff(ds.segment_boxes()[:, 0]) > 0)  # moving right


def test_generate_bad_input_exits_2_and_writes_nothing(tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    bad.write_text(scene(tmp_path).read_text().replace("shape: cube", "shape: cube\n  colour: red"))
    out = tmp_path / "o.h5"
    assert main(["generate", str(bad), "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "unknown field" in err[0] and "bad.yaml" in err[0]
    assert main(["generate", str(scene(tmp_path)), "-o", str(out), "--resolution", "big"]) == 2
    assert main(["generate", str(scene(tmp_path)), "-o", str(tmp_path / "nodir" / "o.h5")]) == 2
    assert not out.exists() and not (tmp_path / "nodir").exists()


def test_direct_shading_gives_the_closed_form_lambert_radiance(tmp_path):
    from dvsot.blender import BlenderScene

    text = SCENE.format(duration=0.02, x0=100.0, x1=100.0, shake=0.0, texture="null")
    text = text.replace("texture: null, emission: 0.3", "texture: null").replace("[0.1, 0.1, 0.1], texture", "[0.5, 0.4, 0.2], texture")
    text = text.replace("lights: []", "lights: [{type: sun, strength: 2.0, rotation_deg: [60, 0, 0]}]")
    text = text.replace("world: {color: [0.5, 0.5, 0.5], strength: 1.0}", "world: {color: [0.1, 0.1, 0.1], strength: 1.0}")
    cfg = parse_scene(text.replace("render: {threads: 2}", "render: {threads: 2, shading: direct}"))
    with BlenderScene(cfg) as sc:
        luma, amodal, _ = sc.render(0.0)
    # the wall faces the camera (normal -y); the sun at 60 deg about x lies along (0, -sin 60, cos 60)
    irradiance = 2.0 * np.sin(np.radians(60)) / np.pi + 0.1
    expected = float(np.array([0.5, 0.4, 0.2]) @ [0.2126, 0.7152, 0.0722]) * irradiance
    assert not amodal.any()
    np.testing.assert_allclose(luma, expected, rtol=1e-3)


def test_direct_shading_refuses_point_and_area_lights():
    from dvsot.errors import UserError

    text = SCENE.format(duration=0.02, x0=0.0, x1=0.0, shake=0.0, texture="null")
    text = text.replace("lights: []", "lights: [{type: point, strength: 100}]")
    with pytest.raises(UserError, match=r"lights\[0\]\.type"):
        parse_scene(text.replace("render: {threads: 2}", "render: {threads: 2, shading: direct}"))
    parse_scene(text)  # path shading takes any light
