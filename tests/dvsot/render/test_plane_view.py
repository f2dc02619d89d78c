"""The background bake's plane geometry (dvsot.render.plane_view), without Blender."""

import numpy as np
import pytest

from dvsot.render.plane_view import WHOLE, bake_sides, plane_uvs, seen_part
from dvsot.scene.trajectory import Intrinsics

K = Intrinsics(fx=35 / 36 * 64, cx=32.0, cy=24.0, width=64, height=48)


def camera_at(x: float, y: float, z: float, flip: bool = False) -> np.ndarray:
    """Camera-to-world pose at (x, y, z) looking along -z (or +z when flip: rotated 180 degrees about x)."""
    m = np.eye(4)
    if flip:
        m[1, 1] = m[2, 2] = -1.0
    m[:3, 3] = (x, y, z)
    return m


def test_a_camera_facing_the_plane_sees_its_frustum_footprint_plus_margins():
    # a 40 m wall 18 m in front: the image covers 64 x 48 px / fx * 18 m of it, centred; 10 % a side + 4 px
    rect, px_per_m = seen_part(np.eye(4), 40.0, camera_at(0, 0, 18)[None], K)
    assert px_per_m == pytest.approx(K.fx / 18)
    half = np.array([32, 24]) / px_per_m / 40 * 1.2 + 4 / (px_per_m * 40)
    np.testing.assert_allclose(rect, [*(0.5 - half), *(0.5 + half)], atol=1e-12)


def test_a_moving_camera_sees_the_union_and_its_closest_approach_sets_the_density():
    one, _ = seen_part(np.eye(4), 40.0, camera_at(0, 0, 18)[None], K)
    rect, px_per_m = seen_part(np.eye(4), 40.0, np.stack([camera_at(0, 0, 18), camera_at(4, 0, 12)]), K)
    assert px_per_m == pytest.approx(K.fx / 12)
    assert rect[2] > one[2] and rect[0] < 0.5 and rect[0] > one[0]  # reaches further right, not further left


def test_a_ray_that_misses_the_plane_means_the_whole_plane():
    rect, _ = seen_part(np.eye(4), 40.0, np.stack([camera_at(0, 0, 18), camera_at(0, 0, 18, flip=True)]), K)
    np.testing.assert_array_equal(rect, WHOLE)
    rect, _ = seen_part(np.eye(4), 4.0, camera_at(0, 0, 1000)[None], K)  # footprint beyond the plane: clipped
    np.testing.assert_array_equal(rect, WHOLE)


def test_bake_sides_and_uvs():
    rect = np.array([0.25, 0.4, 0.75, 0.6])
    near, far = bake_sides(rect, px_per_m=10.0, size_m=40.0, texels_per_px=2.0, max_size=4096)
    assert near == (400, 160) and far == (100, 100)  # 20 texels a metre; the whole plane at 2.5
    assert bake_sides(rect, 1000.0, 40.0, 2.0, 512) == ((512, 512), (512, 512))
    assert bake_sides(rect, 0.01, 40.0, 2.0, 512) == ((16, 16), (16, 16))
    whole, view = plane_uvs(np.array([[-20.0, -20.0], [0.0, 0.0], [10.0, -4.0]]), 40.0, rect)
    np.testing.assert_allclose(whole, [[0, 0], [0.5, 0.5], [0.75, 0.4]])
    np.testing.assert_allclose(view, [[-0.5, -2.0], [0.5, 0.5], [1.0, 0.0]])
