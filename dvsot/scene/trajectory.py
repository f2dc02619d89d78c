"""Poses over time and pinhole projection, in numpy (no Blender): keyframe interpolation, look-at, camera shake.

Conventions are Blender's: world Z up, metres; Euler angles in degrees, XYZ order; a camera looks
down its local -Z axis with local +Y up. Image pixels: x right, y down, origin at the top-left
corner of the top-left pixel. The same matrices drive the Blender scene and the sampling rule, so
the projected motion the sampler bounds is the motion that is rendered.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def euler_xyz_to_matrix(deg: np.ndarray) -> np.ndarray:
    """Rotation matrix of Blender's XYZ Euler angles (degrees): R = Rz @ Ry @ Rx."""
    x, y, z = np.radians(np.asarray(deg, dtype=np.float64))
    cx, sx, cy, sy, cz, sz = np.cos(x), np.sin(x), np.cos(y), np.sin(y), np.cos(z), np.sin(z)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rz @ ry @ rx


_Z_UP = np.array([0.0, 0.0, 1.0])


def look_at_matrix(eye: np.ndarray, target: np.ndarray, up: np.ndarray = _Z_UP) -> np.ndarray:
    """Rotation whose local -Z points from eye to target and local +Y is as close to `up` as possible."""
    f = np.asarray(target, np.float64) - np.asarray(eye, np.float64)
    f = f / np.linalg.norm(f)
    right = np.cross(f, up)
    if np.linalg.norm(right) < 1e-9:  # looking straight up or down
        right = np.cross(f, np.array([0.0, 1.0, 0.0]))
    right /= np.linalg.norm(right)
    true_up = np.cross(right, f)
    return np.stack([right, true_up, -f], axis=1)


def interpolate(times: np.ndarray, values: np.ndarray, t: float, smooth: bool) -> np.ndarray:
    """Value at t (seconds) of keyframes (times, values (K, D)): linear, or Catmull-Rom through them; clamped ends."""
    times = np.asarray(times, np.float64)
    values = np.asarray(values, np.float64).reshape(len(times), -1)
    if len(times) == 1 or t <= times[0]:
        return values[0].copy()
    if t >= times[-1]:
        return values[-1].copy()
    i = int(np.searchsorted(times, t, side="right")) - 1
    t0, t1 = times[i], times[i + 1]
    u = (t - t0) / (t1 - t0)
    p1, p2 = values[i], values[i + 1]
    if not smooth:
        return p1 + (p2 - p1) * u
    # Catmull-Rom with non-uniform key spacing: tangents from neighbours, scaled to this interval.
    p0 = values[i - 1] if i > 0 else p1
    p3 = values[i + 2] if i + 2 < len(times) else p2
    ta = times[i - 1] if i > 0 else t0 - (t1 - t0)
    tb = times[i + 2] if i + 2 < len(times) else t1 + (t1 - t0)
    m1 = (p2 - p0) / (t1 - ta) * (t1 - t0)
    m2 = (p3 - p1) / (tb - t0) * (t1 - t0)
    u2, u3 = u * u, u * u * u
    return ((2 * u3 - 3 * u2 + 1) * p1 + (u3 - 2 * u2 + u) * m1 + (-2 * u3 + 3 * u2) * p2 + (u3 - u2) * m2)


@dataclass(frozen=True)
class Shake:
    """Hand-held camera shake: a sum of sines per rotation axis, amplitude in degrees, seeded."""

    amplitude_deg: float
    frequency_hz: float
    seed: int

    def offset_deg(self, t: float) -> np.ndarray:
        """Rotation offsets (degrees, XYZ) at time t (seconds)."""
        if self.amplitude_deg <= 0:
            return np.zeros(3)
        rng = np.random.default_rng(self.seed)
        freqs = self.frequency_hz * rng.uniform(0.5, 1.5, (3, 3))
        phases = rng.uniform(0, 2 * np.pi, (3, 3))
        weights = np.array([0.6, 0.3, 0.1])
        return self.amplitude_deg * (weights * np.sin(2 * np.pi * freqs * t + phases)).sum(axis=1)


@dataclass(frozen=True)
class Intrinsics:
    """Pinhole camera in pixels: focal lengths fx = fy, principal point (cx, cy), image size."""

    fx: float
    cx: float
    cy: float
    width: int
    height: int

    @property
    def matrix(self) -> np.ndarray:
        """The 3x3 camera matrix K (pixels)."""
        return np.array([[self.fx, 0, self.cx], [0, self.fx, self.cy], [0, 0, 1.0]])


def project(points_world: np.ndarray, cam_to_world: np.ndarray, k: Intrinsics) -> np.ndarray:
    """Pixel positions (N, 2) of world points for a camera pose (4x4, Blender camera axes); NaN behind the camera."""
    p = np.asarray(points_world, np.float64).reshape(-1, 3)
    r, c = cam_to_world[:3, :3], cam_to_world[:3, 3]
    q = (p - c) @ r  # camera coordinates: x right, y up, -z forward
    depth = -q[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        u = k.cx + k.fx * q[:, 0] / depth
        v = k.cy - k.fx * q[:, 1] / depth
    out = np.stack([u, v], axis=1)
    out[depth <= 1e-6] = np.nan
    return out


def compose(location: np.ndarray, rotation: np.ndarray, scale: np.ndarray | float = 1.0) -> np.ndarray:
    """4x4 object-to-world matrix from location (m), rotation matrix and scale."""
    m = np.eye(4)
    m[:3, :3] = rotation * np.asarray(scale, np.float64)
    m[:3, 3] = location
    return m


def _track(keys: list, attr: str) -> tuple[np.ndarray, np.ndarray] | None:
    pairs = [
        (k.t, np.atleast_1d(np.asarray(getattr(k, attr), np.float64))) for k in keys if getattr(k, attr) is not None
    ]
    if not pairs:
        return None
    width = max(len(v) for _, v in pairs)
    return np.array([t for t, _ in pairs]), np.stack([np.broadcast_to(v, (width,)) for _, v in pairs])


def pose_matrix(trajectory, t: float, shake_seed: int = 0) -> np.ndarray:
    """4x4 object-to-world matrix of a `dvsot.scene.Trajectory` at time t (seconds), shake included, scale 1."""
    return pose_and_scale(trajectory, t, shake_seed)[0]


def pose_and_scale(trajectory, t: float, shake_seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(4x4 rotation+location matrix, per-axis scale) of a trajectory at time t (seconds)."""
    keys = trajectory.keyframes
    smooth = trajectory.interpolation == "smooth"
    loc_track = _track(keys, "location")
    loc = interpolate(*loc_track, t, smooth)
    look = _track(keys, "look_at")
    rot = _track(keys, "rotation_deg")
    if look is not None:
        r = look_at_matrix(loc, interpolate(*look, t, smooth))
    elif rot is not None:
        r = euler_xyz_to_matrix(interpolate(*rot, t, smooth))
    else:
        r = np.eye(3)
    if trajectory.shake_deg > 0:
        r = r @ euler_xyz_to_matrix(Shake(trajectory.shake_deg, trajectory.shake_hz, shake_seed).offset_deg(t))
    sc = _track(keys, "scale")
    scale = np.ones(3) if sc is None else np.broadcast_to(interpolate(*sc, t, smooth), (3,)).astype(np.float64)
    return compose(loc, r), scale
