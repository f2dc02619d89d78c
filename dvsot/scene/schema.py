"""The scene file's schema: a typed, validated description of one labelled event sequence (see
blender_scenes/README.md). Reading and checking a file is dvsot.scene.loader's job.

Units are in the field names or documented per field: seconds (`t`, `duration_s`), metres
(locations, `size_m`), degrees (`rotation_deg`), pixels (`max_displacement_px`), millimetres
(`focal_mm`). Unknown keys are errors.
"""

from __future__ import annotations

import hashlib
from pathlib import Path
from typing import Annotated, Literal

from pydantic import ConfigDict, Field, field_validator, model_validator

from dvsot.core.defaults import SEGMENT_US
from dvsot.core.strict import Bool, Float, Int, Strict  # noqa: F401  (also imported from here: dvsot.scene re-exports them)
from dvsot.events import EventParams

# Sane ranges (dvsot.scene.checks has the checks that need the whole scene): coordinates within 1000 km
# (Blender works in float32), scales within 1e-3..1e3 (0 makes an object vanish, 1e30 swallows the camera)
Coord = Annotated[Float, Field(ge=-1e6, le=1e6)]
Vec3 = tuple[Coord, Coord, Coord]
Scale = Annotated[Float, Field(ge=1e-3, le=1e3)]
Size = Annotated[Float, Field(gt=0, le=1e4, description="metres")]
Colour = tuple[Annotated[Float, Field(ge=0)], Annotated[Float, Field(ge=0)], Annotated[Float, Field(ge=0)]]
# Blender's camera clamps its lens (focal length) and sensor size into [1 mm, float32 max]: a value outside would be
# rendered as another camera than the one the ground truth projects with, so the schema refuses it
CAMERA_MM = (1.0, 3.4028234663852886e38)
DEFAULT_FOCAL_MM = 35.0  # the lens of a sensor that gives neither focal_mm nor fx


def _camera_mm_problem(value: float) -> str | None:
    """Why a lens or sensor size (mm) is one Blender's camera would change, or None if it keeps it."""
    lo, hi = CAMERA_MM
    if lo <= value <= hi:
        return None
    return f"must be between {lo:g} and {hi:.4g} mm (Blender's camera clamps it into that range), got {value:g}"


class SceneEvents(EventParams):
    """The scene file's `events:` block: EventParams with the file's strict number rules (no "0.2", no true)."""

    model_config = ConfigDict(strict=True)

    @field_validator("*", mode="before")
    @classmethod
    def _no_flags(cls, value: object) -> object:
        """No field of the block is a flag: true/false is refused also where a Literal of numbers would match it."""
        if isinstance(value, bool):
            raise ValueError(f"Input should be a number, not {str(value).lower()}")
        return value


