"""The scene file: a typed, validated description of one labelled event sequence (see blender_scenes/README.md).

Units are in the field names or documented per field: seconds (`t`, `duration_s`), metres
(locations, `size_m`), degrees (`rotation_deg`), pixels (`max_displacement_px`), millimetres
(`focal_mm`). Unknown keys are errors. `load_scene` turns every problem into one line naming the
file, the field, the YAML line and what is wrong.
"""

from __future__ import annotations

import hashlib
from pathlib import Path
from typing import Annotated, Any, Callable, Literal

from pydantic import BaseModel, ConfigDict, Field, Strict as StrictType, ValidationError, model_validator

from dvsot import validate, yamlio
from dvsot.errors import UserError
from dvsot.events import EventParams
from dvsot.scene_checks import scene_problems

# Numbers must be numbers: no "1.6" strings or true/false where a number goes (an int is a fine float)
Float = Annotated[float, StrictType()]
Int = Annotated[int, StrictType()]
# Sane ranges (dvsot.scene_checks has the checks that need the whole scene): coordinates within 1000 km
# (Blender works in float32), scales within 1e-3..1e3 (0 makes an object vanish, 1e30 swallows the camera)
Coord = Annotated[Float, Field(ge=-1e6, le=1e6)]
Vec3 = tuple[Coord, Coord, Coord]
Scale = Annotated[Float, Field(ge=1e-3, le=1e3)]
Size = Annotated[Float, Field(gt=0, le=1e4, description="metres")]
Colour = tuple[Annotated[Float, Field(ge=0)], Annotated[Float, Field(ge=0)], Annotated[Float, Field(ge=0)]]


