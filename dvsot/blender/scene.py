"""Everything that touches bpy: build a scene from a SceneConfig, pose it at a time, render intensity and masks.

One render call gives three images; the rendered ones are read back from a multilayer EXR written
under /dev/shm (the render result cannot be read from memory in background mode):

* view layer "main": the whole scene; Combined -> linear-light luma (Rec. 709), Object Index ->
  the *visible* target mask (occluders in front hide it);
* the *amodal* target mask (the paper's "target rendered separately"): by default the target's
  triangles projected with the same camera and rasterised at pixel centres (dvsot.raster), which
  gives the pixels an object-index pass of the target alone gives, at a fraction of the cost; with
  render.amodal_mask = "render", a second view layer "mask" holding the target alone (every other
  collection excluded) whose Object Index is the mask.

Cycles runs on the CPU with a fixed seed (no animated seed) and no denoising, so a static pixel gets
exactly the same value in every frame and produces no false events.

Surfaces are the lean dielectric (Lambert + GGX mixed by Fresnel, render.surface = "lean") or the
Principled BSDF; with render.bake_background the background plane's procedural colour is baked into
images once at build time (BlenderScene._bake_background) so that renders only look it up.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
import warnings
from pathlib import Path

import bpy
import numpy as np

from dvsot.config import Background, Material, SceneConfig, SceneObject, Texture
from dvsot.errors import UserError
from dvsot.raster import silhouette_mask, triangulate
from dvsot.shapes import mesh_for
from dvsot.trajectory import pose_and_scale

TARGET_INDEX = 1
_LUMA = np.array([0.2126, 0.7152, 0.0722], np.float32)

# Presets of look-alike backgrounds: (base texture, node settings, output, default colour ramp).
_PRESETS: dict[str, tuple[str, dict, str, list]] = {
    "galaxy": ("noise", {"Scale": 3.0, "Detail": 8.0, "Distortion": 0.6}, "Fac",
               [(0.0, 0.0, 0.01), (0.05, 0.02, 0.12), (0.35, 0.15, 0.5), (0.9, 0.85, 1.0)]),
    "mountain": ("noise", {"Scale": 2.0, "Detail": 10.0, "Distortion": 0.3}, "Fac",
                 [(0.03, 0.08, 0.02), (0.2, 0.16, 0.08), (0.45, 0.45, 0.45), (0.95, 0.95, 0.97)]),
    "city": ("brick", {"Scale": 8.0, "Mortar Size": 0.03}, "Color",
             [(0.05, 0.05, 0.06), (0.9, 0.75, 0.35)]),
    "sea": ("wave", {"Scale": 3.0, "Distortion": 6.0, "Detail": 6.0}, "Fac",
            [(0.0, 0.03, 0.12), (0.05, 0.25, 0.45), (0.7, 0.9, 1.0)]),
    "window": ("brick", {"Scale": 4.0, "Mortar Size": 0.12}, "Fac",
               [(0.8, 0.8, 0.75), (0.1, 0.15, 0.25)]),
    "flower": ("voronoi", {"Scale": 9.0}, "Color",
               [(0.9, 0.2, 0.45), (0.95, 0.85, 0.2), (0.15, 0.45, 0.1)]),
}
_NODE_TYPES = {"noise": "ShaderNodeTexNoise", "voronoi": "ShaderNodeTexVoronoi", "wave": "ShaderNodeTexWave",
               "brick": "ShaderNodeTexBrick", "checker": "ShaderNodeTexChecker", "magic": "ShaderNodeTexMagic",
               "gradient": "ShaderNodeTexGradient"}


# Textures cheap to evaluate and made of sharp edges (bricks, checkers): baking gains little there
# (city_star ~5%) and resamples their sub-pixel edges, so "auto" leaves them procedural.
_SHARP_KINDS = {"brick", "checker", "gradient"}


def _should_bake(tex: Texture | None, mode: str | bool) -> bool:
    """Whether render.bake_background = mode (true, false or "auto") bakes this background texture."""
    if tex is None or tex.type == "image" or mode is False:
        return False
    kind = _PRESETS[tex.type][0] if tex.type in _PRESETS else tex.type
    return mode is True or kind not in _SHARP_KINDS


@contextlib.contextmanager
def _quiet_stdout():
    """Silence Blender's per-frame prints on the C-level stdout."""
    import sys

    sys.stdout.flush()
    saved = os.dup(1)
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, 1)
    try:
        yield
    finally:
        os.dup2(saved, 1)
        os.close(devnull)
        os.close(saved)


