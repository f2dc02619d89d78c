"""Fine-tuning's named options: balanced mini-batches (32 positives, 96 negatives), the fully connected layers
only; the defaults are today's (re-initialisation: tests/sctn/test_tracker_reinit.py)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from sctn.finetune import BALANCED, finetune, minibatch
from sctn.network import SCTN, NetworkConfig

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
    conv_keys = [
        k
        for k in before
        if k.startswith("convs.") or k.split(".")[:2] in (["neurons", "0"], ["neurons", "1"], ["neurons", "2"])
    ]
    assert conv_keys and all(torch.equal(before[k], after[k]) for k in conv_keys)
    assert any(not torch.equal(before[k], after[k]) for k in before if k.startswith("fcs."))
    with pytest.raises(ValueError, match="fine-tuning layers"):
        finetune(net, seg.events, seg.t0_us, seg.box, wh, np.random.default_rng(0), iters=1, layers="conv")
