"""Fine-tuning's named options: balanced mini-batches (32 positives, 96 negatives), the fully connected layers
only, and fine-tuning again at a re-initialisation; the defaults are today's."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from sctn.finetune import BALANCED, finetune, minibatch
from sctn.network import SCTN, NetworkConfig
from sctn.params import SCTNParams, SearchParams

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from synthetic import moving_square_file  # noqa: E402

torch.set_num_threads(1)
SMALL = NetworkConfig(channels=(2, 2, 2), fc=(4, 4))


def test_balanced_minibatch_holds_32_positives_and_96_negatives() -> None:
    rng = np.random.default_rng(0)
    positive = np.arange(2500) < 500
    pick = minibatch(rng, np.arange(2500), positive, 128, True)
    assert BALANCED == (32, 96) and positive[pick].sum() == 32 and (~positive[pick]).sum() == 96
    assert len(np.unique(pick)) == 128
    few = minibatch(rng, np.arange(20), np.arange(20) < 5, 128, True)  # fewer than asked: all there are
    assert len(few) == 20
    plain = minibatch(np.random.default_rng(1), np.arange(2500), positive, 128, False)
    assert np.array_equal(plain, np.random.default_rng(1).choice(2500, 128, replace=False))  # today's draw


@pytest.fixture(scope="module")
def segment(tmp_path_factory):
    from dvsot.dataset import Dataset

    path = moving_square_file(tmp_path_factory.mktemp("ft") / "s.h5", duration_ms=40, seed=2)
    with Dataset(path) as ds:
        return ds.segment(1), (ds.width, ds.height), path


def test_fc_only_leaves_the_convolutions_and_their_neurons_alone(segment) -> None:
    seg, wh, _ = segment
    torch.manual_seed(0)
    net = SCTN(SMALL)
    before = {k: v.clone() for k, v in net.state_dict().items()}
    finetune(net, seg.events, seg.t0_us, seg.box, wh, np.random.default_rng(0), iters=2, layers="fc")
    after = net.state_dict()
    conv_keys = [k for k in before if k.startswith("convs.") or k.split(".")[:2] in (["neurons", "0"],
                                                                                     ["neurons", "1"], ["neurons", "2"])]
    assert conv_keys and all(torch.equal(before[k], after[k]) for k in conv_keys)
    assert any(not torch.equal(before[k], after[k]) for k in before if k.startswith("fcs."))
    with pytest.raises(ValueError, match="fine-tuning layers"):
        finetune(net, seg.events, seg.t0_us, seg.box, wh, np.random.default_rng(0), iters=1, layers="conv")


def test_the_default_tunes_again_at_each_reinit_and_first_only_does_not(segment, monkeypatch) -> None:
    import sctn.tracker

    seg, wh, _ = segment
    calls = []
    monkeypatch.setattr(sctn.tracker, "finetune", lambda *a, **k: calls.append(k) or {})
    assert SCTNParams().finetune_on_reinit is True and SearchParams().finetune_on_reinit is True
    assert SCTNParams().error_time == "stca"
    for again, expected in ((False, 1), (True, 2)):
        calls.clear()
        tracker = sctn.tracker.SCTNTracker(SCTN(SMALL), finetune_on_reinit=again, finetune_balanced=True,
                                           finetune_layers="fc")
        tracker.init(seg.events, seg.t0_us, seg.box, *wh)
        tracker.init(seg.events, seg.t0_us, seg.box, *wh)  # the protocol's re-initialisation
        assert len(calls) == expected
        assert calls[0]["balanced"] is True and calls[0]["layers"] == "fc" and calls[0]["error_time"] == "stca"


def test_reinit_from_trained_tunes_a_fresh_copy_and_the_default_tunes_the_tuned(segment, monkeypatch) -> None:
    import sctn.tracker

    seg, wh, _ = segment
    seen = []

    def fake_finetune(model, *a, **k):  # records the weights it was handed, then "tunes" them by +1
        weight = next(model.parameters())
        seen.append(weight.detach().clone())
        with torch.no_grad():
            weight.add_(1.0)
        return {}

    monkeypatch.setattr(sctn.tracker, "finetune", fake_finetune)
    assert SCTNParams().reinit_from == "tuned"
    base = SCTN(SMALL)
    trained = next(base.parameters()).detach().clone()
    for reinit_from, second in (("tuned", trained + 1.0), ("trained", trained)):
        seen.clear()
        tracker = sctn.tracker.SCTNTracker(base, reinit_from=reinit_from)
        tracker.init(seg.events, seg.t0_us, seg.box, *wh)
        tracker.init(seg.events, seg.t0_us, seg.box, *wh)  # the protocol's re-initialisation
        assert len(seen) == 2 and torch.equal(seen[0], trained) and torch.equal(seen[1], second)
        assert torch.equal(next(base.parameters()), trained)  # the trained network itself is never tuned


def test_reinit_from_trained_without_tuning_on_reinit_is_rejected() -> None:
    with pytest.raises(ValueError, match="needs finetune_on_reinit"):
        SCTNParams(reinit_from="trained", finetune_on_reinit=False)
    with pytest.raises(ValueError, match="reinit_from"):
        SearchParams(reinit_from="fresh")
