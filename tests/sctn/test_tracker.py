"""The tracker's candidates: fixed draws per location, whatever the tracker saw before."""

import numpy as np
import torch

from dvsot.events import EventBatch
from sctn.network import SCTN

torch.set_num_threads(1)


def test_candidates_are_fixed_per_location_whatever_came_before():
    from sctn.tracker import SCTNTracker

    tracker = SCTNTracker(SCTN(), seed=4, finetune_iters=0)
    empty = EventBatch.empty()
    tracker.init(empty, 0, np.array([100.0, 80.0, 40.0, 30.0]), 320, 240)
    first = tracker.candidates()
    tracker.track(empty, 0)
    tracker.track(empty, 10_000)
    tracker.box, tracker.trans = np.array([100.2, 79.9, 40.0, 30.1]), tracker.trans0  # back at the same pixel box
    again = tracker.candidates()  # the same draws around a box 0.2 px away
    np.testing.assert_allclose(again[:, :2], first[:, :2], atol=0.5)
    np.testing.assert_allclose(again[:, 2:], first[:, 2:], rtol=0.01)
    tracker.box = np.array([101.0, 80.0, 40.0, 30.0])  # another location: other draws
    assert not np.allclose(tracker.candidates()[:, 2:], first[:, 2:], rtol=0.01)
