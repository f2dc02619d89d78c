"""The only package that imports bpy: scene building and rendering behind `BlenderScene`."""

from dvsot.blender.scene import BlenderScene

__all__ = ["BlenderScene"]
