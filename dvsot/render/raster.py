"""Exact silhouette masks without a renderer: project a mesh's triangles and test pixel centres.

Used for the *amodal* target mask (the target alone, nothing hides it): rasterising its projected
triangles gives the same pixels as Blender's object-index pass of a layer holding only the target,
at a fraction of the cost of a second Cycles view layer. Conventions are those of
dvsot.scene.trajectory.project: pixel (col, row) covers [col, col+1) x [row, row+1), its centre is at
(col + 0.5, row + 0.5); the camera looks down -z with y up (Blender camera axes).

Rule: a pixel is in the mask when its centre lies inside (or on an edge of) any triangle. Parts in
front of the camera's near clip plane are clipped away exactly as Blender does (clip_start).
"""

from __future__ import annotations

import numpy as np

from dvsot.scene.trajectory import Intrinsics

NEAR_CLIP_M = 0.01  # BlenderScene's camera clip_start
_MAX_PAIRS = 4_000_000  # (triangle, pixel) tests per numpy batch


def triangulate(faces) -> np.ndarray:
    """(T, 3) vertex indices: each face (a convex polygon, as every built-in shape's faces are) split as a fan."""
    tris = []
    for f in faces:
        f = list(f)
        for i in range(1, len(f) - 1):
            tris.append((f[0], f[i], f[i + 1]))
    return np.asarray(tris, np.int64).reshape(-1, 3)


def _clip_near(cam_tris: np.ndarray, near: float) -> np.ndarray:
    """Triangles (T, 3, 3) in camera coordinates cut to depth >= near (depth = -z); (T', 3, 3)."""
    depth = -cam_tris[..., 2]
    front = depth >= near
    whole = front.all(axis=1)
    out = [cam_tris[whole]]
    for tri in cam_tris[front.any(axis=1) & ~whole]:
        poly = []
        for i in range(3):  # Sutherland-Hodgman against one plane
            a, b = tri[i], tri[(i + 1) % 3]
            da, db = -a[2] - near, -b[2] - near
            if da >= 0:
                poly.append(a)
            if (da >= 0) != (db >= 0):
                poly.append(a + (b - a) * (da / (da - db)))
        for i in range(1, len(poly) - 1):
            out.append(np.stack([poly[0], poly[i], poly[i + 1]])[None])
    return np.concatenate(out) if len(out) > 1 else out[0]


def _projected(verts_world: np.ndarray, tris: np.ndarray, cam_to_world: np.ndarray, k: Intrinsics,
               near: float) -> tuple[np.ndarray, np.ndarray]:
    """(u, v): pixel coordinates (T', 3) of the triangles' corners after the near clip; empty when none is in front."""
    if len(tris) == 0:
        return np.empty((0, 3)), np.empty((0, 3))
    r, c = cam_to_world[:3, :3], cam_to_world[:3, 3]
    cam = (np.asarray(verts_world, np.float64) - c) @ r
    cam_tris = _clip_near(cam[tris], near)
    if len(cam_tris) == 0:
        return np.empty((0, 3)), np.empty((0, 3))
    depth = -cam_tris[..., 2]
    return k.cx + k.fx * cam_tris[..., 0] / depth, k.cy - k.fx * cam_tris[..., 1] / depth


def _fill(u: np.ndarray, v: np.ndarray, width: int, height: int) -> np.ndarray:
    """Bool (height, width) mask of the unit pixels whose centre one of the triangles (u, v) (T, 3) covers."""
    W, H = width, height
    mask = np.zeros((H, W), bool)
    if len(u) == 0:
        return mask
    u, v = u.copy(), v.copy()
    # pixel index ranges whose centres (i + 0.5) can lie inside each triangle's bounding box
    x0 = np.maximum(np.ceil(u.min(1) - 0.5), 0)
    x1 = np.minimum(np.floor(u.max(1) - 0.5), W - 1)
    y0 = np.maximum(np.ceil(v.min(1) - 0.5), 0)
    y1 = np.minimum(np.floor(v.max(1) - 0.5), H - 1)
    area2 = (u[:, 1] - u[:, 0]) * (v[:, 2] - v[:, 0]) - (u[:, 2] - u[:, 0]) * (v[:, 1] - v[:, 0])
    keep = (x1 >= x0) & (y1 >= y0) & (area2 != 0) & np.isfinite(area2)
    if not keep.any():
        return mask
    u, v, area2 = u[keep], v[keep], area2[keep]
    x0, y0 = x0[keep].astype(np.int64), y0[keep].astype(np.int64)
    w = x1[keep].astype(np.int64) - x0 + 1
    n = w * (y1[keep].astype(np.int64) - y0 + 1)
    # orient every triangle counter-clockwise in (u, v) so all three edge functions are >= 0 inside
    flip = area2 < 0
    u[flip] = u[flip][:, [0, 2, 1]]
    v[flip] = v[flip][:, [0, 2, 1]]
    ends = np.cumsum(n)
    start = 0
    while start < len(n):  # batches of whole triangles, a bounded number of pixel tests each
        stop = max(int(np.searchsorted(ends, (ends[start - 1] if start else 0) + _MAX_PAIRS, side="right")),
                   start + 1)
        counts = n[start:stop]
        tri = np.repeat(np.arange(start, stop), counts)
        offset = np.arange(int(counts.sum())) - np.repeat(np.cumsum(counts) - counts, counts)
        px = x0[tri] + offset % w[tri]
        py = y0[tri] + offset // w[tri]
        x, y = px + 0.5, py + 0.5
        inside = np.ones(len(tri), bool)
        tu, tv = u[tri], v[tri]
        for a, b in ((0, 1), (1, 2), (2, 0)):
            inside &= (tu[:, b] - tu[:, a]) * (y - tv[:, a]) - (tv[:, b] - tv[:, a]) * (x - tu[:, a]) >= 0
        mask[py[inside], px[inside]] = True
        start = stop
    return mask