def _set_input(node, name: str, value) -> None:
    if name in node.inputs:
        node.inputs[name].default_value = value


def _texture_colour(nt, tex: Texture, coords_socket):
    """Build texture nodes; returns the socket carrying its linear RGB colour."""
    kind, params, output, colors = tex.type, {}, "Fac", None
    if kind in _PRESETS:
        kind, params, output, colors = _PRESETS[kind]
        params = dict(params)
        params["Scale"] = params.get("Scale", 5.0) * tex.scale / 5.0
    colors = tex.colors or colors or [(0.05, 0.05, 0.05), (0.9, 0.9, 0.9)]
    mapping = nt.nodes.new("ShaderNodeMapping")
    nt.links.new(coords_socket, mapping.inputs["Vector"])
    mapping.inputs["Location"].default_value = (tex.seed * 0.137, tex.seed * 0.291, tex.seed * 0.419)
    if kind == "image":
        node = nt.nodes.new("ShaderNodeTexImage")
        try:
            node.image = bpy.data.images.load(str(tex.path))
        except RuntimeError as exc:
            raise UserError(f"{tex.path}: cannot read image texture ({exc})") from None
        node.extension = "REPEAT"
        mapping.inputs["Scale"].default_value = (tex.scale / 5.0,) * 3
        nt.links.new(mapping.outputs["Vector"], node.inputs["Vector"])
        return node.outputs["Color"]
    node = nt.nodes.new(_NODE_TYPES[kind])
    nt.links.new(mapping.outputs["Vector"], node.inputs["Vector"])
    if kind == "noise":
        node.noise_dimensions = "4D"
        _set_input(node, "W", tex.seed)
    _set_input(node, "Scale", params.get("Scale", tex.scale))
    _set_input(node, "Detail", params.get("Detail", tex.detail))
    _set_input(node, "Distortion", params.get("Distortion", tex.distortion))
    if "Mortar Size" in params:
        _set_input(node, "Mortar Size", params["Mortar Size"])
    if kind == "brick":
        _set_input(node, "Color1", (*colors[-1], 1.0))
        _set_input(node, "Color2", (*colors[0], 1.0))
        _set_input(node, "Mortar", (*colors[0], 1.0))
        if output == "Color":
            return node.outputs["Color"]
    if output == "Color" and kind == "voronoi":
        # voronoi cell colours are random; pull them into the palette with a ramp on their brightness
        gray = nt.nodes.new("ShaderNodeRGBToBW")
        nt.links.new(node.outputs["Color"], gray.inputs["Color"])
        src = gray.outputs["Val"]
    else:
        src = node.outputs[output] if output in node.outputs else node.outputs[0]
    ramp = nt.nodes.new("ShaderNodeValToRGB")
    elems = ramp.color_ramp.elements
    while len(elems) < len(colors):
        elems.new(0.5)
    for i, c in enumerate(colors):
        elems[i].position = i / (len(colors) - 1)
        elems[i].color = (*c, 1.0)
    nt.links.new(src, ramp.inputs["Fac"])
    out = ramp.outputs["Color"]
    if tex.type == "galaxy":  # add sparse bright stars on top of the nebula
        stars = nt.nodes.new("ShaderNodeTexVoronoi")
        nt.links.new(mapping.outputs["Vector"], stars.inputs["Vector"])
        stars.inputs["Scale"].default_value = 60.0 * tex.scale / 5.0
        less = nt.nodes.new("ShaderNodeMath")
        less.operation = "LESS_THAN"
        nt.links.new(stars.outputs["Distance"], less.inputs[0])
        less.inputs[1].default_value = 0.06
        mix = nt.nodes.new("ShaderNodeMix")
        mix.data_type = "RGBA"
        mix.blend_type = "ADD"
        mix.inputs["Factor"].default_value = 1.0
        nt.links.new(out, mix.inputs["A"])
        nt.links.new(less.outputs[0], mix.inputs["B"])
        out = mix.outputs["Result"]
    return out


