"""Scene templates: draws reproducible from the master seed and within bounds, bad distributions one line, exit 2."""

from pathlib import Path

import numpy as np
import pytest

from dvsot.cli import main
from dvsot.scene import SceneConfig, read_yaml
from dvsot.scene.random_walk import RandomWalk, random_walk
from dvsot.scene.templates import draw_variants, read_template, validate_variant, variant_seed

ROOT = Path(__file__).resolve().parents[3]

TEMPLATE = """name: rnd
seed: 11
duration_s: {uniform: [0.5, 1.0]}
sensor: {width: 80, height: 60, focal_mm: {normal: [35, 3], clip: [30, 38]}}
camera:
  keyframes: [{t: 0, location: [0, -10, 0], look_at: [0, 0, 0]}]
  shake_deg: {normal: [0.3, 0.1]}
target:
  shape: {choice: [cube, star, cat], weights: [1, 1, 2]}
  size_m: {uniform: [0.8, 1.6]}
  material: {color: {uniform: [[0.2, 0.2, 0.2], [1, 0.5, 0.5]]}}
  trajectory:
    interpolation: linear
    random_walk: {start: [{uniform: [-1, 1]}, 0, 0], speed_mps: [1, 2], turn_deg_s: 60, step_s: 0.1,
                  bounds: [[-3, 0, -2], [3, 0, 2]]}
objects:
  - count: {uniform: [0, 3]}
    each:
      role: occluder
      shape: {choice: [sphere, torus]}
      trajectory: {keyframes: [{t: 0, location: [{uniform: [-2, 2]}, -1, 0]}]}
background:
  material: {texture: {choice: [{type: noise, scale: {uniform: [5, 20]}}, {type: checker}]}}
events: {cp: {uniform: [0.2, 0.3]}}
"""


