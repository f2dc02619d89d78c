"""The only package that imports bpy: scene building and rendering behind `BlenderScene`."""

from dvsot.render.blender.scene import BlenderScene

__all__ = ["BlenderScene", "blender_version"]


def blender_version() -> str:
    """The running Blender's version string (bpy.app.version_string), for a dataset file's provenance."""
    import bpy

    return bpy.app.version_string
