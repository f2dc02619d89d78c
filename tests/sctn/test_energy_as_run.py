"""Energy of the tracker as run (sctn.energy_run): the bases from hand-made run records, fine-tuning's counts, and the
benchmark's own run of SCTN, its twin and SiamFC feeding the one function."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from sctn.energy import E_AC_PJ, E_ACTIVATION_PJ, E_CLIF_UPDATE_PJ, E_MAC_PJ, count_macs
from sctn.energy_run import BACKWARD_FACTOR, dense_macs, energy_as_run, finetune_operations, split
from sctn.network import SCTN, NetworkConfig

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from synthetic import moving_square_file  # noqa: E402

torch.set_num_threads(1)
SMALL = NetworkConfig(channels=(2, 2, 2), fc=(4, 4))


def test_dense_macs_is_every_synapse_at_every_step() -> None:
    for cfg in (NetworkConfig(), SMALL, NetworkConfig(tail_steps=2, background_neuron=False)):
        x = torch.zeros(1, cfg.steps, 2, cfg.input_size, cfg.input_size)
        # the dense forward torch runs: every layer at every step, the tail steps (zero input) too
        assert dense_macs(cfg) == count_macs(SCTN(cfg), x)["mac_ops"]


def test_finetune_operations_forward_as_run_backward_twice_dense() -> None:
    stats = {"finetune_ops": {"samples": 10, "forward_ac_ops": 500.0, "forward_mac_ops": 7.0,
                              "forward_state_updates": 300.0}}
    snn = finetune_operations(stats, True, 100.0)
    assert snn == {"ac_ops": 500.0, "mac_ops": 7.0 + BACKWARD_FACTOR * 100.0 * 10, "state_updates": 600.0,
                   "activations": 0.0}
    ann = finetune_operations(stats, False, 100.0, 4.0)
    assert ann == {"ac_ops": 0.0, "mac_ops": 100.0 * 10 * (1 + BACKWARD_FACTOR), "state_updates": 0.0,
                   "activations": 2 * 4.0 * 10}
    assert finetune_operations({}, True, 100.0) == {"ac_ops": 0.0, "mac_ops": 0.0, "state_updates": 0.0,
                                                    "activations": 0.0}  # no fine-tuning ran


def test_energy_as_run_bases_in_closed_form() -> None:
    seg = {"ac_ops": 256.0, "mac_ops": 0.0, "state_updates": 512.0, "activations": 0.0, "evaluations": 256}
    init = {"ac_ops": 10.0, "mac_ops": 20.0, "state_updates": 30.0, "activations": 0.0}
    records = [{"energy": seg, "init_energy": init, "tracked_segments": 8, "init_segments": [0, 5], "error": None},
               {"energy": {**seg, "ac_ops": 512.0}, "init_energy": init, "tracked_segments": 4, "init_segments": [0]},
               {"energy": None, "init_energy": None, "tracked_segments": 3, "init_segments": [0]},  # not counted
               {"energy": seg, "init_energy": init, "tracked_segments": 3, "init_segments": [0], "error": "crash"}]
    e = energy_as_run(records)
    assert (e["sequences"], e["tracked_segments"], e["initialisations"]) == (2, 12, 3)
    ac_seg = (8 * 256 + 4 * 512) / 12
    assert e["per_segment"]["synaptic"]["ac_ops"] == pytest.approx(ac_seg)
    assert e["per_evaluation"]["synaptic"]["ac_ops"] == pytest.approx(ac_seg / 256)
    assert e["per_evaluation"]["state"]["state_updates"] == pytest.approx(2.0)
    assert e["per_evaluation"]["state"]["energy_pj"] == pytest.approx(2.0 * E_CLIF_UPDATE_PJ)
    assert e["paper_convention"]["energy_pj"] == pytest.approx(ac_seg / 256 * E_AC_PJ)
    init_pj = 10 * E_AC_PJ + 20 * E_MAC_PJ + 30 * E_CLIF_UPDATE_PJ
    assert e["per_initialisation"]["energy_pj"] == pytest.approx(init_pj)
    seq_ac = ((8 * 256 + 2 * 10) + (4 * 512 + 1 * 10)) / 2
    assert e["per_sequence"]["synaptic"]["ac_ops"] == pytest.approx(seq_ac)
    assert split({"activations": 3.0})["state"]["energy_pj"] == pytest.approx(3 * E_ACTIVATION_PJ)
    assert energy_as_run(records[2:3]) is None


@pytest.fixture(scope="module")
def dataset_path(tmp_path_factory):
    return moving_square_file(tmp_path_factory.mktemp("energy") / "s.h5", duration_ms=60, seed=4)


@pytest.mark.parametrize("name", ["sctn", "sctn_ann", "siamfc"])
def test_the_bench_run_feeds_the_one_function(dataset_path, name) -> None:
    from benchmarks.evaluation.protocol import run_sequence
    from benchmarks.trackers import get_tracker
    from dvsot.dataset import Dataset

    options = {"siamfc": {}}.get(name, {"n_candidates": 12, "finetune_iters": 2, "energy_every": 1})
    with Dataset(dataset_path) as ds:
        res = run_sequence(get_tracker(name, **options), ds)
    assert res.error is None and res.tracked_segments > 0 and res.init_energy is not None
    e = energy_as_run([res])
    per_eval, per_init = e["per_evaluation"], e["per_initialisation"]
    assert e["evaluations_per_segment"] == (1 if name == "siamfc" else 12)
    assert e["per_segment"]["energy_pj"] == pytest.approx(per_eval["energy_pj"] * e["evaluations_per_segment"])
    seq = e["per_sequence"]["energy_pj"]
    assert seq == pytest.approx(len(res.init_segments) * per_init["energy_pj"]
                                + res.tracked_segments * e["per_segment"]["energy_pj"])
    if name == "sctn":  # spikes and C-LIF updates; fine-tuning: the spikes forward, dense MACs backward
        assert per_eval["synaptic"]["ac_ops"] > 0 and per_eval["synaptic"]["mac_ops"] == 0
        assert per_eval["state"]["state_updates"] > 0 and per_eval["state"]["activations"] == 0
        tuned_samples = 2 * 128
        model_cfg = get_tracker(name, **options).tracker.model.cfg
        assert per_init["synaptic"]["mac_ops"] == pytest.approx(BACKWARD_FACTOR * dense_macs(model_cfg) * tuned_samples)
        assert per_init["synaptic"]["ac_ops"] > 0 and per_init["state"]["state_updates"] > 0
    else:  # dense MACs and activations
        assert per_eval["synaptic"]["ac_ops"] == 0 and per_eval["synaptic"]["mac_ops"] > 0
        assert per_eval["state"]["activations"] > 0 and per_eval["state"]["state_updates"] == 0
        if name == "sctn_ann":  # fine-tuning: forward once and backward twice the evaluation's MACs per sample
            assert per_init["synaptic"]["mac_ops"] == pytest.approx(
                (1 + BACKWARD_FACTOR) * 2 * 128 * per_eval["synaptic"]["mac_ops"])
        else:  # the exemplar's forward pass, no fine-tuning
            assert 0 < per_init["synaptic"]["mac_ops"] < per_eval["synaptic"]["mac_ops"]
    assert e["paper_convention"]["energy_pj"] == pytest.approx(per_eval["synaptic"]["energy_pj"])
    assert np.isfinite(seq) and seq > per_init["energy_pj"]
