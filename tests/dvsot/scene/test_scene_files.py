"""Scene schema: shipped scenes load; each kind of bad file gives one clean line naming file, field and line."""

from pathlib import Path

import pytest
from synthetic import MINIMAL_SCENE

from dvsot.core.errors import UserError
from dvsot.scene import load_scene

SCENES = sorted(Path(__file__).resolve().parents[3].joinpath("blender_scenes").glob("*.yaml"))
GOOD = MINIMAL_SCENE


def test_every_shipped_scene_loads_with_its_split():
    names = {load_scene(p).name: load_scene(p).split for p in SCENES}
    assert {k for k, v in names.items() if v == "train"} == {"woman_cat", "trees_bottle", "trees_star", "woman_cube"}
    assert {k for k, v in names.items() if v == "test"} >= {"city_cat", "city_bottle", "city_star", "sky_cube",
                                                           "woman_ball"}


def write(tmp_path, text, name="s.yaml"):
    p = tmp_path / name
    p.write_text(text)
    return p


@pytest.mark.parametrize(
    "text, words",
    [
        (GOOD + "  colour: red\n", ":9: field 'target.colour': unknown field"),
        (
            GOOD.replace("duration_s: 0.1", "duration_s: -1"),
            ":2: field 'duration_s': Input should be greater than or equal to 0.001",
        ),
        (GOOD.replace("duration_s: 0.1", "duration_s: soon"), "field 'duration_s'"),
        (GOOD + "events: {cp: -0.2}\n", "field 'events.cp'"),
        (GOOD + "events: {colour: 1}\n", "field 'events.colour': unknown field"),
        (GOOD + "events: {cp: .inf}\n", ":9: field 'events.cp': Input should be a finite number"),
        (GOOD + "render: {surface: phong}\n", "field 'render.surface'"),
        (GOOD + "render: {bake_background: sometimes}\n", "field 'render.bake_background'"),
        (GOOD + "render: {bake_texels_per_px: 0}\n", "field 'render.bake_texels_per_px'"),
        (GOOD + "render: {bake_max_size: 32}\n", "field 'render.bake_max_size'"),
        (GOOD.replace("shape: cube", "shape: dodecahedron"), "field 'target.shape'"),
        (GOOD.replace("shape: cube", "mesh: missing.obj"), "file not found"),
        (GOOD + "sampling: {min_rate_hz: 500, max_rate_hz: 100}\n", "max_rate_hz must be >= min_rate_hz"),
        (
            GOOD + "sampling: {max_rate_hz: 2.0e6}\n",
            "field 'sampling.max_rate_hz': Input should be less than or equal to",
        ),
        (
            GOOD.replace("[{t: 0, location: [0, 0, 0]}]", "[{t: 0.5, location: [0, 0, 0]}, {t: 0.1}]"),
            "keyframe times must increase",
        ),
        ("name: t\n  bad: [\n", "YAML syntax error"),
        (GOOD + "seed: 1\nseed: 2\n", ":10: field 'seed' is given twice (first on line 9)"),
        (GOOD + "seed: true\n", ":9: field 'seed': Input should be a valid integer"),
        (GOOD + "seed: 99999999999999999999999\n", ":9: field 'seed': Input should be less than or equal to"),
        (
            GOOD.replace("duration_s: 0.1", "duration_s: 1.0e-9"),
            ":2: field 'duration_s': Input should be greater than or equal to 0.001",
        ),
        (GOOD + "sensor: {width: 64.0}\n", "field 'sensor.width': Input should be a valid integer"),
        (
            GOOD.replace("shape: cube", "shape: cube\n  size_m: '1.6'"),
            "field 'target.size_m': Input should be a valid number",
        ),
        (
            GOOD.replace("location: [0, 0, 0]}]\n", "location: [.nan, 0, 0]}]\n"),
            "field 'target.trajectory.keyframes.0.location.0': Input should be a finite number",
        ),
        (
            GOOD + "world: {color: [-1, 0.5, 0.5]}\n",
            "field 'world.color.0': Input should be greater than or equal to 0",
        ),
        (GOOD + "lights: [{strength: .inf}]\n", "field 'lights.0.strength': Input should be a finite number"),
        ("- just\n- a list\n", "must be a mapping"),
    ],
)
def test_bad_scene_files(tmp_path, text, words):
    p = write(tmp_path, text)
    with pytest.raises(UserError) as info:
        load_scene(p)
    msg = str(info.value)
    assert msg.startswith(str(p)) and words in msg and "\n" not in msg


