"""One source for each setting: the tracker's typed settings, the trainers' budget, the one-line formatter."""

import numpy as np
import pytest
from pydantic import ValidationError

from dvsot.core.errors import exception_line
from sctn.params import SCTNParams, SearchParams


def test_exception_line_folds_cuts_and_names_the_type():
    assert exception_line(ValueError("a\n  b\tc")) == "ValueError: a b c"
    assert exception_line(ValueError("x" * 50), 10) == "ValueError: " + "x" * 10
    assert exception_line(KeyError(), kind=False) == "KeyError"
    assert exception_line(OSError("disk\nfull"), kind=False) == "disk full"


def test_tracker_keywords_and_params_are_the_same_settings():
    from sctn.network import SCTN, NetworkConfig
    from sctn.tracker import SCTNTracker

    net = SCTN(NetworkConfig(channels=(2, 2, 2), fc=(4, 4)))
    by_keywords = SCTNTracker(net, seed=3, n_candidates=16, fast=True, crop="nearest")
    by_params = SCTNTracker(net, SCTNParams(seed=3, n_candidates=16, fast=True, crop="nearest"))
    assert by_keywords.params == by_params.params
    assert (by_params.seed, by_params.n_candidates, by_params.crop, by_params.finetune_search_iters) == (3, 16,
                                                                                                         "nearest", 10)
    assert SCTNTracker(net, SCTNParams(seed=3), seed=5).seed == 5  # a keyword wins over params
    assert SCTNTracker(net).params == SCTNParams()  # the paper's defaults
    with pytest.raises(ValidationError, match="n_candidates"):
        SCTNTracker(net, n_candidates=0)
    with pytest.raises(ValidationError, match="fast"):
        SCTNTracker(net, fast="False")  # the text must not mean true


def test_benchmark_options_are_the_tracker_settings_plus_their_own():
    from benchmarks.trackers.sctn import BENCH_FIELDS, SCTNOptions
    from benchmarks.trackers.sctn_ann import TwinOptions

    assert set(SCTNOptions.model_fields) == set(SCTNParams.model_fields) | BENCH_FIELDS
    assert set(TwinOptions.model_fields) == set(SearchParams.model_fields) | BENCH_FIELDS
    assert "fast" not in TwinOptions.model_fields  # the twin has no fast mode


def test_train_configs_keep_the_paper_preset_and_the_twin_network():
    from benchmarks.trackers.siamfc.train import SiamFCTrainConfig
    from sctn.ann import TwinConfig
    from sctn.training.snn import TrainConfig, TrainConfigError

    cfg = TrainConfig()
    assert (cfg.squared_error, cfg.background_term, cfg.calibrate, cfg.ops_penalty, cfg.loss) == (False, False, False,
                                                                                                  0.0, "exp")
    assert cfg.planned_steps(10**6) == cfg.epochs * cfg.segments_per_epoch // cfg.batch_segments  # the recipe's steps
    assert TrainConfig(network=TwinConfig(input="sum")).model_dump()["network"]["input"] == "sum"
    siam = SiamFCTrainConfig()
    assert (siam.epochs, siam.batch_segments, siam.lr, siam.max_gap) == (20, 8, 1e-3, 100)
    with pytest.raises(TrainConfigError, match=r"SiamFCTrainConfig\.max_gap must be >= 1, got 0"):
        SiamFCTrainConfig(max_gap=0)
    with pytest.raises(TrainConfigError, match="is not a setting"):
        TrainConfig(epoch=3)


def test_held_out_split_and_spread():
    from sctn.training.loop import held_out, spread

    idx = np.array([3, 5, 8, 9, 12, 13, 14, 20, 21, 22, 30, 31, 40])
    fit, val = held_out(idx)
    assert val.tolist() == idx[::10].tolist()
    assert fit.tolist() == [i for k, i in enumerate(idx) if k % 10 != 0]
    assert spread(list("abcdefghij"), 4) == ["a", "d", "g", "j"] and spread([], 3) == []
    assert spread(["a", "b"], 5) == ["a", "b"]


def test_the_ablation_table_counts_silent_seeds():
    """A seed whose network ended silent stays in the row's mean and is counted in its own column."""
    from benchmarks.experiments.ablation import format_table, summarise

    runs = [
        {"row": "paper", "seed": 0, "A": 0.7, "R": 0.9, "ARscore": 0.88, "ac_ops_per_segment": 1e8, "silent": False},
        {"row": "paper", "seed": 1, "A": 0.5, "R": 0.5, "ARscore": 0.50, "ac_ops_per_segment": None, "silent": True},
    ]
    s = summarise(runs)["paper"]
    assert s["seeds"] == 2 and s["silent"] == 1 and abs(s["mean"]["ARscore"] - 0.69) < 1e-12
    assert format_table(summarise(runs)).splitlines()[-1].endswith("| 1.00e+08 |  | 2 | 1 | 0 |")  # no speed given
