"""The protocol's re-initialisation is a new tracker, for every tracker in the benchmark: re-initialised at segment k,
a tracker gives from k on exactly the boxes a new instance started at k gives."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from benchmarks.trackers import BUILTIN, get_tracker

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
from synthetic import moving_square_file  # noqa: E402

torch.set_num_threads(1)
# the SCTN-like trackers on their shipped checkpoints with fewer candidates and fine-tuning mini-batches (the preset's
# code path, small enough for a test); the others with their defaults
OPTIONS = {"sctn": {"n_candidates": 12, "finetune_iters": 2, "energy_every": 0},
           "sctn_ann": {"n_candidates": 12, "finetune_iters": 2, "energy_every": 0}}
REINIT_AT = 4
# trackers that ship no checkpoint: run on an untrained network of theirs (what is checked needs no training)
UNTRAINED = {"goturn": "benchmarks.trackers.goturn.model:GOTURN",
             "siamrpn": "benchmarks.trackers.siamrpn.model:SiamRPN",
             "siammask": "benchmarks.trackers.siammask.model:SiamMask",
             "ocean": "benchmarks.trackers.ocean.model:Ocean",
             "automatch": "benchmarks.trackers.automatch.model:AutoMatch"}


@pytest.fixture(scope="module", autouse=True)
def untrained_checkpoints(tmp_path_factory):
    """A checkpoint of an untrained network (seeded) for each tracker of UNTRAINED, in OPTIONS."""
    from benchmarks.training.registry import resolve
    from sctn.checkpoint import save_checkpoint

    d = tmp_path_factory.mktemp("untrained")
    for name, net in UNTRAINED.items():
        torch.manual_seed(0)
        OPTIONS[name] = {"checkpoint": str(save_checkpoint(d / f"{name}.pt", resolve(net)(), {}, kind=name))}
    yield
    for name in UNTRAINED:
        OPTIONS.pop(name, None)


@pytest.fixture(scope="module")
def sequence(tmp_path_factory):
    from dvsot.dataset import Dataset

    path = moving_square_file(tmp_path_factory.mktemp("reinit") / "s.h5", duration_ms=90, seed=4)
    with Dataset(path) as ds:
        return list(ds.segments(0, ds.num_segments)), (ds.width, ds.height)


def _run(tracker, segs, wh, inits: list[int]) -> dict[int, np.ndarray]:
    """Boxes per segment index of a tracker initialised on the ground truth at each of inits, updated in between."""
    out = {}
    for i in range(inits[0], len(segs)):
        if i in inits:
            tracker.init(segs[i], segs[i].box.copy(), *wh)
        else:
            out[i] = np.asarray(tracker.update(segs[i]), np.float32)
    return out


def _new(name: str):
    from dvsot.core.errors import UserError

    try:
        return get_tracker(name, **OPTIONS.get(name, {}))
    except UserError as exc:  # a checkpoint that is truly not there (a source tree without the shipped files)
        if "checkpoint" in str(exc).lower() and "no such" in str(exc).lower():
            pytest.skip(f"{name}: {exc}")
        raise


@pytest.mark.parametrize("name", sorted(BUILTIN))  # the project's trackers: a test module may register its own
def test_reinitialised_tracker_gives_what_a_new_one_gives(sequence, name) -> None:
    segs, wh = sequence
    again = _run(_new(name), segs, wh, [0, REINIT_AT])
    fresh = _run(_new(name), segs, wh, [REINIT_AT])
    assert len(fresh) >= 4 and set(fresh) <= set(again)
    for i in fresh:
        assert np.array_equal(again[i], fresh[i]), f"{name}: segment {i}: {again[i]} after a re-initialisation, " \
                                                   f"{fresh[i]} from a new tracker"


@pytest.mark.parametrize("name", ["sctn", "sctn_ann"])
def test_the_retired_reinit_options_are_refused_in_one_line(name) -> None:
    from benchmarks.bench.plan import check_trackers
    from dvsot.core.errors import UserError

    spec = f"{name}.finetune_on_reinit=false"
    with pytest.raises(UserError) as err:
        check_trackers([name], {name: {"finetune_on_reinit": False}}, [spec])
    text = str(err.value)
    assert "\n" not in text and text.startswith(f"options {spec}") and "reinit=once" in text, text