class Strict(BaseModel):
    """Base model: unknown keys are errors, and so are NaN and infinite numbers."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


class Sensor(Strict):
    """Image size (pixels) and lens: focal_mm + sensor_width_mm, or fx (+ cx, cy) in pixels."""

    width: Int = Field(640, ge=8, le=8192)
    height: Int = Field(480, ge=8, le=8192)
    focal_mm: Float | None = Field(None, gt=0)
    sensor_width_mm: Float = Field(36.0, gt=0)
    fx: Float | None = Field(None, gt=0, description="focal length in pixels (overrides focal_mm)")
    fy: Float | None = Field(None, gt=0, description="must equal fx: square pixels")
    cx: Float | None = None
    cy: Float | None = None

    @model_validator(mode="after")
    def _lens(self) -> "Sensor":
        if self.fy is not None and self.fx is not None and abs(self.fy - self.fx) > 1e-6 * self.fx:
            raise ValueError("fy must equal fx (square pixels)")
        if self.fy is not None and self.fx is None:
            raise ValueError("fy given without fx")
        return self

    def intrinsics(self):
        """Pixel intrinsics of this sensor."""
        from dvsot.trajectory import Intrinsics

        fx = self.fx if self.fx is not None else (self.focal_mm or 35.0) / self.sensor_width_mm * max(self.width, self.height)
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
    def _one_rotation(self) -> "Keyframe":
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
    def _ordered(self) -> "Trajectory":
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
    def _image(self) -> "Texture":
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
    def _one_source(self) -> "SceneObject":
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
    persistent_data: bool = True
    amodal_mask: Literal["raster", "render"] = Field(
        "raster", description="raster: project the target's triangles (exact, fast); render: a second Cycles view layer")
    specular: bool = Field(
        True, description="false: matte materials (no specular layer of the Principled BSDF); ~25% faster, duller look")
    shading: Literal["path", "direct"] = Field(
        "path", description="path: Cycles path tracing; direct: Lambert lighting from the suns and the world "
                            "evaluated in each surface's shader (no shadows, no specular, no bounces); ~2x faster")
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

    @model_validator(mode="after")
    def _rates(self) -> "Sampling":
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
    segment_ms: Float = Field(10.0, ge=1, le=60_000, description="milliseconds, at least 1 (dvsot.validate)")
    sensor: Sensor = Sensor()
    camera: Trajectory
    target: SceneObject
    objects: list[Extra] = []
    background: Background = Background()
    lights: list[Light] = [Light()]
    world: World = World()
    render: Render = Render()
    events: dict[str, Any] = Field(default_factory=dict, description="EventParams fields")
    sampling: Sampling = Sampling()

    @model_validator(mode="after")
    def _direct_shading_lights(self) -> "SceneConfig":
        if self.render.shading == "direct":
            for i, light in enumerate(self.lights):
                if light.type != "sun":
                    raise ValueError(f"lights[{i}].type is {light.type!r}: render.shading 'direct' lights with "
                                     "suns only (use shading 'path' for point and area lights)")
        return self

    def event_params(self) -> EventParams:
        """The validated event-generator parameters."""
        return EventParams(**self.events)

    def derived_seed(self, purpose: str) -> int:
        """A seed for one purpose (events, shake, ...) derived from the master seed."""
        digest = hashlib.sha256(f"{self.seed}:{purpose}".encode()).digest()
        return int.from_bytes(digest[:4], "little")


def _field_loc(loc: tuple) -> tuple:
    """A pydantic error location without its validator and union-member tags ('function-after[..]', 'constrained-float')."""
    return tuple(p for p in loc if not (isinstance(p, str) and ("-" in p or "[" in p)))


def _chosen_error(errors: list[dict]) -> dict:
    """The error to report: the first, but for a union (one field, an error per member) the member whose type
    matched (a range error, not 'should be a valid number' from the member of another type)."""
    first = _field_loc(errors[0]["loc"])
    same = [e for e in errors if _field_loc(e["loc"])[:len(first)] == first]
    return next((e for e in same if not e["type"].endswith("_type")), errors[0])


def _line_of(node: yamlio.Node | None, loc: tuple) -> int | None:
    """The 1-based YAML line of the field at loc (or of its nearest existing parent)."""
    line = node.start_mark.line + 1 if node is not None else None
    for key in loc:
        if isinstance(node, yamlio.MappingNode):
            found = None
            for k, v in node.value:
                if k.value == key:
                    found = (k, v)
                    break
            if found is None:
                break
            line, node = found[0].start_mark.line + 1, found[1]
        elif isinstance(node, yamlio.SequenceNode) and isinstance(key, int) and key < len(node.value):
            node = node.value[key]
            line = node.start_mark.line + 1
        else:
            break
    return line


Locate = Callable[[tuple], "int | None"]  # field path (keys, list indices) -> its 1-based line in the file


def read_yaml(text: str, source: str = "<scene>") -> tuple[Any, Locate]:
    """Parse YAML text as a scene file is read: (data, locate), locate(loc) the line of a field. Raises UserError."""
    problem = validate.yaml_text_problem(text)  # size and depth, before a parser that recurses per level
    if problem:
        raise UserError(f"{source}: {problem}")
    try:
        node = yamlio.compose(text)
        problem = validate.yaml_nodes_problem(node)  # before anything expands the aliases
        if problem:
            raise UserError(f"{source}: {problem}")
        twice = yamlio.duplicate_key(node)  # YAML forbids it; a plain loader would keep the last silently
        if twice:
            key, first, again = twice
            raise UserError(f"{source}:{again}: field '{key}' is given twice (first on line {first})")
        data = yamlio.load(text)
    except yamlio.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f":{mark.line + 1}" if mark else ""
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise UserError(f"{source}{where}: YAML syntax error: {problem}") from None
    return data, lambda loc: _line_of(node, tuple(loc))


def parse_scene(text: str, source: str = "<scene>", base_dir: Path | None = None,
                overrides: dict[str, Any] | None = None) -> SceneConfig:
    """Validate scene YAML text; relative asset paths resolve against base_dir. Raises UserError."""
    data, locate = read_yaml(text, source)
    return validate_scene(data, source, locate, base_dir, overrides)


def validate_scene(data: Any, source: str, locate: Locate, base_dir: Path | None = None,
                   overrides: dict[str, Any] | None = None) -> SceneConfig:
    """Validate scene data read from `source`; errors name the field and its line (from locate). Raises UserError."""
    if not isinstance(data, dict):
        raise UserError(f"{source}: a scene file must be a mapping of fields, got {type(data).__name__}")
    for key, value in (overrides or {}).items():
        _set_path(data, key, value, source, locate)
    try:
        cfg = SceneConfig.model_validate(data)
    except ValidationError as exc:
        err = _chosen_error(exc.errors())
        loc = _field_loc(err["loc"])
        field = ".".join(str(p) for p in loc) or "(top level)"
        msg = err["msg"].removeprefix("Value error, ")
        if err["type"] == "extra_forbidden":
            msg = "unknown field"
        if field in (overrides or {}):  # the value came from the command line, not from the file
            raise UserError(f"{source}: field '{field}' = {overrides[field]!r} (an override): {msg}") from None
        line = locate(loc)
        raise UserError(f"{source}{f':{line}' if line else ''}: field '{field}': {msg}") from None
    try:
        cfg.event_params()
    except ValidationError as exc:
        err = exc.errors()[0]
        field = "events." + ".".join(str(p) for p in err["loc"])
        line = locate(tuple(field.split(".")))
        msg = "unknown field" if err["type"] == "extra_forbidden" else err["msg"]
        raise UserError(f"{source}{f':{line}' if line else ''}: field '{field}': {msg}") from None
    for loc, msg in scene_problems(cfg):
        line = locate(loc)
        raise UserError(f"{source}{f':{line}' if line else ''}: field '{'.'.join(map(str, loc))}': {msg}")
    _check_assets(cfg, source, base_dir or Path("."), locate)
    return cfg


def yaml_value(text: str) -> Any:
    """One YAML value as a scene file would read it (for KEY=VALUE overrides on a command line)."""
    return yamlio.load(text)


def _set_path(data: dict, dotted: str, value: Any, source: str, locate: Locate) -> None:
    """Set the field `dotted` (a.b.c) to an override's value; UserError if the file has no mapping there."""
    keys = dotted.split(".")
    for i, k in enumerate(keys[:-1]):
        if data.get(k) is None and k not in data:
            data[k] = {}
        data = data[k]
        if not isinstance(data, dict):
            loc = tuple(keys[:i + 1])
            line = locate(loc)
            raise UserError(f"{source}{f':{line}' if line else ''}: field '{'.'.join(loc)}' must be a mapping "
                            f"(to set {dotted} from the command line), got {type(data).__name__}")
    data[keys[-1]] = value


