"""Tiny real Blender renders (64x48): static scenes give no events, moving targets give events in their box."""

import json

import numpy as np
import pytest

from dvsot.cli import main
from dvsot.dataset import Dataset
from dvsot.scene import parse_scene
from dvsot.scene.trajectory import pose_matrix, project

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


@pytest.mark.parametrize("render", ["{threads: 2}", "{threads: 2, bake_background: false}",
                                    "{threads: 2, surface: principled}"])
def test_static_scene_gives_no_signal_events(tmp_path, render):
    # the default (lean surface, its noise background baked), procedural textures, the Principled BSDF
    path = scene(tmp_path)
    path.write_text(path.read_text().replace("render: {threads: 2}", f"render: {render}"))
    out = tmp_path / "static.h5"
    assert main(["generate", str(path), "-o", str(out), "--quiet"]) == 0
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
    from dvsot.render.blender import BlenderScene

    text = SCENE.format(duration=0.02, x0=100.0, x1=100.0, shake=0.0, texture="null")
    text = text.replace("texture: null, emission: 0.3", "texture: null").replace(
        "[0.1, 0.1, 0.1], texture", "[0.5, 0.4, 0.2], texture"
    )
    text = text.replace("lights: []", "lights: [{type: sun, strength: 2.0, rotation_deg: [60, 0, 0]}]")
    text = text.replace(
        "world: {color: [0.5, 0.5, 0.5], strength: 1.0}", "world: {color: [0.1, 0.1, 0.1], strength: 1.0}"
    )
    cfg = parse_scene(text.replace("render: {threads: 2}", "render: {threads: 2, shading: direct}"))
    with BlenderScene(cfg) as sc:
        luma, amodal, _ = sc.render(0.0)
    # the wall faces the camera (normal -y); the sun at 60 deg about x lies along (0, -sin 60, cos 60)
    irradiance = 2.0 * np.sin(np.radians(60)) / np.pi + 0.1
    expected = float(np.array([0.5, 0.4, 0.2]) @ [0.2126, 0.7152, 0.0722]) * irradiance
    assert not amodal.any()
    np.testing.assert_allclose(luma, expected, rtol=1e-3)


def test_direct_shading_refuses_point_and_area_lights():
    from dvsot.core.errors import UserError

    text = SCENE.format(duration=0.02, x0=0.0, x1=0.0, shake=0.0, texture="null")
    text = text.replace("lights: []", "lights: [{type: point, strength: 100}]")
    with pytest.raises(UserError, match=r"lights\[0\]\.type"):
        parse_scene(text.replace("render: {threads: 2}", "render: {threads: 2, shading: direct}"))
    parse_scene(text)  # path shading takes any light


def _wall_scene(render: str, roughness: float = 0.0, sun_deg: float = 60.0, world: float = 0.0) -> str:
    """The tiny scene as a bare wall (albedo (0.5, 0.4, 0.2), no emission, the target far outside the view)."""
    text = SCENE.format(duration=0.02, x0=100.0, x1=100.0, shake=0.0, texture="null")
    text = text.replace("[0.1, 0.1, 0.1], texture: null, emission: 0.3",
                        f"[0.5, 0.4, 0.2], texture: null, roughness: {roughness}")
    text = text.replace("lights: []", f"lights: [{{type: sun, strength: 2.0, rotation_deg: [{sun_deg}, 0, 0]}}]")
    text = text.replace(
        "world: {color: [0.5, 0.5, 0.5], strength: 1.0}", f"world: {{color: [{world}, {world}, {world}]}}"
    )
    return text.replace("render: {threads: 2}", f"render: {{threads: 2, {render}}}")


def _render_once(text: str, t: float = 0.0) -> np.ndarray:
    from dvsot.render.blender import BlenderScene

    with BlenderScene(parse_scene(text)) as sc:
        return sc.render(t)[0]