def test_render_defaults_are_the_lean_surface_with_the_automatic_bake(tmp_path):
    r = load_scene(write(tmp_path, GOOD)).render
    assert (r.surface, r.bake_background, r.bake_texels_per_px, r.bake_max_size, r.bake_samples) == (
        "lean", "auto", 2.0, 4096, 1)
    r = load_scene(write(tmp_path, GOOD + "render: {surface: principled, bake_background: false}\n")).render
    assert r.surface == "principled" and r.bake_background is False
    assert load_scene(write(tmp_path, GOOD + "render: {bake_background: true}\n")).render.bake_background is True


def test_missing_file_and_overrides(tmp_path):
    with pytest.raises(UserError, match="no such scene file"):
        load_scene(tmp_path / "nope.yaml")
    cfg = load_scene(write(tmp_path, GOOD), {"duration_s": 0.5, "sensor.width": 64, "sensor.height": 48})
    assert cfg.duration_s == 0.5 and (cfg.sensor.width, cfg.sensor.height) == (64, 48)


def test_mesh_file_resolves_relative_to_the_scene(tmp_path):
    (tmp_path / "tri.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    cfg = load_scene(write(tmp_path, GOOD.replace("shape: cube", "mesh: tri.obj")))
    assert cfg.target.mesh == (tmp_path / "tri.obj").resolve()
    from dvsot.scene.shapes import mesh_for

    v, f = mesh_for(None, cfg.target.mesh)
    assert len(v) == 3 and f == [[0, 1, 2]]
    (tmp_path / "bad.obj").write_text("this is not a mesh\n")
    with pytest.raises(UserError, match="bad.obj"):
        mesh_for(None, tmp_path / "bad.obj")


def test_an_override_is_blamed_on_the_command_line_not_the_file(tmp_path):
    p = write(tmp_path, GOOD + "sensor: 320\n")
    with pytest.raises(UserError, match=r"s.yaml:9: field 'sensor' must be a mapping \(to set sensor.width from the"):
        load_scene(p, {"sensor.width": 64})
    p = write(tmp_path, GOOD)
    with pytest.raises(
        UserError, match=r"s.yaml: field 'sensor.width' = 4 \(an override\): .*greater than or equal to 8"
    ):
        load_scene(p, {"sensor.width": 4})
    with pytest.raises(UserError, match=r"field 'duration_s' = nan \(an override\): Input should be a finite number"):
        load_scene(p, {"duration_s": float("nan")})


@pytest.mark.parametrize("name, content, words", [
    ("m.obj", b"this is no mesh\n", "mesh file holds no triangles"),
    ("m.ply", b"ply\nformat binary_little_endian 1.0\nelement vertex 9\n", "cannot read mesh"),
    ("m.stl", b"", "mesh file holds no triangles"),
])
def test_an_unreadable_mesh_names_the_scene_file_and_field(tmp_path, name, content, words):
    (tmp_path / name).write_bytes(content)
    p = write(tmp_path, GOOD.replace("shape: cube", f"mesh: {name}"))
    with pytest.raises(UserError) as info:
        load_scene(p)
    msg = str(info.value)
    assert msg.startswith(f"{p}:6: field 'target.mesh': {tmp_path / name}: ") and words in msg


def test_an_unreadable_image_texture_names_the_scene_file_and_field(tmp_path):
    import cv2
    import numpy as np

    cv2.imwrite(str(tmp_path / "good.png"), np.full((8, 8, 3), 128, np.uint8))
    (tmp_path / "bad.png").write_bytes(b"\x89PNG\r\n\x1a\n" + b"\xff" * 64)
    text = GOOD + "background:\n  material: {texture: {type: image, path: %s}}\n"
    assert load_scene(write(tmp_path, text % "good.png")).background.material.texture.path == tmp_path / "good.png"
    p = write(tmp_path, text % "bad.png")
    with pytest.raises(
        UserError, match=r"s.yaml:10: field 'background.material.texture.path': .*bad.png: cannot read image"
    ):
        load_scene(p)
