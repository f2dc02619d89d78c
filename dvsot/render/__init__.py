"""Rendering a scene: Blender (the blender package, the only one that imports bpy), masks without a renderer
(raster), the background bake's plane geometry (plane_view) and motion-bounded sample times (sample_times)."""
