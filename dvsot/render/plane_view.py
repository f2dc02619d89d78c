"""Which part of a static textured plane a moving camera sees, and how finely: the geometry behind baking
the background plane's texture (dvsot.render.blender.bake), pure numpy so that it is tested without Blender."""

from __future__ import annotations

import numpy as np

from dvsot.scene.trajectory import Intrinsics

WHOLE = np.array([0.0, 0.0, 1.0, 1.0])


def seen_part(plane_to_world: np.ndarray, size_m: float, cameras: np.ndarray,
              k: Intrinsics) -> tuple[np.ndarray, float]:
    """((u0, v0, u1, v1), px_per_m): the part of a square plane (side size_m, its local x/y axes the
    first two columns of plane_to_world) seen from the camera poses cameras (N x 4 x 4 camera-to-world,
    looking along -z), in the plane's 0..1 coordinates with a margin (the whole plane when some view ray
    misses it), and its largest on-screen density (pixels per metre at the closest approach)."""
    axes, normal, centre = plane_to_world[:3, :2], plane_to_world[:3, 2], plane_to_world[:3, 3]
    # image corners as camera-space directions (x right, y up, looking along -z): the frustum meets
    # the plane in a quadrilateral whose corners are these rays' hits
    corners = np.array([[(u - k.cx) / k.fx, -(v - k.cy) / k.fx, -1.0]
                        for u in (0.0, float(k.width)) for v in (0.0, float(k.height))])
    hits, distance = [], np.inf
    for cam in cameras:
        rays, origin = corners @ cam[:3, :3].T, cam[:3, 3]
        distance = min(distance, abs(float(normal @ (origin - centre))))
        with np.errstate(divide="ignore", invalid="ignore"):
            s = float(normal @ (centre - origin)) / (rays @ normal)
        hits.append(((origin + s[:, None] * rays) - centre) @ axes / size_m + 0.5 if np.all(s > 0) else None)
    px_per_m = k.fx / max(distance, 1e-3)
    if any(h is None for h in hits):
        return WHOLE.copy(), px_per_m
    uv = np.concatenate(hits)
    lo, hi = uv.min(0), uv.max(0)
    pad = 0.1 * (hi - lo) + 4.0 / (px_per_m * size_m)  # camera shake between the sampled times
    lo, hi = np.clip(lo - pad, 0.0, 1.0), np.clip(hi + pad, 0.0, 1.0)
    if np.any(hi - lo <= 0):
        return WHOLE.copy(), px_per_m
    return np.concatenate([lo, hi]), px_per_m


def bake_sides(rect: np.ndarray, px_per_m: float, size_m: float, texels_per_px: float,
               max_size: int) -> tuple[tuple[int, int], tuple[int, int]]:
    """(near, far) image sizes (width, height) in texels: the seen part rect at texels_per_px texels per
    on-screen pixel, the whole plane at 1/8 of that; each side 16..max_size."""
    u0, v0, u1, v1 = rect
    texels_per_m = texels_per_px * px_per_m

    def side(extent: float, per_m: float) -> int:
        return int(np.clip(np.ceil(per_m * extent * size_m), 16, max_size))

    return ((side(u1 - u0, texels_per_m), side(v1 - v0, texels_per_m)),
            (side(1.0, texels_per_m / 8), side(1.0, texels_per_m / 8)))


def plane_uvs(xy: np.ndarray, size_m: float, rect: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(whole, view) UVs (N x 2) of plane-local points xy (N x 2, metres): the whole plane's 0..1 coordinates
    (one texel is one fixed patch of wall) and the same mapped so that rect spans 0..1."""
    whole = np.asarray(xy, np.float64) / size_m + 0.5
    lo, hi = np.asarray(rect[:2]), np.asarray(rect[2:])
    return whole, (whole - lo) / (hi - lo)
