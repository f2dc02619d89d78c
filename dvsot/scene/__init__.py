"""The scene file: its schema (dvsot.scene.schema, pydantic) and its loader (dvsot.scene.loader: YAML, overrides,
whole-scene checks, asset files); the names callers use are re-exported here."""

from dvsot.scene.loader import (  # noqa: F401  (the schema's parts: see __all__)
    Locate,
    asset_paths,
    load_scene,
    parse_scene,
    read_scene_text,
    read_yaml,
    validate_scene,
    yaml_value,
)
from dvsot.scene.schema import (  # noqa: F401
    Background,
    Colour,
    Coord,
    Extra,
    Float,
    Int,
    Keyframe,
    Light,
    Material,
    Render,
    Sampling,
    Scale,
    SceneConfig,
    SceneObject,
    Sensor,
    Shape,
    Size,
    Strict,
    Texture,
    TextureKind,
    Trajectory,
    Vec3,
    World,
)

# what a caller of the scene file needs; the schema's parts stay importable from here for the project's modules
__all__ = ["SceneConfig", "load_scene", "parse_scene", "read_scene_text", "read_yaml", "validate_scene", "yaml_value"]