class Sensor(Strict):
    """Image size (pixels) and lens: focal_mm + sensor_width_mm, or fx (+ cx, cy) in pixels."""

    width: Int = Field(640, ge=8, le=8192)
    height: Int = Field(480, ge=8, le=8192)
    focal_mm: Float | None = None  # CAMERA_MM
    sensor_width_mm: Float = 36.0  # CAMERA_MM
    fx: Float | None = Field(None, gt=0, description="focal length in pixels (overrides focal_mm)")
    fy: Float | None = Field(None, gt=0, description="must equal fx: square pixels")
    cx: Float | None = None  # pixels, within float32's range (_principal_point)
    cy: Float | None = None

    @field_validator("focal_mm", "sensor_width_mm")
    @classmethod
    def _camera_mm(cls, value: float | None) -> float | None:
        problem = None if value is None else _camera_mm_problem(value)
        if problem:
            raise ValueError(problem)
        return value

    @field_validator("cx", "cy")
    @classmethod
    def _principal_point(cls, value: float | None) -> float | None:
        # Blender stores the principal point as a float32 camera shift, (c - size / 2) / max side, clamped to
        # float32's range; within +-float32 max pixels the shift always fits
        if value is not None and abs(value) > CAMERA_MM[1]:
            raise ValueError(f"must be between {-CAMERA_MM[1]:.4g} and {CAMERA_MM[1]:.4g} px (Blender's camera "
                             f"shift is a 32-bit float), got {value:g}")
        return value

    @model_validator(mode="after")
    def _lens(self) -> Sensor:
        if self.fy is not None and self.fx is not None and abs(self.fy - self.fx) > 1e-6 * self.fx:
            raise ValueError("fy must equal fx (square pixels)")
        if self.fy is not None and self.fx is None:
            raise ValueError("fy given without fx")
        if self.fx is not None and _camera_mm_problem(self.lens_mm()):
            px = max(self.width, self.height)
            lo, hi = (m / self.sensor_width_mm * px for m in CAMERA_MM)
            raise ValueError(f"fx must be between {lo:g} and {hi:.4g} px with sensor_width_mm {self.sensor_width_mm:g} "
                             f"and a {px} px image side (a lens of 1 mm or more: Blender's camera clamps shorter "
                             f"ones), got {self.fx:g}")
        return self

    def lens_mm(self) -> float:
        """The focal length (mm) of Blender's camera for this sensor: fx in pixels on sensor_width_mm."""
        if self.fx is None:
            return self.focal_mm or DEFAULT_FOCAL_MM
        return self.fx * self.sensor_width_mm / max(self.width, self.height)

    def intrinsics(self):
        """Pixel intrinsics of this sensor."""
        from dvsot.scene.trajectory import Intrinsics

        px = max(self.width, self.height)
        fx = self.fx if self.fx is not None else (self.focal_mm or DEFAULT_FOCAL_MM) / self.sensor_width_mm * px
        cx = self.cx if self.cx is not None else self.width / 2
        cy = self.cy if self.cy is not None else self.height / 2
        return Intrinsics(fx, cx, cy, self.width, self.height)


class Keyframe(Strict):
    """A pose at time t (seconds): location (m), rotation (Euler XYZ degrees) or look_at (m), scale."""

    t: Float = Field(ge=0)
    location: Vec3 | None = None
    rotation_deg: Vec3 | None = None
    look_at: Vec3 | None = None
    scale: Scale | tuple[Scale, Scale, Scale] | None = None

    @model_validator(mode="after")
    def _one_rotation(self) -> Keyframe:
        if self.rotation_deg is not None and self.look_at is not None:
            raise ValueError("give rotation_deg or look_at, not both")
        return self


class Trajectory(Strict):
    """Keyframes in time order; linear or smooth (Catmull-Rom) interpolation; optional hand-held shake."""

    keyframes: list[Keyframe] = Field(min_length=1)
    interpolation: Literal["linear", "smooth"] = "smooth"
    shake_deg: Float = Field(0.0, ge=0, le=20, description="hand-held rotation jitter amplitude, degrees")
    shake_hz: Float = Field(1.5, gt=0, le=50)

    @model_validator(mode="after")
    def _ordered(self) -> Trajectory:
        ts = [k.t for k in self.keyframes]
        if any(b <= a for a, b in zip(ts, ts[1:])):
            raise ValueError("keyframe times must increase")
        first = self.keyframes[0]
        if first.location is None:
            raise ValueError("the first keyframe needs a location")
        kinds = {("look_at" if k.look_at is not None else "rotation") for k in self.keyframes
                 if k.look_at is not None or k.rotation_deg is not None}
        if len(kinds) > 1:
            raise ValueError("use either rotation_deg or look_at in all keyframes of a trajectory")
        return self


TextureKind = Literal["noise", "voronoi", "wave", "brick", "checker", "magic", "gradient", "image",
                      "galaxy", "mountain", "city", "sea", "window", "flower"]


