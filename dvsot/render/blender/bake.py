"""The background plane's procedural colour baked into images once at scene build (Cycles' emission bake),
so that renders only look it up (render.bake_background); which part to bake is dvsot.render.plane_view's job.

The plane is static, so its texture never changes: evaluating noise/Voronoi/wave nodes at every camera ray
and light sample is wasted work (a large share of a sample for an emissive Voronoi: docs/results.md)."""

from __future__ import annotations

import bpy
import numpy as np

from dvsot.render.blender.materials import PRESETS, albedo_and_emission
from dvsot.render.blender.quiet import quiet_stdout
from dvsot.render.plane_view import bake_sides, plane_uvs
from dvsot.scene import Render, Texture

# Textures cheap to evaluate and made of sharp edges (bricks, checkers): baking gains little there
# (docs/results.md) and resamples their sub-pixel edges, so "auto" leaves them procedural.
SHARP_KINDS = {"brick", "checker", "gradient"}


def should_bake(tex: Texture | None, mode: str | bool) -> bool:
    """Whether render.bake_background = mode (true, false or "auto") bakes this background texture."""
    if tex is None or tex.type == "image" or mode is False:
        return False
    kind = PRESETS[tex.type][0] if tex.type in PRESETS else tex.type
    return mode is True or kind not in SHARP_KINDS


def _bake(plane, scene, samples: int, nt, colour, uv_name: str, size: tuple[int, int]):
    """Bake the colour socket of the plane's node tree into a float image of size (width, height) through
    UV map uv_name with samples Cycles samples; returns the image texture node reading it back (linear)."""
    out = next(n for n in nt.nodes if n.type == "OUTPUT_MATERIAL")
    surface = out.inputs["Surface"].links[0].from_socket
    emission = nt.nodes.new("ShaderNodeEmission")  # an emission bake gives the colour itself, unlit
    nt.links.new(colour, emission.inputs["Color"])
    nt.links.new(emission.outputs["Emission"], out.inputs["Surface"])
    node = nt.nodes.new("ShaderNodeTexImage")
    node.image = bpy.data.images.new(f"background_{uv_name}", *size, float_buffer=True)
    nt.nodes.active = node
    plane.data.uv_layers.active = plane.data.uv_layers[uv_name]
    saved, scene.cycles.samples = scene.cycles.samples, samples
    bpy.context.view_layer.objects.active = plane
    plane.select_set(True)
    try:
        with quiet_stdout():
            result = bpy.ops.object.bake(type="EMIT", margin=0, use_clear=True)
    finally:
        scene.cycles.samples = saved
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


def bake_background(plane, scene, r: Render, size_m: float, rect: np.ndarray,
                    px_per_m: float) -> tuple[tuple[int, int], tuple[int, int]]:
    """Bake the plane object's procedural colour and let its material read the images instead: the seen
    part rect at r.bake_texels_per_px texels per on-screen pixel (px_per_m pixels per metre at most), the
    whole plane (seen only by bounce and light rays) at 1/8 of that. Returns the (near, far) image sizes."""
    nt = plane.material_slots[0].material.node_tree
    colour = albedo_and_emission(nt)[0]
    me = plane.data
    view, whole = me.uv_layers.new(name="bake_view"), me.uv_layers.new(name="bake_whole")
    vertex = np.empty(len(me.loops), np.int64)
    me.loops.foreach_get("vertex_index", vertex)
    co = np.empty(3 * len(me.vertices), np.float32)
    me.vertices.foreach_get("co", co)
    whole_uv, view_uv = plane_uvs(co.reshape(-1, 3)[vertex, :2], size_m, rect)
    whole.data.foreach_set("uv", whole_uv.astype(np.float32).ravel())
    view.data.foreach_set("uv", view_uv.astype(np.float32).ravel())
    near_size, far_size = bake_sides(rect, px_per_m, size_m, r.bake_texels_per_px, r.bake_max_size)
    near = _bake(plane, scene, r.bake_samples, nt, colour, "bake_view", near_size)
    near.extension = "CLIP"  # alpha 0 outside the seen part: the mix below falls back to the whole plane
    far = _bake(plane, scene, r.bake_samples, nt, colour, "bake_whole", far_size)
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
    return tuple(near.image.size), tuple(far.image.size)