def _material(name: str, m: Material, surface: str = "principled") -> bpy.types.Material:
    """A node material for m: its albedo (colour or texture) into the chosen surface shader, plus emission."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        mat = bpy.data.materials.new(name)
        mat.use_nodes = True
    nt = mat.node_tree
    bsdf = next(n for n in nt.nodes if n.type == "BSDF_PRINCIPLED")
    colour = None
    if m.texture is not None:
        coords = nt.nodes.new("ShaderNodeTexCoord")
        colour = _texture_colour(nt, m.texture, coords.outputs["Generated"])
    if surface == "lean":
        nt.nodes.remove(bsdf)
        _lean_surface(nt, m, colour)
        return mat
    bsdf.inputs["Base Color"].default_value = (*m.color, 1.0)
    bsdf.inputs["Roughness"].default_value = m.roughness
    if colour is not None:
        nt.links.new(colour, bsdf.inputs["Base Color"])
    if m.emission > 0:
        bsdf.inputs["Emission Strength"].default_value = m.emission
        if colour is not None:
            nt.links.new(colour, bsdf.inputs["Emission Color"])
        else:
            bsdf.inputs["Emission Color"].default_value = (*m.color, 1.0)
    return mat


def _lean_surface(nt, m: Material, colour) -> None:
    """The classic dielectric: Lambert diffuse and GGX glossy (same roughness) mixed by the Fresnel
    reflectance of IOR 1.5, plus an Emission shader when m.emission > 0.

    It has the Principled BSDF's two lobes without its layering, energy compensation and multiscatter
    GGX, which Cycles evaluates at every shading point and light sample (city_star: ~9% less CPU time
    a sample, mean luma -0.9%)."""
    out = next(n for n in nt.nodes if n.type == "OUTPUT_MATERIAL")
    diffuse = nt.nodes.new("ShaderNodeBsdfDiffuse")
    diffuse.inputs["Color"].default_value = (*m.color, 1.0)
    diffuse.inputs["Roughness"].default_value = 0.0  # Lambert, as the Principled BSDF's default diffuse
    glossy = nt.nodes.new("ShaderNodeBsdfGlossy")
    glossy.distribution = "GGX"  # single scattering: the multiscatter variant costs more for little light
    glossy.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)  # a dielectric's reflection is uncoloured
    glossy.inputs["Roughness"].default_value = m.roughness
    fresnel = nt.nodes.new("ShaderNodeFresnel")
    fresnel.inputs["IOR"].default_value = 1.5
    mix = nt.nodes.new("ShaderNodeMixShader")
    nt.links.new(fresnel.outputs["Fac"], mix.inputs["Fac"])
    nt.links.new(diffuse.outputs["BSDF"], mix.inputs[1])
    nt.links.new(glossy.outputs["BSDF"], mix.inputs[2])
    surface = mix.outputs["Shader"]
    if colour is not None:
        nt.links.new(colour, diffuse.inputs["Color"])
    if m.emission > 0:
        emission = nt.nodes.new("ShaderNodeEmission")
        emission.inputs["Strength"].default_value = m.emission
        emission.inputs["Color"].default_value = (*m.color, 1.0)
        if colour is not None:
            nt.links.new(colour, emission.inputs["Color"])
        add = nt.nodes.new("ShaderNodeAddShader")
        nt.links.new(surface, add.inputs[0])
        nt.links.new(emission.outputs["Emission"], add.inputs[1])
        surface = add.outputs["Shader"]
    nt.links.new(surface, out.inputs["Surface"])


def _albedo_and_emission(nt) -> tuple:
    """(albedo, emission colour, emission strength) of a built surface; colours are sockets or RGB tuples."""

    def value(sock):
        return sock.links[0].from_socket if sock.links else tuple(sock.default_value)[:3]

    bsdf = next((n for n in nt.nodes if n.type == "BSDF_PRINCIPLED"), None)
    if bsdf is not None:
        return (value(bsdf.inputs["Base Color"]), value(bsdf.inputs["Emission Color"]),
                bsdf.inputs["Emission Strength"].default_value)
    diffuse = next(n for n in nt.nodes if n.type == "BSDF_DIFFUSE")
    emission = next((n for n in nt.nodes if n.type == "EMISSION"), None)
    if emission is None:
        return value(diffuse.inputs["Color"]), (0.0, 0.0, 0.0), 0.0
    return value(diffuse.inputs["Color"]), value(emission.inputs["Color"]), emission.inputs["Strength"].default_value


def _mesh_object(name: str, obj: SceneObject, collection, surface: str = "principled") -> bpy.types.Object:
    verts, faces = mesh_for(obj.shape, obj.mesh)
    me = bpy.data.meshes.new(name)
    me.from_pydata((verts * obj.size_m).tolist(), [], faces)
    me.validate()
    me.update()
    if obj.shape in {"sphere", "ball", "cylinder", "torus", "bottle", "cat"}:
        with contextlib.suppress(AttributeError):
            me.shade_smooth()
    me.materials.append(_material(name + "_mat", obj.material, surface))
    ob = bpy.data.objects.new(name, me)
    collection.objects.link(ob)
    return ob


def _direct_lighting(mat: bpy.types.Material, suns: list[tuple[tuple, tuple]], ambient: tuple) -> None:
    """Rewire a material to render.shading 'direct': an emission of albedo x (ambient + sum over suns of
    E_sun max(0, N.L) / pi), plus its own emission. That is the radiance of a Lambertian surface lit by
    the suns (irradiance E_sun, direction L to the sun) and a uniform world, without shadows or bounces."""
    nt = mat.node_tree
    albedo, emission_colour, strength = _albedo_and_emission(nt)
    out = next(n for n in nt.nodes if n.type == "OUTPUT_MATERIAL")

    def vmath(op: str, a, b=None):
        node = nt.nodes.new("ShaderNodeVectorMath")
        node.operation = op
        for sock, val in ((node.inputs[0], a), (node.inputs[1], b)):
            if isinstance(val, tuple):
                sock.default_value = val
            elif val is not None:
                nt.links.new(val, sock)
        return node

    geometry = nt.nodes.new("ShaderNodeNewGeometry")
    light = vmath("ADD", ambient, (0.0, 0.0, 0.0)).outputs["Vector"]
    for direction, irradiance in suns:
        cos = nt.nodes.new("ShaderNodeMath")
        cos.operation = "MAXIMUM"
        nt.links.new(vmath("DOT_PRODUCT", geometry.outputs["Normal"], direction).outputs["Value"], cos.inputs[0])
        cos.inputs[1].default_value = 0.0
        term = vmath("SCALE", irradiance)
        nt.links.new(cos.outputs[0], term.inputs["Scale"])
        light = vmath("ADD", light, term.outputs["Vector"]).outputs["Vector"]
    radiance = vmath("MULTIPLY", albedo, light).outputs["Vector"]
    if strength > 0:
        own = vmath("SCALE", emission_colour)
        own.inputs["Scale"].default_value = strength
        radiance = vmath("ADD", radiance, own.outputs["Vector"]).outputs["Vector"]
    emission = nt.nodes.new("ShaderNodeEmission")
    emission.inputs["Strength"].default_value = 1.0
    nt.links.new(radiance, emission.inputs["Color"])
    nt.links.new(emission.outputs["Emission"], out.inputs["Surface"])


class BlenderScene:
    """A built scene: set_time(t) poses it, render() returns (luma, amodal mask, visible mask)."""

    def __init__(self, cfg: SceneConfig) -> None:
        self.cfg = cfg
        self.width, self.height = cfg.sensor.width, cfg.sensor.height
        self._tmp = Path(tempfile.mkdtemp(prefix="dvsot-render-", dir="/dev/shm" if os.path.isdir("/dev/shm") else None))
        with _quiet_stdout():
            bpy.ops.wm.read_factory_settings(use_empty=True)
        self.scene = bpy.context.scene
        self._setup_render()
        self._build()

    def close(self) -> None:
        """Remove the temporary render directory."""
        shutil.rmtree(self._tmp, ignore_errors=True)

    def __enter__(self) -> "BlenderScene":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _setup_render(self) -> None:
        sc, r = self.scene, self.cfg.render
        sc.render.engine = "CYCLES"
        sc.cycles.device = "CPU"
        sc.cycles.samples = r.samples
        sc.cycles.use_denoising = False
        sc.cycles.use_adaptive_sampling = False
        sc.cycles.seed = self.cfg.derived_seed("cycles") % (2**31)
        sc.cycles.use_animated_seed = False
        # With a single light (one lamp, no emissive surface; the world is sampled apart) the light tree
        # only adds work: the samples, and so the image, are the same without it (~10% faster). With
        # more lights it chooses among them differently, so it stays on there.
        cfg = self.cfg
        materials = [cfg.target.material] + [o.material for o in cfg.objects]
        if cfg.background.kind == "plane":
            materials.append(cfg.background.material)
        sc.cycles.use_light_tree = len(cfg.lights) + sum(m.emission > 0 for m in materials) > 1
        sc.cycles.max_bounces = 0 if r.shading == "direct" else r.max_bounces  # direct: emission only
        for attr in ("diffuse_bounces", "glossy_bounces", "transmission_bounces", "volume_bounces",
                     "transparent_max_bounces"):
            setattr(sc.cycles, attr, min(getattr(sc.cycles, attr), max(r.max_bounces, 1)))
        sc.render.use_persistent_data = r.persistent_data
        sc.render.resolution_x, sc.render.resolution_y = self.width, self.height
        sc.render.resolution_percentage = 100
        sc.render.pixel_aspect_x = sc.render.pixel_aspect_y = 1.0
        if r.threads:
            sc.render.threads_mode = "FIXED"
            sc.render.threads = r.threads
        sc.view_settings.view_transform = "Standard"
        sc.view_settings.look = "None"
        sc.view_settings.exposure = 0.0
        sc.view_settings.gamma = 1.0
        sc.render.film_transparent = False
        sc.render.image_settings.media_type = "MULTI_LAYER_IMAGE"
        sc.render.image_settings.file_format = "OPEN_EXR_MULTILAYER"
        sc.render.image_settings.color_depth = "32"
        sc.render.image_settings.exr_codec = "NONE"

    def _build(self) -> None:
        cfg, sc = self.cfg, self.scene
        root = sc.collection
        self.collections = {}
        for name in ("target", "others", "background"):
            col = bpy.data.collections.new(name)
            root.children.link(col)
            self.collections[name] = col
        cam_data = bpy.data.cameras.new("camera")
        k = cfg.sensor.intrinsics()
        cam_data.sensor_fit = "HORIZONTAL" if self.width >= self.height else "VERTICAL"
        cam_data.sensor_width = cfg.sensor.sensor_width_mm
        cam_data.sensor_height = cfg.sensor.sensor_width_mm
        cam_data.lens = k.fx * cfg.sensor.sensor_width_mm / max(self.width, self.height)
        cam_data.shift_x = -(k.cx - self.width / 2) / max(self.width, self.height)
        cam_data.shift_y = (k.cy - self.height / 2) / max(self.width, self.height)
        cam_data.clip_start, cam_data.clip_end = 0.01, 1e5
        self.camera = bpy.data.objects.new("camera", cam_data)
        root.objects.link(self.camera)
        sc.camera = self.camera
        surface = cfg.render.surface
        self.target = _mesh_object("target", cfg.target, self.collections["target"], surface)
        self.target.pass_index = TARGET_INDEX
        verts, faces = mesh_for(cfg.target.shape, cfg.target.mesh)
        self._target_verts = np.asarray(verts, np.float64) * cfg.target.size_m
        self._target_tris = triangulate(faces)
        self._intrinsics = k
        self.others = [(_mesh_object(o.name or f"{o.role}_{i}", o, self.collections["others"], surface), o)
                       for i, o in enumerate(cfg.objects)]
        self._background(cfg.background)
        if cfg.background.kind == "plane" and _should_bake(cfg.background.material.texture, cfg.render.bake_background):
            self._bake_background()
        direct = cfg.render.shading == "direct"
        for i, light in enumerate(cfg.lights):
            if direct:  # the suns live in the materials' shaders (_direct_lighting)
                continue
            data = bpy.data.lights.new(f"light_{i}", light.type.upper())
            data.energy = light.strength
            data.color = light.color
            if light.type == "area":
                data.size = light.size_m
            ob = bpy.data.objects.new(f"light_{i}", data)
            ob.location = light.location
            ob.rotation_euler = tuple(np.radians(light.rotation_deg))
            self.collections["background"].objects.link(ob)
        world = bpy.data.worlds.new("world")
        sc.world = world
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)
            world.use_nodes = True
        bg = next(n for n in world.node_tree.nodes if n.type == "BACKGROUND")
        bg.inputs["Color"].default_value = (*cfg.world.color, 1.0)
        bg.inputs["Strength"].default_value = cfg.world.strength
        if cfg.background.kind == "environment":
            nt = world.node_tree
            coords = nt.nodes.new("ShaderNodeTexCoord")
            colour = _texture_colour(nt, cfg.background.material.texture or Texture(type="noise"),
                                     coords.outputs["Generated"])
            nt.links.new(colour, bg.inputs["Color"])
        if direct:
            from mathutils import Euler, Vector

            # a sun shines along its local -Z: the direction to it is +Z rotated
            suns = [(tuple(Euler([float(a) for a in np.radians(light.rotation_deg)], "XYZ").to_matrix()
                           @ Vector((0.0, 0.0, 1.0))),
                     tuple(light.strength * np.asarray(light.color) / np.pi)) for light in cfg.lights]
            ambient = tuple(float(c) * cfg.world.strength for c in cfg.world.color)
            for mat in bpy.data.materials:
                _direct_lighting(mat, suns, ambient)
        main = sc.view_layers[0]
        main.name = "main"
        main.use_pass_object_index = True
        main.use_pass_z = False  # on by default; nothing reads depth, and writing it costs ~2% a frame
        if not self.cfg.render.specular:  # matte: Cycles skips a closure whose weight is zero
            for mat in bpy.data.materials:
                for node in mat.node_tree.nodes if mat.node_tree else ():
                    if node.type == "BSDF_PRINCIPLED":
                        node.inputs["Specular IOR Level"].default_value = 0.0
                    elif node.type == "MIX_SHADER":  # lean surface: all weight on the diffuse lobe
                        for link in node.inputs["Fac"].links:
                            mat.node_tree.links.remove(link)
                        node.inputs["Fac"].default_value = 0.0
        if self.cfg.render.amodal_mask == "render":
            mask = sc.view_layers.new("mask")
            mask.use_pass_object_index = True
            mask.use_pass_z = False
            for name in ("others", "background"):
                mask.layer_collection.children[name].exclude = True
            mask.use_pass_combined = False
        self.set_time(0.0)

    def _background(self, bg: Background) -> None:
        if bg.kind != "plane":
            return
        plane = SceneObject(shape="plane", size_m=bg.size_m, material=bg.material,
                            trajectory={"keyframes": [{"t": 0, "location": bg.location, "rotation_deg": bg.rotation_deg}],
                                        "interpolation": "linear"})
        self._plane_spec = plane
        self.background_plane = _mesh_object("background", plane, self.collections["background"],
                                             self.cfg.render.surface)
        m, _ = pose_and_scale(plane.trajectory, 0.0)
        self.background_plane.matrix_world = m.T.tolist()

    def _plane_view(self) -> tuple[np.ndarray, float]:
        """((u0, v0, u1, v1), px_per_m): the part of the background plane the camera sees over the whole
        sequence, in the plane's 0..1 coordinates with a margin (the whole plane when some view ray
        misses it), and its largest on-screen density (pixels per metre at the closest approach)."""
        cfg, k = self.cfg, self._intrinsics
        m, _ = pose_and_scale(self._plane_spec.trajectory, 0.0)
        axes, normal, centre = m[:3, :2], m[:3, 2], m[:3, 3]
        size_m = cfg.background.size_m
        # image corners as camera-space directions (x right, y up, looking along -z): the frustum meets
        # the plane in a quadrilateral whose corners are these rays' hits
        corners = np.array([[(u - k.cx) / k.fx, -(v - k.cy) / k.fx, -1.0]
                            for u in (0.0, float(k.width)) for v in (0.0, float(k.height))])
        seed = cfg.derived_seed("camera_shake")
        hits, distance = [], np.inf
        for t in np.linspace(0.0, cfg.duration_s, 65):
            cam = pose_and_scale(cfg.camera, float(t), seed)[0]
            rays, origin = corners @ cam[:3, :3].T, cam[:3, 3]
            distance = min(distance, abs(float(normal @ (origin - centre))))
            with np.errstate(divide="ignore", invalid="ignore"):
                s = float(normal @ (centre - origin)) / (rays @ normal)
            hits.append(((origin + s[:, None] * rays) - centre) @ axes / size_m + 0.5 if np.all(s > 0) else None)
        px_per_m = k.fx / max(distance, 1e-3)
        if any(h is None for h in hits):
            return np.array([0.0, 0.0, 1.0, 1.0]), px_per_m
        uv = np.concatenate(hits)
        lo, hi = uv.min(0), uv.max(0)
        pad = 0.1 * (hi - lo) + 4.0 / (px_per_m * size_m)  # camera shake between the sampled times
        lo, hi = np.clip(lo - pad, 0.0, 1.0), np.clip(hi + pad, 0.0, 1.0)
        if np.any(hi - lo <= 0):
            return np.array([0.0, 0.0, 1.0, 1.0]), px_per_m
        return np.concatenate([lo, hi]), px_per_m

    def _bake(self, nt, colour, uv_name: str, width: int, height: int):
        """Bake the colour socket of the plane's node tree into a float image through UV map uv_name;
        returns the image texture node reading it back (linear interpolation)."""
        plane, sc = self.background_plane, self.scene
        out = next(n for n in nt.nodes if n.type == "OUTPUT_MATERIAL")
        surface = out.inputs["Surface"].links[0].from_socket
        emission = nt.nodes.new("ShaderNodeEmission")  # an emission bake gives the colour itself, unlit
        nt.links.new(colour, emission.inputs["Color"])
        nt.links.new(emission.outputs["Emission"], out.inputs["Surface"])
        node = nt.nodes.new("ShaderNodeTexImage")
        node.image = bpy.data.images.new(f"background_{uv_name}", width, height, float_buffer=True)
        nt.nodes.active = node
        plane.data.uv_layers.active = plane.data.uv_layers[uv_name]
        samples, sc.cycles.samples = sc.cycles.samples, self.cfg.render.bake_samples
        bpy.context.view_layer.objects.active = plane
        plane.select_set(True)
        try:
            with _quiet_stdout():
                result = bpy.ops.object.bake(type="EMIT", margin=0, use_clear=True)
        finally:
            sc.cycles.samples = samples
            plane.select_set(False)
        if "FINISHED" not in result:
            raise RuntimeError("Blender could not bake the background texture")
        node.image.pack()  # keep the baked pixels with the scene data that Cycles reads
        nt.nodes.remove(emission)
        nt.links.new(surface, out.inputs["Surface"])
        node.interpolation = "Linear"
        coords = nt.nodes.new("ShaderNodeUVMap")
        coords.uv_map = uv_name
        nt.links.new(coords.outputs["UV"], node.inputs["Vector"])
        return node

    def _bake_background(self) -> None:
        """Bake the background plane's procedural colour into images once (Cycles' emission bake) and let
        its material read them instead: the part the camera sees at render.bake_texels_per_px texels per
        on-screen pixel, the whole plane (seen only by bounce and light rays) at 1/8 of that.

        The plane is static, so its texture never changes: evaluating noise/Voronoi/wave nodes at every
        camera ray and light sample is wasted work (woman_ball's emissive Voronoi: ~0.3 s a sample)."""
        r, size_m = self.cfg.render, self.cfg.background.size_m
        nt = self.background_plane.material_slots[0].material.node_tree
        colour = _albedo_and_emission(nt)[0]
        (u0, v0, u1, v1), px_per_m = self._plane_view()
        me = self.background_plane.data
        view, whole = me.uv_layers.new(name="bake_view"), me.uv_layers.new(name="bake_whole")
        for loop in me.loops:  # the plane's own coordinates, so one texel is one fixed patch of wall
            co = me.vertices[loop.vertex_index].co
            u, v = co.x / size_m + 0.5, co.y / size_m + 0.5
            whole.data[loop.index].uv = (u, v)
            view.data[loop.index].uv = ((u - u0) / (u1 - u0), (v - v0) / (v1 - v0))
        texels_per_m = r.bake_texels_per_px * px_per_m

        def side(extent: float, per_m: float) -> int:
            return int(np.clip(np.ceil(per_m * extent * size_m), 16, r.bake_max_size))

        near = self._bake(nt, colour, "bake_view", side(u1 - u0, texels_per_m), side(v1 - v0, texels_per_m))
        near.extension = "CLIP"  # alpha 0 outside the seen part: the mix below falls back to the whole plane
        far = self._bake(nt, colour, "bake_whole", side(1.0, texels_per_m / 8), side(1.0, texels_per_m / 8))
        far.extension = "EXTEND"
        mix = nt.nodes.new("ShaderNodeMix")
        mix.data_type = "RGBA"
        nt.links.new(near.outputs["Alpha"], mix.inputs["Factor"])
        nt.links.new(far.outputs["Color"], mix.inputs["A"])
        nt.links.new(near.outputs["Color"], mix.inputs["B"])
        for link in list(colour.links):
            to_socket = link.to_socket
            nt.links.remove(link)
            nt.links.new(mix.outputs["Result"], to_socket)
        me.uv_layers.active = view
        self.bake_sizes = (tuple(near.image.size), tuple(far.image.size))

    def set_time(self, t: float) -> None:
        """Pose camera and objects at time t (seconds)."""
        cfg = self.cfg
        m, _ = pose_and_scale(cfg.camera, t, cfg.derived_seed("camera_shake"))
        self.camera.matrix_world = m.T.tolist()
        self._camera_matrix = m
        for ob, spec in [(self.target, cfg.target)] + self.others:
            m, s = pose_and_scale(spec.trajectory, t, cfg.derived_seed("shake:" + ob.name))
            m[:3, :3] = m[:3, :3] * s
            ob.matrix_world = m.T.tolist()
            if ob is self.target:
                self._target_matrix = m

    def raster_amodal_mask(self) -> np.ndarray:
        """The amodal target mask at the current pose, from the target's projected triangles (bool HxW)."""
        m = self._target_matrix
        verts = self._target_verts @ m[:3, :3].T + m[:3, 3]
        return silhouette_mask(verts, self._target_tris, self._camera_matrix, self._intrinsics)

    def render(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(linear luma float32 HxW, amodal target mask bool HxW, visible target mask bool HxW) at t seconds."""
        import OpenEXR

        self.set_time(t)
        path = self._tmp / "frame.exr"
        self.scene.render.filepath = str(path)
        with _quiet_stdout():
            result = bpy.ops.render.render(write_still=True)
        if "FINISHED" not in result or not path.is_file():
            raise RuntimeError(f"Blender render failed at t={t:.6f} s")
        try:
            with OpenEXR.File(str(path)) as f:
                channels = {}
                for part in f.parts:
                    channels.update(part.channels)
        finally:
            path.unlink(missing_ok=True)
        rgba = channels["main.Combined"].pixels
        luma = rgba[..., :3] @ _LUMA
        visible = np.rint(channels["main.Object Index.X"].pixels) == TARGET_INDEX
        if self.cfg.render.amodal_mask == "render":
            amodal = np.rint(channels["mask.Object Index.X"].pixels) == TARGET_INDEX
        else:
            amodal = self.raster_amodal_mask()
        return np.ascontiguousarray(np.maximum(luma, 0.0), np.float32), amodal, visible