class Texture(Strict):
    """A procedural texture (Blender shader nodes) or an image file, mapped through a colour ramp."""

    type: TextureKind
    scale: Float = Field(5.0, gt=0)
    detail: Float = Field(4.0, ge=0, le=15)
    distortion: Float = Field(0.0, ge=0)
    colors: list[Colour] | None = Field(None, min_length=2, description="linear RGB ramp, dark to light")
    path: Path | None = Field(None, description="image file, for type: image")
    seed: Float = Field(0.0, description="offset of the procedural pattern (its 'W' coordinate)")

    @model_validator(mode="after")
    def _image(self) -> Texture:
        if (self.type == "image") != (self.path is not None):
            raise ValueError("type: image needs path, and path is only for type: image")
        return self


class Material(Strict):
    """Surface: a base colour (linear RGB), optionally a texture; emission makes it self-lit."""

    color: Colour = (0.8, 0.8, 0.8)
    texture: Texture | None = None
    roughness: Float = Field(0.6, ge=0, le=1)
    emission: Float = Field(0.0, ge=0, description="emission strength (W/m^2-ish), 0 = none")


Shape = Literal["cube", "sphere", "ball", "cylinder", "torus", "star", "bottle", "cat", "plane"]


class SceneObject(Strict):
    """An object: a primitive `shape` or a `mesh` file, its size, material and trajectory."""

    name: str | None = None
    shape: Shape | None = None
    mesh: Path | None = Field(None, description="OBJ, PLY, STL, GLB or glTF file")
    size_m: Size = Field(1.0, description="largest extent after scaling, metres")
    material: Material = Material()
    trajectory: Trajectory

    @model_validator(mode="after")
    def _one_source(self) -> SceneObject:
        if (self.shape is None) == (self.mesh is None):
            raise ValueError("give exactly one of shape or mesh")
        if self.mesh is not None and self.mesh.suffix.lower() not in {".obj", ".ply", ".stl", ".glb", ".gltf"}:
            raise ValueError(f"mesh {self.mesh.name}: unsupported type (OBJ, PLY, STL, GLB, glTF)")
        return self


class Extra(SceneObject):
    """Another object: an occluder (may pass in front of the target) or a distractor (moves elsewhere)."""

    role: Literal["occluder", "distractor"] = "distractor"


class Background(Strict):
    """A textured plane (wall) behind the scene, or an environment (world) texture."""

    kind: Literal["plane", "environment"] = "plane"
    material: Material = Material(texture=Texture(type="noise"))
    location: Vec3 = (0.0, 8.0, 0.0)
    rotation_deg: Vec3 = (90.0, 0.0, 0.0)
    size_m: Size = 40.0


class Light(Strict):
    """A light: sun (direction from rotation), point or area (location); strength in Blender units."""

    type: Literal["sun", "point", "area"] = "sun"
    strength: Float = Field(3.0, ge=0)
    color: Colour = (1.0, 1.0, 1.0)
    location: Vec3 = (0.0, -6.0, 6.0)
    rotation_deg: Vec3 = (40.0, 0.0, 20.0)
    size_m: Size = 1.0


class World(Strict):
    """Ambient light from the world: a uniform colour and strength."""

    color: Colour = (0.05, 0.05, 0.05)
    strength: Float = Field(1.0, ge=0)


