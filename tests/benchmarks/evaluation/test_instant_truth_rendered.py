"""Boxes interpolated between motion-bounded samples against boxes rendered at the query instants (real renders)."""

import numpy as np
import pytest

from benchmarks.evaluation.instant_truth import interpolation_bound_px, truth_at
from dvsot.cli import main
from dvsot.dataset import Dataset
from tests.synthetic import linear_path, tiny_scene

pytestmark = pytest.mark.blender


def test_interpolated_boxes_are_within_the_bound_of_boxes_rendered_there(tmp_path):
    cube = {"shape": "cube", "size_m": 1.5, "material": {"color": [0.9, 0.9, 0.9]},
            "trajectory": linear_path((-2.0, 0, -0.5), (2.0, 0, 0.5))}
    plain, extra = tmp_path / "plain.yaml", tmp_path / "extra.yaml"
    plain.write_text(tiny_scene("plain", cube).replace("duration_s: 0.2", "duration_s: 0.05"))
    assert main(["generate", str(plain), "-o", str(tmp_path / "plain.h5"), "--quiet"]) == 0
    with Dataset(tmp_path / "plain.h5") as ds:
        first = ds.boxes()
    # the middles of the sample intervals, where interpolation is furthest from a sample
    middles = np.unique((first.t[:-1] + first.t[1:]) // 2)
    middles = middles[~np.isin(middles, first.t)]
    assert middles.size >= 3
    extra.write_text(tiny_scene("extra", cube, sampling={"extra_times_ms": (middles / 1000).tolist()})
                     .replace("duration_s: 0.2", "duration_s: 0.05"))
    assert main(["generate", str(extra), "-o", str(tmp_path / "extra.h5"), "--quiet"]) == 0
    with Dataset(tmp_path / "extra.h5") as ds:
        second = ds.boxes()
    assert np.isin(first.t, second.t).all() and np.isin(middles, second.t).all()  # the extra instants are rendered
    rendered = np.isin(second.t, middles)
    truth = truth_at(first, second.t[rendered])
    edge, side = interpolation_bound_px(0.75)
    pairs = ((truth.xywh, second.xywh[rendered]), (truth.xywh_visible, second.xywh_visible[rendered]))
    for interpolated, exact in pairs:
        ok = np.isfinite(exact).all(axis=1)
        assert ok.sum() >= 3
        err = np.abs(interpolated[ok] - exact[ok])
        assert np.all(err[:, :2] <= edge) and np.all(err[:, 2:] <= side)
    # and the samples both renders share give the same boxes (the extra samples change nothing else)
    np.testing.assert_allclose(second.xywh[np.isin(second.t, first.t)], first.xywh, atol=1e-4)
