"""The varied training template keeps out what is read to choose or to score, over many draws (no rendering): no
target or distractor class of any held-out scene or of the validation template, and no pairing of target class and
backdrop that a test-split scene has (a sphere counts as a ball: the same mesh)."""

from __future__ import annotations

from pathlib import Path

from dvsot.scene import load_scene
from dvsot.scene.templates import draw_variants, read_template, validate_variant

SCENES = Path(__file__).resolve().parents[3] / "blender_scenes"
SAME_MESH = {"sphere": "ball"}
DRAWS = 500


def _cls(shape: str | None) -> str | None:
    return SAME_MESH.get(shape, shape)


def _backdrop(scene: dict) -> str | None:
    texture = ((scene.get("background") or {}).get("material") or {}).get("texture") or {}
    return texture.get("type")


def _distractors(scene: dict) -> set:
    return {_cls(o.get("shape")) for o in scene.get("objects") or [] if o.get("role") == "distractor"}


def held_out_classes() -> set:
    """Target classes of every held-out set (blender_scenes/heldout*/)."""
    return {_cls(load_scene(p).target.shape) for d in SCENES.glob("heldout*") for p in d.glob("*.yaml")}


def validation_classes() -> set:
    """Target classes the validation template draws."""
    tpl = read_template(SCENES / "templates" / "dvsot21_validation.yaml")
    return {_cls(v.scene["target"]["shape"]) for v in draw_variants(tpl, 100)}


def split_pairings() -> set:
    """(target class, backdrop) of every test-split scene file of blender_scenes/."""
    pairs = set()
    for p in SCENES.glob("*.yaml"):
        cfg = load_scene(p)
        if cfg.split == "test":
            pairs.add((_cls(cfg.target.shape), cfg.background.material.texture.type))
    return pairs


def test_varied_template_excludes_held_out_and_validation_classes_and_test_pairings() -> None:
    held, val, pairs = held_out_classes(), validation_classes(), split_pairings()
    assert {"cat", "ball", "torus"} <= held and {"cylinder", "plane"} <= val  # the sets are read, not empty
    assert {("bottle", "window"), ("cat", "sea"), ("cube", "galaxy")} <= pairs
    tpl = read_template(SCENES / "templates" / "dvsot21_varied.yaml")
    targets, backdrops = set(), set()
    for v in draw_variants(tpl, DRAWS):
        target, backdrop = _cls(v.scene["target"]["shape"]), _backdrop(v.scene)
        assert target not in held | val, (v.index, target)
        assert not _distractors(v.scene) & (held | val), (v.index, _distractors(v.scene))
        assert (target, backdrop) not in pairs, (v.index, target, backdrop)
        targets.add(target)
        backdrops.add(backdrop)
    assert len(targets) >= 3 and len(backdrops) >= 5  # still varied
    for v in draw_variants(tpl, 3):  # and the drawn scenes are valid scenes of the training split
        assert validate_variant(tpl, v).split == "train"