class Render(Strict):
    """Renderer settings: Cycles on the CPU, its seed fixed so static pixels do not flicker.

    Only Cycles is offered: Workbench does not show procedural shader textures, and EEVEE takes tens
    of seconds a frame on a CPU without a GPU.
    """

    engine: Literal["cycles"] = "cycles"
    samples: Int = Field(1, ge=1, le=4096)
    threads: Int = Field(0, ge=0, description="0 = all cores")
    max_bounces: Int = Field(2, ge=0, le=32)
    persistent_data: Bool = True
    amodal_mask: Literal["raster", "render"] = Field(
        "raster", description="raster: project the target's triangles (exact, fast); render: a second Cycles view layer"
    )
    specular: Bool = Field(
        True, description="false: matte materials (no specular layer of the Principled BSDF); faster, duller look")
    shading: Literal["path", "direct"] = Field(
        "path", description="path: Cycles path tracing; direct: Lambert lighting from the suns and the world "
                            "evaluated in each surface's shader (no shadows, no specular, no bounces); much faster")
    surface: Literal["lean", "principled"] = Field(
        "lean", description="lean: Lambert diffuse + GGX glossy mixed by Fresnel (IOR 1.5), the classic dielectric; "
                            "principled: Blender's Principled BSDF (layered, energy-compensated; slower)")
    bake_background: Literal["auto", True, False] = Field(
        "auto", description="bake the background plane's procedural texture into an image once, before the first "
                           "render; true: any procedural kind; auto: only the smooth, costly ones (noise, voronoi, "
                           "wave, magic and their presets), not brick/checker/gradient; false: never")
    bake_texels_per_px: Float = Field(2.0, gt=0, le=8, description="bake texels per on-screen pixel (closest approach)")
    bake_max_size: Int = Field(4096, ge=64, le=16384, description="largest side of the bake image, texels")
    bake_samples: Int = Field(1, ge=1, le=64, description="Cycles samples per texel of the bake")


class Sampling(Strict):
    """Motion-bounded render times: no visible point moves more than max_displacement_px between samples."""

    max_displacement_px: Float = Field(0.75, gt=0, le=10)
    min_rate_hz: Float = Field(100.0, gt=0)
    max_rate_hz: Float = Field(5000.0, gt=0, le=1e6)  # the file's 1 us resolution: no two samples share one
    points_per_object: Int = Field(400, ge=8, le=100000)
    extra_times_ms: list[Annotated[Float, Field(ge=0)]] = Field(
        [], max_length=100000, description="milliseconds: render these instants too (ground truth exactly there)")

    @model_validator(mode="after")
    def _rates(self) -> Sampling:
        if self.max_rate_hz < self.min_rate_hz:
            raise ValueError("max_rate_hz must be >= min_rate_hz")
        return self


class SceneConfig(Strict):
    """One scene file: everything needed to make one labelled event sequence."""

    name: str = Field(pattern=r"^[A-Za-z0-9_.-]+$")
    split: Literal["train", "test", ""] = ""
    description: str = ""
    challenges: list[str] = []
    seed: Int = Field(0, ge=0, le=2**63 - 1, description="master seed: every other seed derives from it")
    duration_s: Float = Field(ge=0.001, le=600, description="seconds; at least 1 ms")
    segment_ms: Float = Field(SEGMENT_US / 1000, ge=1, le=60_000,
                              description="milliseconds, at least 1 (dvsot.core.bounds)")
    sensor: Sensor = Sensor()
    camera: Trajectory
    target: SceneObject
    objects: list[Extra] = []
    background: Background = Background()
    lights: list[Light] = [Light()]
    world: World = World()
    render: Render = Render()
    events: SceneEvents = SceneEvents()
    sampling: Sampling = Sampling()

    @model_validator(mode="after")
    def _extra_times_inside(self) -> SceneConfig:
        late = [t for t in self.sampling.extra_times_ms if t > self.duration_s * 1000]
        if late:
            raise ValueError(f"sampling.extra_times_ms holds {late[0]:g}, after the scene's end "
                             f"({self.duration_s * 1000:g} ms)")
        return self

    @model_validator(mode="after")
    def _direct_shading_lights(self) -> SceneConfig:
        if self.render.shading == "direct":
            for i, light in enumerate(self.lights):
                if light.type != "sun":
                    raise ValueError(f"lights[{i}].type is {light.type!r}: render.shading 'direct' lights with "
                                     "suns only (use shading 'path' for point and area lights)")
        return self

    def derived_seed(self, purpose: str) -> int:
        """A seed for one purpose (events, shake, ...) derived from the master seed."""
        digest = hashlib.sha256(f"{self.seed}:{purpose}".encode()).digest()
        return int.from_bytes(digest[:4], "little")
