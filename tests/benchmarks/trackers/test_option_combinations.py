"""Option combinations the SCTN-like trackers cannot honour are refused in one line naming the settings, and by
`dvsot bench` with exit status 2 before any run; the combinations they can honour still build."""

from __future__ import annotations

import pytest
from pydantic import ValidationError

from sctn.params import SCTNParams, SearchParams
from tests.cli.test_bench_command import fails_cleanly, make

REFUSED = [
    ({"top_k": 5, "n_candidates": 4}, "top_k 5 needs at least as many candidates (n_candidates is 4)"),
    ({"trans": 2.0, "trans_max": 1.0}, "trans 2 starts above trans_max 1"),
    ({"reinit": "online", "finetune_iters": 0}, "reinit 'online' keeps a tuning, but finetune_iters is 0"),
    ({"reinit": "once", "finetune_iters": 0}, "reinit 'once' keeps a tuning, but finetune_iters is 0"),
]
REFUSED_SCTN = REFUSED + [
    ({"crop": "nearest"}, "crop is the fast mode's setting: it needs fast=true"),
    ({"crop": "bilinear", "fast": False}, "crop is the fast mode's setting"),
    ({"finetune_search_iters": 5}, "finetune_search_iters is the fast mode's setting"),
    ({"finetune_iters": 0, "error_time": "max"}, "error_time is fine-tuning's setting, but nothing is fine-tuned"),
    ({"finetune_iters": 0, "finetune_layers": "fc"}, "finetune_layers is fine-tuning's setting"),
    ({"finetune_iters": 0, "fast": True, "finetune_search_iters": 0, "finetune_balanced": True},
     "finetune_balanced is fine-tuning's setting"),
]
HONOURED = [{}, {"fast": True, "crop": "nearest", "finetune_search_iters": 0}, {"finetune_search_iters": 0},
            {"finetune_iters": 0, "fast": True, "finetune_search_iters": 3, "error_time": "max"},
            {"reinit": "online"}, {"reinit": "once", "finetune_iters": 1}, {"top_k": 4, "n_candidates": 4},
            {"trans": 1.5, "trans_max": 1.5}, {"finetune_iters": 0}]


def _message(cls, settings: dict) -> str:
    with pytest.raises(ValidationError) as info:
        cls(**settings)
    return info.value.errors()[0]["msg"]


@pytest.mark.parametrize("settings, words", REFUSED_SCTN)
def test_sctn_settings_it_cannot_honour_are_refused(settings: dict, words: str) -> None:
    text = _message(SCTNParams, settings)
    assert words in text and "\n" not in text


@pytest.mark.parametrize("settings, words", REFUSED)
def test_twin_settings_it_cannot_honour_are_refused(settings: dict, words: str) -> None:
    assert words in _message(SearchParams, settings)


@pytest.mark.parametrize("settings", HONOURED)
def test_combinations_it_honours_build(settings: dict) -> None:
    from sctn.network import SCTN, NetworkConfig
    from sctn.tracker import SCTNTracker

    assert SCTNParams(**settings).combination_problem() is None
    tracker = SCTNTracker(SCTN(NetworkConfig(channels=(2, 2, 2), fc=(4, 4))), SCTNParams(**settings))
    # the tracker runs what was asked: the fast mode's search tuning only with the fast mode
    assert tracker.finetune_search_iters == (tracker.params.finetune_search_iters if tracker.fast else 0)
    # settings given through params keep what they left unset unset, so keywords on top are checked as given
    assert SCTNTracker(tracker.base, SCTNParams(seed=2), n_candidates=8).params.model_fields_set == {"seed",
                                                                                                     "n_candidates"}


@pytest.mark.parametrize("tracker, option, words", [
    ("sctn", "sctn.crop=nearest", "--option sctn.crop=nearest: crop is the fast mode's setting: it needs fast=true"),
    ("sctn", "sctn.finetune_iters=0 sctn.reinit=online", "reinit 'online' keeps a tuning, but finetune_iters is 0"),
    ("sctn_ann", "sctn_ann.top_k=9 sctn_ann.n_candidates=8", "top_k 9 needs at least as many candidates"),
])
def test_bench_refuses_a_combination_in_one_line(tmp_path, capsys, tracker: str, option: str, words: str) -> None:
    make(tmp_path / "a.h5")
    options = [a for o in option.split() for a in ("--option", o)]
    fails_cleanly(tmp_path, capsys, ["--tracker", tracker, "--data", str(tmp_path / "a.h5"), "--out",
                                     str(tmp_path / "out"), *options], words)
