"""The learning-rate schedule every trainer shares (sctn.training.loop): constant (the default) or cosine to 0."""

import json
import math

import numpy as np
import pytest
import torch

from sctn.training.loop import TrainBudget, TrainConfigError, fit, lr_factor


def test_the_factors_in_closed_form():
    assert [lr_factor("constant", k, 8) for k in (0, 4, 8)] == [1.0, 1.0, 1.0]
    assert lr_factor("cosine", 0, 8) == 1.0
    assert lr_factor("cosine", 4, 8) == pytest.approx(0.5)
    assert lr_factor("cosine", 2, 8) == pytest.approx((1 + math.cos(math.pi / 4)) / 2)
    assert lr_factor("cosine", 8, 8) == pytest.approx(0.0) and lr_factor("cosine", 9, 8) == pytest.approx(0.0)


@pytest.mark.parametrize("schedule", ["constant", "cosine"])
def test_each_step_trains_at_its_scheduled_rate(schedule):
    model = torch.nn.Linear(1, 1)
    opt = torch.optim.Adam(model.parameters(), lr=0.1)
    cfg = TrainBudget(epochs=2, segments_per_epoch=4, batch_segments=1, lr=0.1, lr_schedule=schedule)
    seen = []

    def batch_loss(batch):
        seen.append(opt.param_groups[0]["lr"])
        return (model.weight.sum() - 1.0) ** 2, {}

    history = fit(model, opt, list(range(4)), cfg, np.random.default_rng(0), batch_loss, None, str, {}, progress=False)
    assert history["steps"] == 8
    assert seen == pytest.approx([0.1 * lr_factor(schedule, k, 8) for k in range(8)])


def test_an_unknown_schedule_names_the_field():
    with pytest.raises(TrainConfigError, match="lr_schedule"):
        TrainBudget(lr_schedule="step")


def test_the_command_records_the_schedule(tmp_path):
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from synthetic import moving_square_file

    from dvsot.cli import main

    data = moving_square_file(tmp_path / "syn.h5", width=64, height=48, size=12, duration_ms=60, split="train")
    out = tmp_path / "c.pt"
    assert main(["train", "--data", str(data), "-o", str(out), "--epochs", "1", "--segments-per-epoch", "2",
                 "--batch-segments", "1", "--channels", "2", "2", "2", "--fc", "4", "4", "--threads", "1",
                 "--lr-schedule", "cosine", "--quiet"]) == 0
    assert json.loads(out.with_suffix(".json").read_text())["train_config"]["lr_schedule"] == "cosine"
