"""Energy stated one way everywhere: per evaluation and per tracked segment from sctn.energy.tracker_energy, the
paper's Table 3 restated the same two ways, and neuron-state updates counted apart."""

from __future__ import annotations

import pytest
import torch

from sctn.energy import E_AC_PJ, E_CLIF_UPDATE_PJ, E_MAC_PJ, count_activations, snn_state_updates, tracker_energy
from sctn.network import NetworkConfig


def test_tracker_energy_per_evaluation_and_per_segment() -> None:
    row = tracker_energy(256, ac_ops=1000.0, mac_ops=10.0, state_updates=50.0)
    e, s = row["per_evaluation"], row["per_segment"]
    assert e["energy_pj"] == pytest.approx(1000 * E_AC_PJ + 10 * E_MAC_PJ)
    assert s["ac_ops"] == 256_000 and s["mac_ops"] == 2560 and s["energy_pj"] == pytest.approx(256 * e["energy_pj"])
    assert s["state_updates"] == 256 * 50 and s["state_energy_pj"] == pytest.approx(256 * 50 * E_CLIF_UPDATE_PJ)
    assert E_CLIF_UPDATE_PJ == pytest.approx(3 * 3.7 + 4 * 0.9)
    frame = tracker_energy(1, mac_ops=4.82e9)
    assert frame["per_segment"] == frame["per_evaluation"] and frame["per_segment"]["state_updates"] is None


def test_state_updates_by_hand() -> None:
    cfg = NetworkConfig()  # conv 8 x 26^2, 16 x 12^2, 16 x 10^2; fc 64, 32; 2 outputs; 10 steps
    assert snn_state_updates(cfg) == (8 * 26 * 26 + 16 * 12 * 12 + 16 * 10 * 10 + 64 + 32 + 2) * 10
    assert snn_state_updates(NetworkConfig(tail_steps=2)) == snn_state_updates(cfg) / 10 * 12
    from sctn.ann import SCTNTwin

    twin = SCTNTwin()
    acts = count_activations(twin, torch.zeros(1, 10, 2, 107, 107))
    assert acts == 8 * 26 * 26 + 16 * 12 * 12 + 16 * 10 * 10 + 64 + 32  # the outputs have no activation


def test_paper_rows_restated_both_ways_and_the_twin_with_summed_input() -> None:
    from benchmarks.analysis.energy_table import ann_rows, paper_rows
    from sctn.ann import SCTNTwin, TwinConfig, twin_macs

    rows = paper_rows(256)
    sctn, rpn = rows["paper SCTN (Table 3, per evaluation)"], rows["paper SiamRPN (Table 3, per frame)"]
    # rows keep their per-segment figures at the top and per_evaluation beside them
    assert sctn["per_evaluation"]["ac_ops"] == 7.69e6 and sctn["ac_ops"] == 7.69e6 * 256
    assert sctn["evaluations_per_segment"] == 256 and rpn["evaluations_per_segment"] == 1
    assert rpn["mac_ops"] == rpn["per_evaluation"]["mac_ops"] == 4.82e9
    # per tracked segment the paper's SiamRPN costs about 12.5x its SCTN, not 3203x
    assert rpn["energy_pj"] / sctn["energy_pj"] == pytest.approx(12.5, rel=0.01)
    twins = ann_rows(256, twin=SCTNTwin())
    summed = twins["SCTN's ANN twin (sctn_ann, input sum)"]
    assert summed["per_evaluation"]["mac_ops"] == twin_macs(SCTNTwin(TwinConfig(input="sum")))["mac_ops"]
    assert (
        summed["per_evaluation"]["mac_ops"]
        < twins["SCTN's ANN twin (sctn_ann, input bins)"]["per_evaluation"]["mac_ops"]
    )


def test_ablation_rows_for_the_rule_the_inits_and_the_tracker() -> None:
    from benchmarks.experiments.ablation import ROWS, training_key

    assert ROWS["error_time_max"][0] == {"error_time": "max"} and ROWS["error_time_max"][2] == {"error_time": "max"}
    assert ROWS["calibration"][0] == {"init": "calibrate"} and ROWS["init_fluctuation"][0] == {"init": "fluctuation"}
    for row, option in (
        ("finetune_balanced", {"finetune_balanced": True}),
        ("finetune_fc_only", {"finetune_layers": "fc"}),
        ("tuned_once", {"reinit": "once"}),
        ("online_tuning", {"reinit": "online"}),
    ):
        assert ROWS[row] == ({}, {}, option) and training_key(row) == "paper"  # the preset's networks, tuned otherwise
    assert ROWS["background_term"][0] == {"background_term": True}


def test_learning_curves_read_the_history_and_draw(tmp_path) -> None:
    import json

    from benchmarks.analysis.learning_curves import main, read_curves

    meta = {"model": "sctn", "train_config": {"seed": 3}, "history": {"validation": "files", "val": [
        {"step": 50, "loss": 0.4, "accuracy": 0.8}, {"step": 100, "loss": 0.3, "accuracy": 0.9, "arscore": 0.7},
        {"step": 100, "loss": 0.3, "accuracy": 0.9, "arscore": 0.71}]}}
    path = tmp_path / "c.json"
    path.write_text(json.dumps(meta))
    c = read_curves(path)
    assert c["loss"] == [(50, 0.4), (100, 0.3)] and c["arscore"] == [(100, 0.71)] and "seed 3" in c["label"]
    assert main([str(path), "-o", str(tmp_path / "c.png")]) == 0 and (tmp_path / "c.png").stat().st_size > 0
    empty = tmp_path / "e.json"
    empty.write_text(json.dumps({"history": {"val": []}}))
    assert main([str(empty), "-o", str(tmp_path / "e.png")]) == 2 and not (tmp_path / "e.png").exists()