def asset_paths(cfg: SceneConfig) -> list[Path]:
    """The mesh and image files a loaded scene reads (absolute paths)."""
    materials = [cfg.target.material, cfg.background.material] + [o.material for o in cfg.objects]
    meshes = [o.mesh for o in [cfg.target, *cfg.objects] if o.mesh is not None]
    return meshes + [m.texture.path for m in materials if m.texture is not None and m.texture.path is not None]


def _check_assets(cfg: SceneConfig, source: str, base: Path, locate: Locate) -> None:
    """Resolve mesh and image paths against the scene file's folder and read each once: a missing or
    unreadable file is an error here, before anything is rendered (Blender itself only warns)."""
    def fix(obj: Any, attr: str, loc: tuple, read) -> None:
        p = getattr(obj, attr)
        if p is None:
            return
        full = p if p.is_absolute() else (base / p)
        line = locate(loc)
        where = f"{source}{f':{line}' if line else ''}: field '{'.'.join(map(str, loc))}'"
        kind = validate.file_kind_problem(full)
        if kind:
            raise UserError(f"{where}: " + (f"file not found: {full}" if kind == "no such file" else
                                          f"{full} {kind}, not a regular file"))
        try:
            read(full.resolve())
        except UserError as exc:
            raise UserError(f"{where}: {exc}") from None
        setattr(obj, attr, full.resolve())

    def material(m: Material, loc: tuple) -> None:
        if m.texture is not None:
            fix(m.texture, "path", loc + ("texture", "path"), _read_image)

    from dvsot.shapes import load_mesh_file

    fix(cfg.target, "mesh", ("target", "mesh"), load_mesh_file)
    material(cfg.target.material, ("target", "material"))
    material(cfg.background.material, ("background", "material"))
    for i, o in enumerate(cfg.objects):
        fix(o, "mesh", ("objects", i, "mesh"), load_mesh_file)
        material(o.material, ("objects", i, "material"))


def _read_image(path: Path) -> None:
    """Decode an image texture once (OpenCV; OpenEXR for .exr); UserError if it holds no pixels."""
    if path.suffix.lower() == ".exr":
        import OpenEXR

        try:
            with OpenEXR.File(str(path)) as f:
                ok = any(part.channels for part in f.parts)
        except Exception as exc:  # OpenEXR raises several kinds for damaged files
            raise UserError(f"{path}: cannot read image ({' '.join(str(exc).split())[:200]})") from None
    else:
        from dvsot.frames import imread

        ok = imread(path) is not None
    if not ok:
        raise UserError(f"{path}: cannot read image (not an image file OpenCV or OpenEXR can decode)")


def read_scene_text(path: str | Path, what: str = "scene") -> str:
    """The text of a scene (or template) file: a regular file of at most MAX_SCENE_BYTES; UserError otherwise."""
    p = Path(path)
    kind = validate.file_kind_problem(p)  # checked first: reading a FIFO would wait forever
    if kind:
        raise UserError(f"{p}: " + (f"no such {what} file" if kind == "no such file" else f"{kind}, not a {what} file"))
    try:
        size = p.stat().st_size
        if size > validate.MAX_SCENE_BYTES:
            raise UserError(f"{p}: {size} bytes, more than the bound of {validate.MAX_SCENE_BYTES} bytes (1 MB) "
                            f"for a {what} file")
        return p.read_text()
    except FileNotFoundError:
        raise UserError(f"{p}: no such {what} file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise UserError(f"{p}: cannot read {what} file ({exc})") from None


def load_scene(path: str | Path, overrides: dict[str, Any] | None = None) -> SceneConfig:
    """Read and validate a scene file; every problem raises UserError naming file, field and line."""
    p = Path(path)
    return parse_scene(read_scene_text(p), str(p), p.parent, overrides)