def write(tmp_path, text=TEMPLATE, name="tpl.yaml"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_draws_are_reproducible_per_variant_and_within_bounds(tmp_path):
    tpl = read_template(write(tmp_path))
    a, b = draw_variants(tpl, 40), draw_variants(read_template(write(tmp_path)), 40)
    assert [v.scene for v in a] == [v.scene for v in b]
    assert draw_variants(tpl, 1, first=17)[0].scene == a[17].scene  # variant 17 alone is variant 17
    assert a[3].seed == variant_seed(11, 3) and a[3].scene["seed"] == a[3].seed and a[3].name == "rnd_00003"
    assert len({v.seed for v in a}) == 40
    d = {k: np.array([v.drawn.get(k, np.nan) for v in a], dtype=object) for k in a[0].drawn}
    assert all(0.5 <= v.scene["duration_s"] <= 1.0 for v in a)
    assert all(30 <= v.scene["sensor"]["focal_mm"] <= 38 for v in a)
    assert any(v.scene["sensor"]["focal_mm"] in (30, 38) for v in a)  # the clip bites at sigma 3
    shake = np.array([v.scene["camera"]["shake_deg"] for v in a])
    assert abs(shake.mean() - 0.3) < 0.06 and 0.05 < shake.std() < 0.16
    shapes = [v.scene["target"]["shape"] for v in a]
    assert set(shapes) <= {"cube", "star", "cat"} and shapes.count("cat") > 10
    colours = np.array([v.scene["target"]["material"]["color"] for v in a])
    assert np.all(colours >= [0.2, 0.2, 0.2]) and np.all(colours <= [1, 0.5, 0.5]) and colours.std(0).min() > 0.05
    counts = [len(v.scene["objects"]) for v in a]
    assert set(counts) == {0, 1, 2, 3} and all(o["shape"] in ("sphere", "torus") for v in a for o in v.scene["objects"])
    assert [v.drawn["objects.count@0"] for v in a] == counts
    assert all(-2 <= o["trajectory"]["keyframes"][0]["location"][0] <= 2 for v in a for o in v.scene["objects"])
    kinds = {v.scene["background"]["material"]["texture"]["type"] for v in a}
    assert kinds == {"noise", "checker"}
    assert all(0.2 <= v.scene["events"]["cp"] <= 0.3 for v in a)
    assert "target.size_m" in d and all(0.8 <= x <= 1.6 for x in d["target.size_m"])
    for v in a:  # every drawn scene is a valid scene, and its text reads back as the same scene
        validate_variant(tpl, v)
        data, _ = read_yaml(v.text("tpl.yaml"))
        assert data == v.scene
        keys = v.scene["target"]["trajectory"]["keyframes"]
        assert keys[-1]["t"] == v.scene["duration_s"]
        pos = np.array([k["location"] for k in keys])
        assert np.all(pos[:, 0] >= -3) and np.all(pos[:, 0] <= 3) and np.all(np.abs(pos[:, 2]) <= 2)
        assert np.all(pos[:, 1] == 0)  # the walk stays in the x-z plane


def test_random_walk_speed_and_turn_rate_within_bounds():
    walk = RandomWalk(start=(0, 0, 0), speed_mps=(1.0, 2.0), turn_deg_s=45, step_s=0.05)
    times, pos = random_walk(walk, 3.0, np.random.default_rng(0))
    assert times[0] == 0 and times[-1] == 3.0 and np.all(np.diff(times) > 0)
    step = np.diff(pos[:, [0, 2]], axis=0)
    speed = np.linalg.norm(step, axis=1) / np.diff(times)
    assert np.all(speed >= 1.0 - 1e-9) and np.all(speed <= 2.0 + 1e-9) and speed.std() > 0.1
    heading = np.unwrap(np.arctan2(step[:, 1], step[:, 0]))
    turn = np.degrees(np.abs(np.diff(heading))) / np.diff(times)[1:]
    assert np.all(turn <= 45 + 1e-6) and turn.max() > 20
    again = random_walk(walk, 3.0, np.random.default_rng(0))[1]
    np.testing.assert_array_equal(pos, again)


def test_shipped_template_draws_valid_dvsot21_like_scenes(tmp_path, capsys):
    path = ROOT / "blender_scenes" / "templates" / "dvsot21_random.yaml"
    tpl = read_template(path)
    for v in draw_variants(tpl, 5):
        cfg = validate_variant(tpl, v)
        assert isinstance(cfg, SceneConfig) and (cfg.sensor.width, cfg.sensor.height) == (640, 480)
        assert cfg.split == "train"
    assert main(["generate", str(path), "--variants", "2", "--dry-run", "--out-dir", str(tmp_path / "o")]) == 0
    out = capsys.readouterr().out
    assert "name: dvsot21_random_00000" in out and "name: dvsot21_random_00001" in out
    assert not (tmp_path / "o").exists()  # a dry run writes nothing


@pytest.mark.parametrize("old, new, words", [
    ("size_m: {uniform: [0.8, 1.6]}", "size_m: {uniform: [2, 1]}",
     ":10: field 'target.size_m.uniform': uniform needs lo <= hi, got [2, 1]"),
    ("size_m: {uniform: [0.8, 1.6]}", "size_m: {unifrom: [0.8, 1.6]}",
     ":10: field 'target.size_m': unknown distribution 'unifrom' (uniform, normal or choice)"),
    ("[cube, star, cat], weights: [1, 1, 2]", "[cube, dragon, cat]",
     ":9: field 'target.shape': Input should be 'cube', 'sphere'"),  # and it ends "(when target.shape is 'dragon')"
    ("{choice: [sphere, torus]}", "{choice: [sphere, torso]}", ":20: field 'objects.0.shape': Input should be"),
    ("shake_deg: {normal: [0.3, 0.1]}", "shake_deg: {normal: [0.3, -1]}",
     ":7: field 'camera.shake_deg.normal': normal needs sigma >= 0"),
    ("weights: [1, 1, 2]", "weights: [1, 1]", ":9: field 'target.shape.weights': weights must be 3 numbers"),
    ("count: {uniform: [0, 3]}", "count: {normal: [1, 1]}", ":17: field 'objects.0.count.normal': a count is drawn"),
    ("size_m: {uniform: [0.8, 1.6]}", "size_m: {uniform: [0, 1.6]}",
     ":10: field 'target.size_m': Input should be greater than 0 (when target.size_m is its lo 0)"),
    ("speed_mps: [1, 2]", "speed_mps: [2, 1]", ":14: field 'target.trajectory.random_walk': speed_mps needs"),
    ("seed: 11", "seed: {uniform: [0, 9]}", ":2: field 'seed': the template's seed is a whole number, not drawn"),
])
def test_bad_distribution_is_one_line_with_file_line_and_field(tmp_path, capsys, old, new, words):
    assert old in TEMPLATE
    path = write(tmp_path, TEMPLATE.replace(old, new))
    out = tmp_path / "out"
    assert main(["generate", str(path), "--variants", "3", "--out-dir", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"{path}{words}" in err[0], err
    assert not out.exists()


def test_a_template_without_variants_says_so(tmp_path, capsys):
    path = write(tmp_path)
    assert main(["generate", str(path), "-o", str(tmp_path / "x.h5")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"{path}: a scene template" in err[0] and "--variants N" in err[0], err
