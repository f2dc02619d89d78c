"""Scenes that validate but make no sense: refused with the field and line, or warned
about before anything is rendered (no Blender here: an output in a missing directory stops the run after)."""

from __future__ import annotations

import pytest
from synthetic import MINIMAL_SCENE

from dvsot.cli import main

CAMERA = "keyframes: [{t: 0, location: [0, -10, 0], look_at: [0, 0, 0]}]"
TARGET = "keyframes: [{t: 0, location: [0, 0, 0]}]"


@pytest.mark.parametrize("old, new, field, words", [
    (CAMERA, "keyframes: [{t: 0, location: [0, -10, 0], look_at: [0, -10, 0]}]", "camera.keyframes.0.look_at",
     "own location"),
    # the camera passes through the point it looks at half-way (no keyframe says so)
    (CAMERA, "interpolation: linear\n  keyframes: [{t: 0, location: [0, -10, 0], look_at: [0, -9, 0]}, "
             "{t: 0.1, location: [0, -8, 0], look_at: [0, -9, 0]}]", "camera", "at t = 0.05 s"),
    (TARGET, "keyframes: [{t: 0, location: [0, 0, 0], scale: 0}]", "target.trajectory.keyframes.0.scale",
     "greater than or equal to 0.001"),
    (TARGET, "keyframes: [{t: 0, location: [0, 0, 0], scale: 1e30}]", "target.trajectory.keyframes.0.scale",
     "less than or equal to 1000"),
    (TARGET, "keyframes: [{t: 0, location: [0, 0, 0], scale: [1, -1, 1]}]", "target.trajectory.keyframes.0.scale.1",
     "greater than or equal to 0.001"),
    ("shape: cube", "shape: cube\n  size_m: 1.0e+30", "target.size_m", "less than or equal to 10000"),
    (TARGET, "keyframes: [{t: 0, location: [1.0e+30, 0, 0]}]", "target.trajectory.keyframes.0.location.0",
     "less than or equal to 1000000"),
    ("duration_s: 0.1", "duration_s: 0.1\nsegment_ms: 200", "segment_ms", "no segment"),
])
def test_nonsense_is_refused_naming_field_and_line(tmp_path, capsys, old, new, field, words):
    scene = tmp_path / "s.yaml"
    scene.write_text(MINIMAL_SCENE.replace(old, new))
    assert main(["generate", str(scene), "-o", str(tmp_path / "o.h5")]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and f"field '{field}'" in err and words in err and f"{scene}:" in err, err


@pytest.mark.parametrize("old, new, words", [
    (TARGET, "keyframes: [{t: 0, location: [0, -20, 0]}]", "never in view"),  # behind the camera
    (TARGET, "keyframes: [{t: 0, location: [40, 0, 0]}, {t: 0.1, location: [60, 0, 0]}]", "never in view"),
    ("shape: cube", "shape: cube\n  size_m: 0.00001", "never in view"),  # under a pixel
    (TARGET, "keyframes: [{t: 0, location: [0, 0, 0], scale: 500}]", "fills the whole frame"),  # camera inside
    ("shape: cube", "shape: cube\n  size_m: 19", "fills the whole frame"),  # just in front of the lens
])
def test_a_target_never_seen_or_always_filling_the_frame_is_warned_about(tmp_path, capsys, old, new, words):
    scene = tmp_path / "s.yaml"
    scene.write_text(MINIMAL_SCENE.replace(old, new))
    assert main(["generate", str(scene), "-o", str(tmp_path / "missing" / "o.h5")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and "warning" in err[0] and str(scene) in err[0] and words in err[0], err


def test_an_ordinary_scene_gets_no_warning(tmp_path, capsys):
    scene = tmp_path / "s.yaml"
    scene.write_text(MINIMAL_SCENE)
    assert main(["generate", str(scene), "-o", str(tmp_path / "missing" / "o.h5")]) == 2
    assert "warning" not in capsys.readouterr().err
