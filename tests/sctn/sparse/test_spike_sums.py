"""The fast mode's kernels (sctn/spike_sums.py) on hand-made spikes: window sums and the corner mix."""

import numpy as np


def test_window_sums_add_the_weights_of_the_spikes_inside_each_kept_window():
    from sctn.spike_sums import window_sums

    spikes = np.zeros((2, 4, 5, 3), np.uint8)  # (T, H, W, C)
    spikes[0, 1, 2, 0] = spikes[0, 1, 2, 2] = 1  # two channels of one cell
    spikes[0, 3, 4, 1] = 1
    spikes[1, 0, 0, 1] = 1
    weights = np.arange(3 * 3 * 3 * 2, dtype=np.float32).reshape(3, 3, 3, 2)  # (row, col, channel, out)
    crops = np.array([[1, 0, 0, 3, 0, 3],   # map cells x 1..3, y 0..2: holds (y1, x2) at crop (r1, q1)
                      [2, 1, 1, 2, 0, 3],   # columns 1..2 kept (x 3..4): (y1, x2) masked, (y3, x4) at (r2, q2)
                      [-1, -1, 0, 3, 0, 3]])  # reaches outside the map: (y0, x0) at (r1, q1)
    out = window_sums(spikes, weights, crops)
    np.testing.assert_array_equal(out[0, 0], weights[1, 1, 0] + weights[1, 1, 2])
    np.testing.assert_array_equal(out[0, 1], weights[2, 2, 1])
    np.testing.assert_array_equal(out[1, 2], weights[1, 1, 1])
    assert not out[1, :2].any() and not out[0, 2].any()


def test_mix_corners_weights_each_candidates_corner_sums():
    from sctn.spike_sums import mix_corners

    sums = np.arange(2 * 3 * 2, dtype=np.float32).reshape(2, 3, 2)  # (T, U, width)
    slots = np.array([[0, 2, 0, 0], [1, 1, 2, 0]])
    weights = np.array([[0.25, 0.75, 0.0, 0.0], [0.5, 0.25, 0.25, 0.0]], np.float32)
    out = mix_corners(sums, slots, weights)
    expect = np.einsum("nk,tnkw->tnw", weights, sums[:, slots])
    np.testing.assert_allclose(out, expect, rtol=1e-6)
