"""The rasterised amodal mask: pixel-centre coverage, near-plane clipping, and agreement with Blender's render."""

import numpy as np
import pytest

from dvsot.render.raster import silhouette_coverage, silhouette_mask, triangulate
from dvsot.scene.trajectory import Intrinsics

K = Intrinsics(fx=20.0, cx=8.0, cy=6.0, width=16, height=12)
CAM = np.eye(4)  # at the origin looking down -z, y up


def square(x0, x1, y0, y1, depth=1.0):
    """A camera-facing square whose corners project to pixel x in [x0, x1], y in [y0, y1] (K above)."""
    u = (np.array([x0, x1, x1, x0]) - K.cx) / K.fx * depth
    v = -(np.array([y0, y0, y1, y1]) - K.cy) / K.fx * depth
    return np.stack([u, v, np.full(4, -depth)], 1), triangulate([[0, 1, 2, 3]])


def test_triangulate_fans_quads_and_keeps_triangles():
    np.testing.assert_array_equal(triangulate([[0, 1, 2, 3], [4, 5, 6]]), [[0, 1, 2], [0, 2, 3], [4, 5, 6]])
    assert triangulate([]).shape == (0, 3)


@pytest.mark.parametrize("x0,x1,cols", [(2.3, 5.3, [2, 3, 4]), (2.7, 5.7, [3, 4, 5]), (2.0, 5.0, [2, 3, 4])])
def test_pixels_whose_centre_is_covered(x0, x1, cols):
    verts, tris = square(x0, x1, 3.2, 7.9)
    m = silhouette_mask(verts, tris, CAM, K)
    assert sorted(np.nonzero(m.any(0))[0]) == cols
    assert sorted(np.nonzero(m.any(1))[0]) == [3, 4, 5, 6, 7]  # centres 3.5 .. 7.5


def test_winding_does_not_matter_and_outside_or_behind_is_empty():
    verts, tris = square(2.3, 5.3, 3.2, 7.9)
    assert (silhouette_mask(verts, tris[:, ::-1], CAM, K) == silhouette_mask(verts, tris, CAM, K)).all()
    far, _ = square(100, 120, 3, 8)
    assert not silhouette_mask(far, tris, CAM, K).any()
    behind = verts * np.array([1, 1, -1])
    assert not silhouette_mask(behind, tris, CAM, K).any()


def test_near_plane_clipping_keeps_the_part_in_front():
    # a floor strip from behind the camera to 5 m ahead, below the eye: only its visible part is drawn
    verts = np.array([[-0.3, -0.2, 1.0], [0.3, -0.2, 1.0], [0.3, -0.2, -5.0], [-0.3, -0.2, -5.0]])
    m = silhouette_mask(verts, triangulate([[0, 1, 2, 3]]), CAM, K)
    rows = np.nonzero(m.any(1))[0]
    assert m.any() and rows.max() == K.height - 1  # reaches the bottom edge
    assert rows.min() >= int(K.cy + K.fx * 0.2 / 5.0 - 0.5)  # and stops at its far end


def test_huge_triangle_covering_the_image():
    verts, tris = square(-1e6, 1e6, -1e6, 1e6)
    assert silhouette_mask(verts, tris, CAM, K).all()


def test_coverage_of_a_square_wholly_on_the_sensor_is_its_mask():
    verts, tris = square(2.3, 5.3, 3.2, 7.9)
    mask, on, whole = silhouette_coverage(verts, tris, CAM, K)
    assert (mask == silhouette_mask(verts, tris, CAM, K)).all()
    assert on == whole == mask.sum() == 15


@pytest.mark.parametrize("x0,x1,off", [(-4.0, 4.0, 0.5), (12.0, 20.0, 0.5), (-6.0, 2.0, 0.75), (10.0, 30.0, 0.7)])
def test_coverage_counts_the_part_past_the_edge_exactly(x0, x1, off):
    # pixel centres at integer + 0.5: a square spanning whole pixels is counted exactly on and off the sensor
    verts, tris = square(x0, x1, 2.0, 6.0)
    mask, on, whole = silhouette_coverage(verts, tris, CAM, K)
    assert whole == (x1 - x0) * 4 and on == mask.sum()
    assert 1 - on / whole == pytest.approx(off)


def test_coverage_of_a_huge_extent_uses_coarse_cells_within_one_cell_of_the_outline():
    verts, tris = square(-2000.0, 8.0, 0.0, 12.0)  # 2008 x 12 px, 500 of them over max_cells below
    _, on, whole = silhouette_coverage(verts, tris, CAM, K, max_cells=500)
    true_off = 1 - (8 * 12) / (2008 * 12)
    s = int(np.ceil(np.sqrt((2008 + 8) * 12 / 500)))
    assert abs((1 - on / whole) - true_off) <= 2 * s * (2008 + 12) / (2008 * 12)
    assert 0 < on <= whole


def test_coverage_of_nothing_in_front_is_zero():
    verts, tris = square(2.3, 5.3, 3.2, 7.9)
    mask, on, whole = silhouette_coverage(verts * np.array([1, 1, -1]), tris, CAM, K)
    assert not mask.any() and on == whole == 0
    far, _ = square(100, 120, 3, 8)
    mask, on, whole = silhouette_coverage(far, tris, CAM, K)
    assert not mask.any() and on == 0 and whole == 20 * 5


@pytest.mark.blender
def test_raster_mask_matches_the_rendered_object_index_layer(tmp_path):
    from dvsot.dataset.boxes import box_from_mask
    from dvsot.render.blender import BlenderScene
    from dvsot.scene import parse_scene

    text = """name: cmp
duration_s: 0.1
sensor: {width: 96, height: 72, focal_mm: 35}
camera:
  keyframes: [{t: 0, location: [0, -10, 0], look_at: [0, 0, 0]}]
  shake_deg: 0.5
target:
  shape: star
  size_m: 2.5
  trajectory:
    keyframes:
      - {t: 0, location: [-1, 0, 0], rotation_deg: [10, 20, 0]}
      - {t: 0.1, location: [1, 0, 0.5], rotation_deg: [40, 120, 30]}
lights: []
render: {threads: 2, amodal_mask: render}
"""
    cfg = parse_scene(text)
    with BlenderScene(cfg) as s:
        for t in (0.0, 0.05, 0.1):
            _, rendered, _ = s.render(t)
            raster = s.raster_amodal_mask()
            assert rendered.any()
            np.testing.assert_array_equal(box_from_mask(raster), box_from_mask(rendered))
            assert (raster & rendered).sum() / (raster | rendered).sum() > 0.98
