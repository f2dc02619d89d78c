"""Named ablation rows run on tiny synthetic data: the widths sweep (accuracy, ACs per evaluation and tracking speed
per row) and the background output neuron (trained by the mirrored error, or left out)."""

import json
import sys
from pathlib import Path

import pytest
import torch

from benchmarks.experiments.ablation import (
    MDNET_WIDTHS,
    ROWS,
    format_table,
    run_one,
    scaled_widths,
    summarise,
    training_key,
)
from sctn.checkpoint import load_checkpoint
from sctn.network import NetworkConfig

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
from synthetic import moving_square_file  # noqa: E402

torch.set_num_threads(1)
BUDGET = {"epochs": 1, "segments_per_epoch": 2, "batch_segments": 1, "lr": 3e-3, "max_minutes": None,
          "val_segments": 2}


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("ablation_rows")
    train = moving_square_file(d / "train.h5", width=64, height=48, size=12, duration_ms=60,
                               velocity_px_s=(100.0, 40.0), start=(10.0, 10.0))
    test = moving_square_file(d / "test.h5", width=64, height=48, size=14, duration_ms=50,
                              velocity_px_s=(-60.0, 30.0), start=(40.0, 8.0), split="test", seed=4)
    return [train], [test]


def test_the_widths_rows_go_from_the_preset_towards_mdnet():
    preset = NetworkConfig()
    assert ROWS["widths_x2"] == ({}, {"channels": tuple(2 * c for c in preset.channels),
                                      "fc": tuple(2 * n for n in preset.fc)}, {})
    assert ROWS["widths_x4"] == ({}, scaled_widths(4), {}) and scaled_widths(4)["channels"] == (32, 64, 64)
    assert ROWS["widths_mdnet"][1] == MDNET_WIDTHS == {"channels": (96, 256, 512), "fc": (512, 512)}
    for row in ("widths_x2", "widths_x4", "widths_mdnet"):
        assert training_key(row) == row  # each trains its own networks
        NetworkConfig(**ROWS[row][1])  # a valid network config


@pytest.mark.parametrize("row", ["widths_x2", "no_background_neuron"])
def test_a_row_reports_accuracy_operations_and_speed(files, tmp_path, row, monkeypatch):
    # the tracker fine-tunes once at initialisation (the preset: 10 times, most of the run's CPU time): the row's
    # training and network settings, which this test is about, are unchanged
    train_kw, net_kw, track_kw = ROWS[row]
    monkeypatch.setitem(ROWS, row, (train_kw, net_kw, {**track_kw, "finetune_iters": 1}))
    r = run_one(row, 0, *files, BUDGET, tmp_path, 8, 4)
    assert r["row"] == row and 0.0 <= r["ARscore"] <= 1.0 and r["segments"] > 0
    assert r["ac_ops_per_evaluation"] > 0 and r["ac_ops_per_segment"] == pytest.approx(8 * r["ac_ops_per_evaluation"])
    assert r["segments_per_s"] > 0 and r["init_seconds"] > 0
    model, _ = load_checkpoint(tmp_path / f"{row}_seed0.pt")
    assert model.cfg == NetworkConfig(**ROWS[row][1])  # the row's network, trained and tracked
    json.dumps(r)  # a runs.jsonl record


def test_the_table_has_a_speed_column():
    runs = [{"row": "widths_x2", "seed": s, "A": 0.7, "R": 0.9, "ARscore": 0.8, "ac_ops_per_evaluation": 2e5,
             "ac_ops_per_segment": 5e7, "segments_per_s": v} for s, v in ((0, 3.0), (1, 5.0))]
    header, _, line = format_table(summarise(runs)).splitlines()
    cells = [c.strip() for c in line.split("|")]
    assert "segments/s" in header and cells[header.split("|").index(" segments/s ")] == "4.00"


def test_the_reinit_and_error_time_rows_and_the_renamed_ones(tmp_path, capsys):
    from benchmarks.experiments.ablation import main

    assert ROWS["paper"] == ({}, {}, {}) and ROWS["online_tuning"] == ({}, {}, {"reinit": "online"})
    assert ROWS["tuned_once"] == ({}, {}, {"reinit": "once"}) and training_key("tuned_once") == "paper"
    assert ROWS["stca_code"] == ({"error_time": "stca_code"}, {}, {"error_time": "stca_code"})
    for old, new in (("finetune_first_only", "tuned_once"), ("reinit_from_trained", "paper")):
        with pytest.raises(SystemExit) as exit_:
            main(["--rows", old, "--out", str(tmp_path / "out")])
        assert exit_.value.code == 2 and f"--rows {old}: renamed; it is now {new}" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()