@pytest.mark.parametrize("sun_deg", [30.0, 60.0])
def test_lean_surface_gives_the_closed_form_fresnel_weighted_lambert_radiance(sun_deg):
    # A smooth (roughness 0) wall under a sun and a black world: the glossy lobe is a mirror that sees
    # neither the sun nor the camera, so each pixel is the diffuse lobe's share (1 - F) of the Lambert
    # radiance rho E cos(theta) / pi; F is the Fresnel reflectance of IOR 1.5 at the camera ray's angle,
    # 0.040 at normal incidence and < 0.0405 within this 64x48 view. Per pixel, the sun's 0.53 deg disc
    # (one sample of it) moves cos(theta) by up to 0.0046 cot(theta): 0.8 % at 30 deg.
    luma = _render_once(_wall_scene("surface: lean", sun_deg=sun_deg))
    lambert = float(np.array([0.5, 0.4, 0.2]) @ [0.2126, 0.7152, 0.0722]) * 2.0 * np.sin(np.radians(sun_deg)) / np.pi
    np.testing.assert_allclose(luma.mean(), (1 - 0.04) * lambert, rtol=2e-3)
    np.testing.assert_allclose(luma, (1 - 0.04) * lambert, rtol=0.012)


def test_lean_surface_matches_the_principled_bsdf_on_a_rough_glossy_wall():
    # Same wall, roughness 0.5 and an ambient world: both shaders add a broad Fresnel-weighted GGX sheen
    # to the Lambert term; they differ in the Principled BSDF's energy compensation and multiscatter GGX
    # (city_star: mean luma -0.9 %). One sample per pixel: compare means over the image.
    text = _wall_scene("surface: lean", roughness=0.5, world=0.1)
    lean = _render_once(text)
    principled = _render_once(text.replace("surface: lean", "surface: principled"))
    assert abs(lean.mean() / principled.mean() - 1) < 0.015  # measured -0.4 %


def test_baked_background_renders_like_the_procedural_texture(tmp_path):
    from dvsot.render.blender import BlenderScene

    text = scene(tmp_path, texture="{type: galaxy, scale: 5}").read_text()
    images = {}
    for bake in ("true", "false"):
        cfg = parse_scene(text.replace("render: {threads: 2}", f"render: {{threads: 2, bake_background: {bake}}}"))
        with BlenderScene(cfg) as sc:
            images[bake] = sc.render(0.0)[0]
            nodes = {n.type for n in sc.background_plane.material_slots[0].material.node_tree.nodes}
            assert ("TEX_IMAGE" in nodes) == (bake == "true")
            if bake == "true":
                # the camera (fx = 35/36 * 64 px) looks straight at the 40 m wall 18 m away: it sees
                # 64 x 48 px / fx * 18 m of it, centred; that part + 10 % a side + 4 px is baked at 2
                # texels per pixel, the whole wall at 1/8 of that
                (u0, v0, u1, v1), px_per_m = sc._plane_view()
                assert px_per_m == pytest.approx(35 / 36 * 64 / 18)
                half = np.array([32, 24]) / px_per_m / 40 * 1.2 + 4 / (px_per_m * 40)
                np.testing.assert_allclose([u0, v0, u1, v1], [*(0.5 - half), *(0.5 + half)], atol=1e-6)
                near, whole = sc.bake_sizes
                assert near == tuple(int(n) for n in np.ceil(2 * px_per_m * 40 * 2 * half))
                assert whole == (int(np.ceil(2 * px_per_m * 40 / 8)),) * 2
    baked, procedural = images["true"], images["false"]
    assert abs(baked.mean() / procedural.mean() - 1) < 0.01
    assert np.abs(baked - procedural).mean() < 0.02 * procedural.mean()


def test_bake_auto_leaves_sharp_edged_textures_procedural():
    from dvsot.render.blender.bake import should_bake as _should_bake
    from dvsot.scene import Texture

    assert _should_bake(Texture(type="flower"), "auto") and _should_bake(Texture(type="noise"), "auto")
    assert not _should_bake(Texture(type="window"), "auto") and not _should_bake(Texture(type="checker"), "auto")
    assert _should_bake(Texture(type="window"), True) and not _should_bake(Texture(type="noise"), False)
    assert not _should_bake(None, True)
