"""The second held-out set (blender_scenes/heldout2/) is fresh: its target classes, backdrops and motions are used by no
other scene file and by no draw of any template; its scenes check as the first held-out set's do (same sensor and
duration, test split) and pass `dvsot generate --dry-run` (no rendering)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from dvsot.cli import main
from dvsot.scene import SceneConfig, load_scene
from dvsot.scene.templates import draw_variants, read_template

SCENES = Path(__file__).resolve().parents[3] / "blender_scenes"
FRESH = sorted((SCENES / "heldout2").glob("*.yaml"))
SAME_MESH = {"sphere": "ball"}
STILL_M = 0.5  # a target whose path spans less than this (m) on every axis stands still
STEADY_M = 1.0  # a camera whose path spans less than this (m) on every axis stays put (shake aside)
DRAWS = 100  # draws of each template


def _object_class(obj) -> str:
    return Path(obj.mesh).stem if obj.mesh is not None else SAME_MESH.get(obj.shape, obj.shape)


def _texture(material) -> tuple | None:
    tex = material.texture
    if tex is None:
        return None
    return (tex.type, Path(tex.path).name) if tex.path is not None else (tex.type,)


def _path_kind(locations: np.ndarray, still: float, name: str) -> str:
    """'still' or the axis its path spans most with the sign of its net move along it: 'x+', 'y-' (towards the
    camera, which looks along +y), ..."""
    span = np.ptp(locations, axis=0)
    if span.max() < still:
        return name
    axis = int(np.argmax(span))
    return "xyz"[axis] + ("+" if locations[-1, axis] >= locations[0, axis] else "-")


def motion(cfg: SceneConfig) -> tuple[str, str]:
    """(the target's motion, the camera's) as _path_kind names them."""
    target = np.array([k.location for k in cfg.target.trajectory.keyframes], float)
    camera = np.array([k.location for k in cfg.camera.keyframes], float)
    return _path_kind(target, STILL_M, "still"), _path_kind(camera, STEADY_M, "steady")


def usage(cfg: SceneConfig) -> tuple[set, set, set]:
    """(classes of every object, textures of every surface and the backdrop, {motion}) of a scene."""
    objects = [cfg.target, *cfg.objects]
    textures = {_texture(o.material) for o in objects} | {_texture(cfg.background.material)}
    return {_object_class(o) for o in objects}, textures - {None}, {motion(cfg)}


def everything_else() -> tuple[set, set, set]:
    """What every other scene file and DRAWS draws of every template use."""
    classes, textures, motions = set(), set(), set()
    configs = []
    for p in sorted(SCENES.rglob("*.yaml")):
        if p.parent.name == "heldout2":
            continue
        if p.parent.name == "templates":
            tpl = read_template(p)
            configs += [SceneConfig.model_validate(v.scene) for v in draw_variants(tpl, DRAWS)]
        else:
            configs.append(load_scene(p))
    for cfg in configs:
        c, t, m = usage(cfg)
        classes |= c
        textures |= t
        motions |= m
    return classes, textures, motions


def test_fresh_held_out_set_shares_no_class_backdrop_or_motion_with_anything_else() -> None:
    classes, textures, motions = everything_else()
    assert {"cat", "ball", "torus", "cylinder", "plane"} <= classes and ("voronoi",) in textures  # all were read
    assert ("x+", "steady") in motions
    assert len(FRESH) == 4
    fresh_classes, fresh_backdrops = set(), set()
    for p in FRESH:
        cfg = load_scene(p)
        c, t, m = usage(cfg)
        assert not c & classes, (p.name, c & classes)
        assert not t & textures, (p.name, t & textures)
        assert not m & motions, (p.name, m)
        fresh_classes.add(_object_class(cfg.target))
        fresh_backdrops.add(_texture(cfg.background.material))
    assert len(fresh_classes) == 4 and len(fresh_backdrops) == 4  # four scenes, each its own class and backdrop


@pytest.mark.parametrize("path", FRESH, ids=lambda p: p.stem)
def test_fresh_scene_is_shaped_like_the_first_held_out_set_and_dry_runs(path: Path, capsys) -> None:
    first = [load_scene(p) for p in sorted((SCENES / "heldout").glob("*.yaml"))]
    cfg = load_scene(path)
    assert {(c.sensor.width, c.sensor.height, c.duration_s) for c in first} == {(cfg.sensor.width, cfg.sensor.height,
                                                                                  cfg.duration_s)}
    assert cfg.split == "test" and cfg.name == path.stem
    assert main(["generate", str(path), "--dry-run"]) == 0
    out = capsys.readouterr()
    assert cfg.name in out.out and out.err == ""
