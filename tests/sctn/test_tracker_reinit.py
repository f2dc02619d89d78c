"""What SCTNTracker's re-initialisation starts from: a new tracker by default (the trained network tuned afresh, the
generator restarted), online learning on the test sequence, or the single tuning kept."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
import torch
from pydantic import ValidationError

import sctn.tracker
from sctn.network import SCTN, NetworkConfig
from sctn.params import SCTNParams, SearchParams

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from synthetic import moving_square_file  # noqa: E402

torch.set_num_threads(1)
SMALL = NetworkConfig(channels=(2, 2, 2), fc=(4, 4))
FEW = {"n_candidates": 12, "finetune_iters": 2}  # the preset's code path, small enough for a test


@pytest.fixture(scope="module")
def segments(tmp_path_factory):
    from dvsot.dataset import Dataset

    path = moving_square_file(tmp_path_factory.mktemp("reinit") / "s.h5", duration_ms=60, seed=2)
    with Dataset(path) as ds:
        return list(ds.segments(0, ds.num_segments)), (ds.width, ds.height)


def test_the_preset_is_a_new_tracker_and_the_old_settings_are_refused_in_one_line() -> None:
    assert SCTNParams().reinit == "new" and SearchParams().reinit == "new"
    with pytest.raises(ValidationError, match="finetune_on_reinit was replaced by reinit .*reinit=once"):
        SCTNParams(finetune_on_reinit=False)
    with pytest.raises(ValidationError, match="reinit_from was replaced by reinit .*reinit=new"):
        SearchParams(reinit_from="trained")
    with pytest.raises(ValidationError, match="reinit"):
        SearchParams(reinit="fresh")


@pytest.mark.parametrize("reinit, tuned_second, second_from", [("new", True, "trained"), ("online", True, "tuned"),
                                                               ("once", False, None)])
def test_what_each_reinit_tunes(segments, monkeypatch, reinit, tuned_second, second_from) -> None:
    segs, wh = segments
    seen = []

    def fake_finetune(model, events, t0, box, image_wh, rng, **k):  # records weights and generator, "tunes" by +1
        weight = next(model.parameters())
        seen.append((weight.detach().clone(), int(rng.integers(1 << 30))))
        with torch.no_grad():
            weight.add_(1.0)
        return {}

    monkeypatch.setattr(sctn.tracker, "finetune", fake_finetune)
    base = SCTN(SMALL)
    trained = next(base.parameters()).detach().clone()
    tracker = sctn.tracker.SCTNTracker(base, reinit=reinit, trans=0.2)
    tracker.init(segs[0].events, segs[0].t0_us, segs[0].box, *wh)
    tracker.trans = 1.5
    tracker.init(segs[1].events, segs[1].t0_us, segs[1].box, *wh)  # the protocol's re-initialisation
    assert tracker.trans == 0.2 and np.array_equal(tracker.box, segs[1].box)
    assert len(seen) == (2 if tuned_second else 1)
    if second_from == "trained":  # a new tracker: the trained weights and the generator's first draw again
        assert torch.equal(seen[1][0], trained) and seen[1][1] == seen[0][1]
    elif second_from == "tuned":  # online learning: the tuned weights, the generator running on
        assert torch.equal(seen[1][0], trained + 1.0) and seen[1][1] != seen[0][1]
    assert torch.equal(next(base.parameters()), trained)  # the trained network itself is never tuned


def _boxes(tracker, segs, wh, init_at: list[int]) -> dict[int, np.ndarray]:
    """Boxes per segment index of a tracker initialised at each of init_at and tracking the segments between."""
    out = {}
    for i, seg in enumerate(segs[init_at[0]:], start=init_at[0]):
        if i in init_at:
            tracker.init(seg.events, seg.t0_us, seg.box, *wh)
        else:
            out[i] = tracker.track(seg.events, seg.t0_us)
    return out


def test_a_reinitialised_tracker_is_a_new_tracker_from_then_on(segments) -> None:
    segs, wh = segments
    k = 3
    torch.manual_seed(0)
    base = SCTN(SMALL)
    rerun = _boxes(sctn.tracker.SCTNTracker(base, **FEW), segs, wh, [0, k])
    fresh = _boxes(sctn.tracker.SCTNTracker(base, **FEW), segs, wh, [k])
    assert fresh and all(np.array_equal(rerun[i], fresh[i]) for i in fresh)
    # online learning carries the first segment's tuning into the second: not a new tracker's network
    online = sctn.tracker.SCTNTracker(base, reinit="online", **FEW)
    _boxes(online, segs, wh, [0, k])
    new = sctn.tracker.SCTNTracker(base, **FEW)
    _boxes(new, segs, wh, [k])
    assert any(not torch.equal(a, b) for a, b in zip(online.model.parameters(), new.model.parameters()))
