"""The validation template draws scenes apart from the test split and the held-out scenes: no target class and no
backdrop of either (a sphere counts as a ball: the same mesh)."""

from __future__ import annotations

from pathlib import Path

from dvsot.scene import load_scene
from dvsot.scene.templates import check_template, draw_variants, read_template, validate_variant

SCENES = Path(__file__).resolve().parents[3] / "blender_scenes"
SAME_MESH = {"sphere": "ball"}


def _classes_and_backdrops(paths) -> tuple[set, set]:
    shapes, backdrops = set(), set()
    for path in paths:
        cfg = load_scene(path)
        shapes.add(SAME_MESH.get(cfg.target.shape, cfg.target.shape))
        if cfg.background is not None and cfg.background.material.texture is not None:
            backdrops.add(cfg.background.material.texture.type)
    return shapes, backdrops


def test_validation_scenes_share_no_class_or_backdrop_with_test_or_heldout() -> None:
    test = [p for p in SCENES.glob("*.yaml") if load_scene(p).split == "test"]
    t_shapes, t_backs = _classes_and_backdrops(test)
    h_shapes, h_backs = _classes_and_backdrops(sorted((SCENES / "heldout").glob("*.yaml")))
    assert {"cat", "ball", "torus"} <= t_shapes | h_shapes and {"sea", "voronoi"} <= t_backs | h_backs
    tpl = read_template(SCENES / "templates" / "dvsot21_validation.yaml")
    check_template(tpl)
    seen_shapes, seen_backs = set(), set()
    for v in draw_variants(tpl, 40):
        cfg = validate_variant(tpl, v)
        assert cfg.split not in ("train", "test")
        seen_shapes.add(SAME_MESH.get(cfg.target.shape, cfg.target.shape))
        seen_backs.add(cfg.background.material.texture.type)
    assert not seen_shapes & (t_shapes | h_shapes), seen_shapes & (t_shapes | h_shapes)
    assert not seen_backs & (t_backs | h_backs), seen_backs & (t_backs | h_backs)
    assert len(seen_shapes) >= 2 and len(seen_backs) >= 4