def silhouette_mask(verts_world: np.ndarray, tris: np.ndarray, cam_to_world: np.ndarray, k: Intrinsics,
                    near: float = NEAR_CLIP_M) -> np.ndarray:
    """Bool (height, width) mask of pixels whose centre a projected triangle covers.

    verts_world: (N, 3) vertex positions in metres; tris: (T, 3) indices; cam_to_world: 4x4 camera pose
    (Blender camera axes); k: the sensor intrinsics.
    """
    u, v = _projected(verts_world, tris, cam_to_world, k, near)
    return _fill(u, v, k.width, k.height)


# The whole silhouette is counted on a grid of at most this many cells: a target a few metres past the image's edge,
# or one reaching the near plane, projects to millions of pixels, and a coarser grid counts it in bounded time.
MAX_COVERAGE_CELLS = 1 << 20


def silhouette_coverage(verts_world: np.ndarray, tris: np.ndarray, cam_to_world: np.ndarray, k: Intrinsics,
                        near: float = NEAR_CLIP_M,
                        max_cells: int = MAX_COVERAGE_CELLS) -> tuple[np.ndarray, float, float]:
    """(mask, on_sensor, whole): the on-sensor silhouette mask (bool, height x width, as silhouette_mask) and the
    silhouette's area on the sensor and in all, in sensor pixels, counted on one grid (the pixel-centre rule).

    The silhouette is rasterised over its whole projected extent, not only the sensor: where that extent fits in
    max_cells pixels the grid is the sensor's own pixels extended past its edges (exact at pixel resolution:
    on_sensor is the mask's count, up to ties of a pixel centre on an edge); where it does not, every cell is
    s x s pixels (s the smallest integer that fits, cells aligned with the sensor's corner), and both areas are
    counted on that coarser grid, so their ratio's error is a band of about one cell along the outline. Nothing in front
    of the camera gives (empty mask, 0, 0).
    """
    u, v = _projected(verts_world, tris, cam_to_world, k, near)
    W, H = k.width, k.height
    inside = len(u) and u.min() >= 0 and v.min() >= 0 and u.max() <= W and v.max() <= H
    mask = _fill(u, v, W, H)
    if len(u) == 0 or inside:  # the common case: wholly on the sensor, no wider grid needed
        n = float(np.count_nonzero(mask))
        return mask, n, n
    # the extent in whole pixels, the sensor included (the offsets keep the sensor's pixels on the grid)
    x0, y0 = min(0, int(np.floor(u.min()))), min(0, int(np.floor(v.min())))
    x1, y1 = max(W, int(np.ceil(u.max()))), max(H, int(np.ceil(v.max())))
    s = max(1, int(np.ceil(np.sqrt((x1 - x0) * (y1 - y0) / max_cells))))
    # cells of s pixels with a corner at the sensor's (0, 0): cell c spans pixels [c s, (c + 1) s)
    c0x, c0y = int(np.floor(x0 / s)), int(np.floor(y0 / s))
    c1x, c1y = -(-x1 // s), -(-y1 // s)
    grid = _fill((u - c0x * s) / s, (v - c0y * s) / s, c1x - c0x, c1y - c0y)
    whole = float(np.count_nonzero(grid)) * s * s
    # cells whose centre lies on the sensor, counted on the same grid as the whole (with s = 1: the sensor's pixels)
    cx = (np.arange(c0x, c1x) + 0.5) * s
    cy = (np.arange(c0y, c1y) + 0.5) * s
    on = float(np.count_nonzero(grid[np.ix_((cy >= 0) & (cy < H), (cx >= 0) & (cx < W))])) * s * s
    return mask, on, whole
