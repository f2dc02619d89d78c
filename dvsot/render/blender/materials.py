"""Shader graphs for a scene's surfaces: procedural and image textures, the Principled or lean dielectric
surface, and the rewiring of a material to render.shading = "direct" (Lambert lighting in its shader)."""

from __future__ import annotations

import warnings

import bpy

from dvsot.core.errors import UserError
from dvsot.scene import Material, Texture

# Presets of look-alike backgrounds: (base texture, node settings, output, default colour ramp).
PRESETS: dict[str, tuple[str, dict, str, list]] = {
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




def _set_input(node, name: str, value) -> None:
    """Set a node input's default if the node has it (texture nodes differ in which inputs they have)."""
    if name in node.inputs:
        node.inputs[name].default_value = value


def texture_colour(nt, tex: Texture, coords_socket):
    """Build texture nodes; returns the socket carrying its linear RGB colour."""
    kind, params, output, colors = tex.type, {}, "Fac", None
    if kind in PRESETS:
        kind, params, output, colors = PRESETS[kind]
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


def material(name: str, m: Material, surface: str = "principled") -> bpy.types.Material:
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
        colour = texture_colour(nt, m.texture, coords.outputs["Generated"])
    if surface == "lean":
        nt.nodes.remove(bsdf)
        lean_surface(nt, m, colour)
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


def lean_surface(nt, m: Material, colour) -> None:
    """The classic dielectric: Lambert diffuse and GGX glossy (same roughness) mixed by the Fresnel
    reflectance of IOR 1.5, plus an Emission shader when m.emission > 0.

    It has the Principled BSDF's two lobes without its layering, energy compensation and multiscatter
    GGX, which Cycles evaluates at every shading point and light sample: less CPU time a sample for a
    look close to the Principled BSDF's (figures: docs/results.md)."""
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


def albedo_and_emission(nt) -> tuple:
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



def direct_lighting(mat: bpy.types.Material, suns: list[tuple[tuple, tuple]], ambient: tuple) -> None:
    """Rewire a material to render.shading 'direct': an emission of albedo x (ambient + sum over suns of
    E_sun max(0, N.L) / pi), plus its own emission. That is the radiance of a Lambertian surface lit by
    the suns (irradiance E_sun, direction L to the sun) and a uniform world, without shadows or bounces."""
    nt = mat.node_tree
    albedo, emission_colour, strength = albedo_and_emission(nt)
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

