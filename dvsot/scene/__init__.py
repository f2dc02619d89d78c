"""The scene file: its schema (dvsot.scene.schema, pydantic) and its loader (dvsot.scene.loader: YAML, overrides,
whole-scene checks, asset files); the names callers use are re-exported here."""

from dvsot.scene.loader import (Locate, asset_paths, load_scene, parse_scene, read_scene_text, read_yaml,
                                 validate_scene, yaml_value)
from dvsot.scene.schema import (Background, Colour, Coord, Extra, Float, Int, Keyframe, Light, Material, Render,
                                 Sampling, Scale, SceneConfig, SceneObject, Sensor, Shape, Size, Strict, Texture,
                                 TextureKind, Trajectory, Vec3, World)

__all__ = ["Background", "Colour", "Coord", "Extra", "Float", "Int", "Keyframe", "Light", "Locate", "Material",
           "Render", "Sampling", "Scale", "SceneConfig", "SceneObject", "Sensor", "Shape", "Size", "Strict", "Texture",
           "TextureKind", "Trajectory", "Vec3", "World", "asset_paths", "load_scene", "parse_scene",
           "read_scene_text", "read_yaml", "validate_scene", "yaml_value"]
