"""`dvsot generate --masks/--no-masks` reaches generate() for one scene and on the many-scene path, resume tells a file
without masks from one with them, and a real render with --no-masks keeps no /masks/objects."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from dvsot.cli import main

SCENE = """name: {name}
duration_s: 0.02
sensor: {{width: 16, height: 12, focal_mm: 35}}
camera: {{keyframes: [{{t: 0, location: [0, -10, 0], look_at: [0, 0, 0]}}]}}
target:
  shape: cube
  size_m: 1.5
  trajectory: {{interpolation: linear, keyframes: [{{t: 0, location: [-1, 0, 0]}}, {{t: 0.02, location: [1, 0, 0]}}]}}
background: {{material: {{color: [0.1, 0.1, 0.1], emission: 0.3}}}}
lights: []
world: {{color: [0.5, 0.5, 0.5], strength: 1.0}}
render: {{threads: 2}}
sampling: {{min_rate_hz: 200}}
"""


def scenes(tmp_path: Path, *names: str) -> list[str]:
    out = []
    for name in names:
        p = tmp_path / f"{name}.yaml"
        p.write_text(SCENE.format(name=name))
        out.append(str(p))
    return out


@pytest.fixture
def asked(monkeypatch) -> list:
    """generate() replaced by one that records the masks each scene asked for (nothing rendered)."""
    import dvsot.pipeline.generate as gen

    calls = []

    def fake(cfg, out_path, scene_text="", progress=True, keep_frames=None, preview=False, labels=True, masks=None):
        calls.append((cfg.name, masks))
        Path(out_path).write_bytes(b"")
        return {"name": cfg.name, "output": str(out_path)}

    monkeypatch.setattr(gen, "generate", fake)
    return calls


@pytest.mark.parametrize("flags, want", [([], None), (["--masks"], True), (["--no-masks"], False)])
def test_the_flag_reaches_generate_for_one_scene_and_for_many(tmp_path, asked, capsys, flags, want):
    (one,) = scenes(tmp_path, "one")
    assert main(["generate", one, "-o", str(tmp_path / "one.h5"), "--quiet", *flags]) == 0
    many = scenes(tmp_path, "a", "b")
    assert main(["generate", *many, "--out-dir", str(tmp_path / "many"), "--quiet", *flags]) == 0
    assert sorted(asked) == [("a", want), ("b", want), ("one", want)]
    capsys.readouterr()


def test_generate_variants_takes_masks(tmp_path, asked):
    import dvsot

    (tpl,) = scenes(tmp_path, "tpl")
    Path(tpl).write_text(Path(tpl).read_text().replace("size_m: 1.5", "size_m: {uniform: [1.2, 1.8]}"))
    dvsot.generate_variants(tpl, 2, tmp_path / "v", masks=False)
    assert [m for _, m in asked] == [False, False]


@pytest.mark.blender
def test_no_masks_writes_no_masks_and_resume_renders_again_with_them(tmp_path, capsys):
    from dvsot.dataset import Dataset

    (path,) = scenes(tmp_path, "tiny")
    out = tmp_path / "out"
    assert main(["generate", path, "--out-dir", str(out), "--no-masks", "--resume", "--quiet"]) == 0
    with Dataset(out / "tiny.h5") as ds:
        assert not ds.has_masks and ds.objects is not None  # labels and per-object truth stay
        assert ds.object_track() is not None
    capsys.readouterr()
    # the same scene asked with masks: the file without them is not done, so it is rendered again
    assert main(["generate", path, "--out-dir", str(out), "--resume", "--quiet"]) == 0
    rec = json.loads(capsys.readouterr().out.splitlines()[0])
    assert rec["status"] == "done" and not rec.get("resumed")
    with Dataset(out / "tiny.h5") as ds:
        assert ds.has_masks and ds.mask(0).shape == (12, 16)
