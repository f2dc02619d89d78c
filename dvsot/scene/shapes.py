"""Procedural meshes in numpy (vertices in metres, faces as vertex-index lists), and user mesh files via trimesh.

Every shape is centred at the origin and scaled so its largest extent is 1 m; the scene scales it
to `size_m`. The cat is a composite of ellipsoids and cones (body, head, ears, tail, legs).
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np

from dvsot.core.errors import UserError, exception_line

Mesh = tuple[np.ndarray, list[list[int]]]


def _grid_faces(rows: int, cols: int, wrap_cols: bool, offset: int = 0) -> list[list[int]]:
    faces = []
    ncols = cols if wrap_cols else cols - 1
    for r in range(rows - 1):
        for c in range(ncols):
            c2 = (c + 1) % cols
            faces.append([offset + r * cols + c, offset + r * cols + c2, offset + (r + 1) * cols + c2,
                          offset + (r + 1) * cols + c])
    return faces


def lathe(profile: np.ndarray, segments: int = 32) -> Mesh:
    """Surface of revolution about Z of a (radius, z) profile, with caps at the ends."""
    ang = np.linspace(0, 2 * np.pi, segments, endpoint=False)
    r, z = profile[:, 0], profile[:, 1]
    verts = np.stack([np.outer(r, np.cos(ang)).ravel(), np.outer(r, np.sin(ang)).ravel(),
                      np.repeat(z, segments)], axis=1)
    faces = _grid_faces(len(profile), segments, wrap_cols=True)
    n = len(verts)
    verts = np.vstack([verts, [[0, 0, z[0]], [0, 0, z[-1]]]])
    last = (len(profile) - 1) * segments
    for c in range(segments):
        c2 = (c + 1) % segments
        faces.append([n, c2, c])
        faces.append([n + 1, last + c, last + c2])
    return verts, faces


def ellipsoid(radii=(0.5, 0.5, 0.5), rings: int = 16, segments: int = 32) -> Mesh:
    """A UV ellipsoid with the given semi-axes (m)."""
    theta = np.linspace(0.02, np.pi - 0.02, rings)
    profile = np.stack([np.sin(theta), -np.cos(theta)], axis=1)
    v, f = lathe(profile, segments)
    return v * np.asarray(radii), f


def cube() -> Mesh:
    """A unit cube."""
    v = np.array([[x, y, z] for z in (-0.5, 0.5) for y in (-0.5, 0.5) for x in (-0.5, 0.5)], float)
    f = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]]
    return v, f


def cylinder(segments: int = 32) -> Mesh:
    """A cylinder of diameter 1 and height 1."""
    return lathe(np.array([[0.5, -0.5], [0.5, 0.5]]), segments)


def torus(major: float = 0.35, minor: float = 0.15, rings: int = 32, segments: int = 16) -> Mesh:
    """A torus in the XY plane."""
    u = np.linspace(0, 2 * np.pi, rings, endpoint=False)
    w = np.linspace(0, 2 * np.pi, segments, endpoint=False)
    uu, ww = np.meshgrid(u, w, indexing="ij")
    x = (major + minor * np.cos(ww)) * np.cos(uu)
    y = (major + minor * np.cos(ww)) * np.sin(uu)
    z = minor * np.sin(ww)
    verts = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
    faces = []
    for i in range(rings):
        for j in range(segments):
            i2, j2 = (i + 1) % rings, (j + 1) % segments
            faces.append([i * segments + j, i2 * segments + j, i2 * segments + j2, i * segments + j2])
    return verts, faces


def star(points: int = 5, inner: float = 0.4, depth: float = 0.25) -> Mesh:
    """A star prism: `points` spikes in the XZ plane (facing -Y, towards a default camera), extruded along Y."""
    k = 2 * points
    ang = np.pi / 2 + np.arange(k) * np.pi / points
    rad = np.where(np.arange(k) % 2 == 0, 0.5, 0.5 * inner)
    x, z = rad * np.cos(ang), rad * np.sin(ang)
    front = np.stack([x, np.full(k, -depth / 2), z], axis=1)
    back = np.stack([x, np.full(k, depth / 2), z], axis=1)
    verts = np.vstack([front, back, [[0, -depth / 2, 0], [0, depth / 2, 0]]])
    faces = []
    for i in range(k):
        j = (i + 1) % k
        faces.append([i, j, k + j, k + i])
        faces.append([2 * k, j, i])
        faces.append([2 * k + 1, k + i, k + j])
    return verts, faces


def bottle(segments: int = 32) -> Mesh:
    """A wine-bottle-like surface of revolution (body, shoulder, neck, lip)."""
    profile = np.array([[0.0, -0.5], [0.17, -0.5], [0.18, -0.47], [0.18, 0.05], [0.16, 0.12], [0.1, 0.2],
                        [0.065, 0.26], [0.06, 0.42], [0.07, 0.44], [0.07, 0.5], [0.0, 0.5]])
    return lathe(profile[1:-1], segments)


def _place(mesh: Mesh, scale=(1, 1, 1), offset=(0, 0, 0), tilt_deg: float = 0.0) -> Mesh:
    v, f = mesh
    v = v * np.asarray(scale, float)
    if tilt_deg:
        a = np.radians(tilt_deg)
        rot = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
        v = v @ rot.T
    return v + np.asarray(offset, float), f


def merge(parts: list[Mesh]) -> Mesh:
    """One mesh made of several (faces re-indexed)."""
    verts, faces, n = [], [], 0
    for v, f in parts:
        verts.append(v)
        faces += [[i + n for i in face] for face in f]
        n += len(v)
    return np.vstack(verts), faces


def cat() -> Mesh:
    """A sitting-cat-like composite seen from the front (-Y): body, head, two ears, tail and front legs."""
    cone = lathe(np.array([[0.5, -0.5], [0.01, 0.5]]), 12)
    parts = [
        _place(ellipsoid((0.5, 0.5, 0.5)), (0.42, 0.36, 0.55), (0, 0, -0.12)),       # body
        _place(ellipsoid((0.5, 0.5, 0.5)), (0.34, 0.3, 0.3), (0, -0.05, 0.28)),      # head
        _place(cone, (0.1, 0.06, 0.14), (-0.1, -0.05, 0.46)),                        # ears
        _place(cone, (0.1, 0.06, 0.14), (0.1, -0.05, 0.46)),
        _place(cylinder(12), (0.06, 0.06, 0.4), (0.25, 0.1, -0.2), tilt_deg=35),    # tail
        _place(cylinder(12), (0.08, 0.08, 0.25), (-0.1, -0.12, -0.38)),              # front legs
        _place(cylinder(12), (0.08, 0.08, 0.25), (0.1, -0.12, -0.38)),
    ]
    return merge(parts)


def normalise(mesh: Mesh) -> Mesh:
    """Centre a mesh on its bounding box and scale its largest extent to 1."""
    v, f = mesh
    lo, hi = v.min(axis=0), v.max(axis=0)
    size = float((hi - lo).max())
    if size <= 0:
        raise ValueError("mesh has no extent")
    return (v - (lo + hi) / 2) / size, f


@lru_cache(maxsize=32)  # the scene check, the sample times and the Blender build each ask for it
def load_mesh_file(path: Path) -> Mesh:
    """Vertices and triangles of an OBJ/PLY/STL/GLB/glTF file (via trimesh); UserError if unreadable."""
    import trimesh

    try:
        loaded = trimesh.load(str(path), force="mesh")
    except Exception as exc:  # trimesh raises many kinds for damaged files
        raise UserError(f"{path}: cannot read mesh ({exception_line(exc, 200)})") from None
    if not isinstance(loaded, trimesh.Trimesh) or len(loaded.vertices) == 0 or len(loaded.faces) == 0:
        raise UserError(f"{path}: mesh file holds no triangles")
    # trimesh keeps glTF's Y-up; Blender's importer turns Y-up into Z-up the same way
    v = np.asarray(loaded.vertices, float)
    if path.suffix.lower() in {".glb", ".gltf"}:
        v = v[:, [0, 2, 1]] * np.array([1, -1, 1])
    v.setflags(write=False)  # cached: shared by every caller
    return v, np.asarray(loaded.faces).tolist()


BUILDERS = {"cube": cube, "sphere": ellipsoid, "ball": ellipsoid, "cylinder": cylinder, "torus": torus,
            "star": star, "bottle": bottle, "cat": cat}


def mesh_for(shape: str | None, mesh_path: Path | None) -> Mesh:
    """The unit-size mesh of a primitive shape or a mesh file."""
    if mesh_path is not None:
        return normalise(load_mesh_file(mesh_path))
    if shape == "plane":
        return np.array([[-0.5, -0.5, 0], [0.5, -0.5, 0], [0.5, 0.5, 0], [-0.5, 0.5, 0]], float), [[0, 1, 2, 3]]
    return normalise(BUILDERS[shape]())


def sample_points(mesh: Mesh, n: int, seed: int = 0) -> np.ndarray:
    """Up to n mesh vertices (all when fewer), a deterministic subset, for motion bounds."""
    v = mesh[0]
    if len(v) <= n:
        return v
    return v[np.random.default_rng(seed).choice(len(v), n, replace=False)]
