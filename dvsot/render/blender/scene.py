"""A scene built in Blender from a SceneConfig: pose it at a time, render intensity and masks.

One render call gives three images; the rendered ones are read back from a multilayer EXR written
under RENDER_DIR, /dev/shm (the render result cannot be read from memory in background mode); an image
Blender could not write there (a full or read-only file system) is one RunError line:

* view layer "main": the whole scene; Combined -> linear-light luma (Rec. 709), Object Index ->
  the object id of each pixel (dvsot.events.labels: 0 background, 1 target, 2.. the other objects in the
  scene file's order) and from it the *visible* target mask (occluders in front hide it);
* the *amodal* target mask (the paper's "target rendered separately"): by default the target's
  triangles projected with the same camera and rasterised at pixel centres (dvsot.render.raster), which
  gives the pixels an object-index pass of the target alone gives, at a fraction of the cost; with
  render.amodal_mask = "render", a second view layer "mask" holding the target alone (every other
  collection excluded) whose Object Index is the mask;
* every object's amodal silhouette (the target's and the scene file's objects'), rasterised the same way over
  its whole projected extent, on the sensor and past its edges (object_coverage): its amodal mask, and its
  area on the sensor and in all, from which truncation (the share off the sensor) follows; render_truth gives
  it with the render.

Cycles runs on the CPU with a fixed seed (no animated seed) and no denoising, so a static pixel gets
exactly the same value in every frame and produces no false events.

Surfaces and their shader graphs are dvsot.render.blender.materials' job; with render.bake_background the
background plane's procedural colour is baked into images once at build time (dvsot.render.blender.bake).
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

from dvsot.core.errors import RunError, exception_line
from dvsot.events.labels import TARGET_ID
from dvsot.render.blender.bake import bake_background, should_bake
from dvsot.render.blender.materials import direct_lighting, material, texture_colour
from dvsot.render.blender.quiet import captured_output, quiet_stdout
from dvsot.render.plane_view import seen_part
from dvsot.render.raster import silhouette_coverage, silhouette_mask, triangulate
from dvsot.scene import Background, SceneConfig, SceneObject, Texture
from dvsot.scene.shapes import mesh_for
from dvsot.scene.trajectory import pose_and_scale

TARGET_INDEX = TARGET_ID  # the target's pass index: its id in the per-event labels
RENDER_DIR: str | None = "/dev/shm" if os.path.isdir("/dev/shm") else None  # None: the system's temp directory
_LUMA = np.array([0.2126, 0.7152, 0.0722], np.float32)
# camera poses sampled over the sequence to find the part of the background plane it sees
_VIEW_SAMPLES = 65


def _mesh_object(name: str, obj: SceneObject, collection, surface: str = "principled") -> bpy.types.Object:
    """A mesh object for obj (its shape scaled to size_m, its material) linked into collection."""
    verts, faces = mesh_for(obj.shape, obj.mesh)
    me = bpy.data.meshes.new(name)
    me.from_pydata((verts * obj.size_m).tolist(), [], faces)
    me.validate()
    me.update()
    if obj.shape in {"sphere", "ball", "cylinder", "torus", "bottle", "cat"}:
        with contextlib.suppress(AttributeError):
            me.shade_smooth()
    me.materials.append(material(name + "_mat", obj.material, surface))
    ob = bpy.data.objects.new(name, me)
    collection.objects.link(ob)
    return ob


class BlenderScene:
    """A built scene: set_time(t) poses it, render() returns (luma, amodal mask, visible mask); render_truth() adds
    the object index pass and every object's amodal coverage."""

    def __init__(self, cfg: SceneConfig) -> None:
        self.cfg = cfg
        self.width, self.height = cfg.sensor.width, cfg.sensor.height
        where = RENDER_DIR or tempfile.gettempdir()
        try:
            self._tmp = Path(tempfile.mkdtemp(prefix="dvsot-render-", dir=where))
        except OSError as exc:
            raise RunError(f"{where}: cannot make Blender's render directory ({exc.strerror or exc}); "
                           f"nothing was replaced") from None
        try:
            with quiet_stdout():
                bpy.ops.wm.read_factory_settings(use_empty=True)
            self.scene = bpy.context.scene
            self._setup_render()
            self._build()
        except BaseException:
            self.close()
            raise

    def close(self) -> None:
        """Remove the temporary render directory."""
        shutil.rmtree(self._tmp, ignore_errors=True)

    def __enter__(self) -> BlenderScene:
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
        # only adds work: the samples, and so the image, are the same without it, and faster. With
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
        self.collections = {}
        for name in ("target", "others", "background"):
            col = bpy.data.collections.new(name)
            sc.collection.children.link(col)
            self.collections[name] = col
        self._camera()
        surface = cfg.render.surface
        self.target = _mesh_object("target", cfg.target, self.collections["target"], surface)
        self.target.pass_index = TARGET_INDEX
        verts, faces = mesh_for(cfg.target.shape, cfg.target.mesh)
        self._target_verts = np.asarray(verts, np.float64) * cfg.target.size_m
        self._target_tris = triangulate(faces)
        self.others = [(_mesh_object(o.name or f"{o.role}_{i}", o, self.collections["others"], surface), o)
                       for i, o in enumerate(cfg.objects)]
        for i, (ob, _) in enumerate(self.others):  # the background plane keeps 0, the world's value
            ob.pass_index = TARGET_INDEX + 1 + i
        # every object's mesh (vertices in metres, scaled by size_m; triangles) by its id, for the amodal rasters
        self._meshes = {TARGET_INDEX: (self._target_verts, self._target_tris)}
        for i, (_, o) in enumerate(self.others):
            v, fcs = mesh_for(o.shape, o.mesh)
            self._meshes[TARGET_INDEX + 1 + i] = (np.asarray(v, np.float64) * o.size_m, triangulate(fcs))
        self._matrices: dict[int, np.ndarray] = {}
        self._background(cfg.background)
        if cfg.background.kind == "plane" and should_bake(cfg.background.material.texture, cfg.render.bake_background):
            self.bake_sizes = bake_background(self.background_plane, sc, cfg.render, cfg.background.size_m,
                                              *self._plane_view())
        direct = cfg.render.shading == "direct"
        if not direct:  # with direct shading the suns live in the materials' shaders (direct_lighting)
            self._lights()
        self._world()
        if direct:
            self._direct_lighting()
        main = sc.view_layers[0]
        main.name = "main"
        main.use_pass_object_index = True
        main.use_pass_z = False  # on by default; nothing reads depth, and writing it costs render time
        if not cfg.render.specular:
            self._matte()
        if cfg.render.amodal_mask == "render":
            mask = sc.view_layers.new("mask")
            mask.use_pass_object_index = True
            mask.use_pass_z = False
            for name in ("others", "background"):
                mask.layer_collection.children[name].exclude = True
            mask.use_pass_combined = False
        self.set_time(0.0)

    def _camera(self) -> None:
        """The camera object with the sensor's intrinsics (focal length and principal point as lens and shift)."""
        cfg = self.cfg
        cam_data = bpy.data.cameras.new("camera")
        k = cfg.sensor.intrinsics()
        cam_data.sensor_fit = "HORIZONTAL" if self.width >= self.height else "VERTICAL"
        cam_data.sensor_width = cfg.sensor.sensor_width_mm
        cam_data.sensor_height = cfg.sensor.sensor_width_mm
        cam_data.lens = cfg.sensor.lens_mm()  # the schema keeps it and the sensor size where Blender keeps them
        cam_data.shift_x = -(k.cx - self.width / 2) / max(self.width, self.height)
        cam_data.shift_y = (k.cy - self.height / 2) / max(self.width, self.height)
        cam_data.clip_start, cam_data.clip_end = 0.01, 1e5
        self.camera = bpy.data.objects.new("camera", cam_data)
        self.scene.collection.objects.link(self.camera)
        self.scene.camera = self.camera
        self._intrinsics = k

    def _lights(self) -> None:
        """The scene file's lights as Blender lamps."""
        for i, light in enumerate(self.cfg.lights):
            data = bpy.data.lights.new(f"light_{i}", light.type.upper())
            data.energy = light.strength
            data.color = light.color
            if light.type == "area":
                data.size = light.size_m
            ob = bpy.data.objects.new(f"light_{i}", data)
            ob.location = light.location
            ob.rotation_euler = tuple(np.radians(light.rotation_deg))
            self.collections["background"].objects.link(ob)

    def _world(self) -> None:
        """The world: a uniform colour, or the environment background's texture."""
        cfg = self.cfg
        world = bpy.data.worlds.new("world")
        self.scene.world = world
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)
            world.use_nodes = True
        bg = next(n for n in world.node_tree.nodes if n.type == "BACKGROUND")
        bg.inputs["Color"].default_value = (*cfg.world.color, 1.0)
        bg.inputs["Strength"].default_value = cfg.world.strength
        if cfg.background.kind == "environment":
            nt = world.node_tree
            coords = nt.nodes.new("ShaderNodeTexCoord")
            colour = texture_colour(nt, cfg.background.material.texture or Texture(type="noise"),
                                    coords.outputs["Generated"])
            nt.links.new(colour, bg.inputs["Color"])

    def _direct_lighting(self) -> None:
        """render.shading = "direct": every material lit in its shader by the suns and the world."""
        from mathutils import Euler, Vector

        cfg = self.cfg
        # a sun shines along its local -Z: the direction to it is +Z rotated
        suns = [(tuple(Euler([float(a) for a in np.radians(light.rotation_deg)], "XYZ").to_matrix()
                       @ Vector((0.0, 0.0, 1.0))),
                 tuple(light.strength * np.asarray(light.color) / np.pi)) for light in cfg.lights]
        ambient = tuple(float(c) * cfg.world.strength for c in cfg.world.color)
        for mat in bpy.data.materials:
            direct_lighting(mat, suns, ambient)

    def _matte(self) -> None:
        """render.specular = false: no glossy lobe (Cycles skips a closure whose weight is zero)."""
        for mat in bpy.data.materials:
            for node in mat.node_tree.nodes if mat.node_tree else ():
                if node.type == "BSDF_PRINCIPLED":
                    node.inputs["Specular IOR Level"].default_value = 0.0
                elif node.type == "MIX_SHADER":  # lean surface: all weight on the diffuse lobe
                    for link in node.inputs["Fac"].links:
                        mat.node_tree.links.remove(link)
                    node.inputs["Fac"].default_value = 0.0

    def _background(self, bg: Background) -> None:
        """The background plane object (kind "plane"); an environment background is the world's."""
        if bg.kind != "plane":
            return
        plane = SceneObject(
            shape="plane",
            size_m=bg.size_m,
            material=bg.material,
            trajectory={
                "keyframes": [{"t": 0, "location": bg.location, "rotation_deg": bg.rotation_deg}],
                "interpolation": "linear",
            },
        )
        self._plane_spec = plane
        self.background_plane = _mesh_object("background", plane, self.collections["background"],
                                             self.cfg.render.surface)
        m, _ = pose_and_scale(plane.trajectory, 0.0)
        self.background_plane.matrix_world = m.T.tolist()

    def _plane_view(self) -> tuple[np.ndarray, float]:
        """((u0, v0, u1, v1), px_per_m): the part of the background plane the camera sees over the whole
        sequence and its largest on-screen density (dvsot.render.plane_view.seen_part)."""
        cfg = self.cfg
        seed = cfg.derived_seed("camera_shake")
        cameras = np.stack([pose_and_scale(cfg.camera, float(t), seed)[0]
                            for t in np.linspace(0.0, cfg.duration_s, _VIEW_SAMPLES)])
        plane_to_world = pose_and_scale(self._plane_spec.trajectory, 0.0)[0]
        return seen_part(plane_to_world, cfg.background.size_m, cameras, self._intrinsics)

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
            self._matrices[ob.pass_index] = m
            if ob is self.target:
                self._target_matrix = m

    def _channels(self) -> list[str]:
        """The EXR channels render() reads: main's colour and object index, and the mask layer's if rendered."""
        names = ["main.Combined", "main.Object Index.X"]
        return names + (["mask.Object Index.X"] if self.cfg.render.amodal_mask == "render" else [])

    def _render_failure(self, t: float, what: str) -> RunError:
        """One line for a render whose image did not come back (t in seconds), naming a full or read-only
        render directory when that is the cause."""
        reason = None
        try:
            st = os.statvfs(self._tmp)
            if st.f_flag & os.ST_RDONLY:
                reason = "Read-only file system"
            elif st.f_bavail * st.f_frsize < self.width * self.height * 4 * 4 * len(self._channels()):
                reason = "No space left on device"  # not room for one uncompressed image of every layer
        except OSError as exc:
            reason = exc.strerror or str(exc)
        if reason:
            return RunError(f"{self._tmp.parent}: Blender cannot write its render at t={t:.6f} s ({reason}); "
                            f"nothing was replaced")
        return RunError(f"{self._tmp}: Blender's render at t={t:.6f} s failed ({what}); nothing was replaced")

    def raster_amodal_mask(self) -> np.ndarray:
        """The amodal target mask at the current pose, from the target's projected triangles (bool HxW)."""
        m = self._target_matrix
        verts = self._target_verts @ m[:3, :3].T + m[:3, 3]
        return silhouette_mask(verts, self._target_tris, self._camera_matrix, self._intrinsics)

    def object_coverage(self) -> dict[int, tuple[np.ndarray, float, float]]:
        """Per object id (the target and the scene file's objects) at the current pose: (its amodal mask on the
        sensor, bool HxW; its silhouette's area on the sensor and in all, pixels), from its projected triangles
        (dvsot.render.raster.silhouette_coverage: the sensor's pixel grid extended past its edges)."""
        out = {}
        for i, (verts, tris) in self._meshes.items():
            m = self._matrices[i]
            out[i] = silhouette_coverage(verts @ m[:3, :3].T + m[:3, 3], tris, self._camera_matrix, self._intrinsics)
        return out

    def render_truth(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict]:
        """render_with_objects(t) and object_coverage() at t seconds, the target's amodal mask taken from the latter
        (raster mode: one rasterisation of the target per sample)."""
        luma, objects, rendered = self._render_passes(t)
        coverage = self.object_coverage()
        amodal = rendered if rendered is not None else coverage[TARGET_INDEX][0]
        return luma, amodal, objects == TARGET_INDEX, objects, coverage

    def render(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(linear luma float32 HxW, amodal target mask bool HxW, visible target mask bool HxW) at t seconds."""
        return self.render_with_objects(t)[:3]

    def render_with_objects(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """render(t) and the object id of each pixel (u1 HxW, dvsot.events.labels' ids) from the same pass."""
        luma, objects, rendered = self._render_passes(t)
        amodal = rendered if rendered is not None else self.raster_amodal_mask()
        return luma, amodal, objects == TARGET_INDEX, objects

    def _render_passes(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """(luma float32 HxW, object ids u1 HxW, the rendered amodal target mask or None in raster mode) at t (s)."""
        import OpenEXR

        self.set_time(t)
        path = self._tmp / "frame.exr"
        self.scene.render.filepath = str(path)
        with quiet_stdout():
            result = bpy.ops.render.render(write_still=True)
        if "FINISHED" not in result or not path.is_file():
            raise self._render_failure(t, "Blender wrote no image")
        channels = {}
        try:  # a failure is worded while the file is still there: a full disk is then still full
            try:
                with captured_output() as printed, OpenEXR.File(str(path)) as f:
                    for part in f.parts:
                        channels.update(part.channels)
            except Exception as exc:  # OpenEXR raises several kinds for a damaged file
                raise self._render_failure(t, f"its image cannot be read: {exception_line(exc, 120)}") from None
            # a file cut short (a full disk) reads with zeros where its pixels are missing: OpenEXR only prints that
            damaged = [line for line in printed[0].splitlines() if "Exception raised" in line or "EXR_ERR" in line]
            if damaged:
                raise self._render_failure(t, f"its image is cut short: {damaged[0].strip()[:120]}")
            missing = [c for c in self._channels() if c not in channels]
            if missing:
                raise self._render_failure(t, f"its image lacks {', '.join(missing)}")
        finally:
            path.unlink(missing_ok=True)
        rgba = channels["main.Combined"].pixels
        luma = rgba[..., :3] @ _LUMA
        objects = np.rint(channels["main.Object Index.X"].pixels).astype(np.uint8)
        rendered = None
        if self.cfg.render.amodal_mask == "render":
            rendered = np.rint(channels["mask.Object Index.X"].pixels) == TARGET_INDEX
        return np.ascontiguousarray(np.maximum(luma, 0.0), np.float32), objects, rendered
