"""bench_training --row: the timed network is the ablation row's, and bad options stop before any timing."""

import subprocess
import sys

import pytest

from benchmarks.experiments.ablation import MDNET_WIDTHS, PRESET_NET, scaled_widths
from benchmarks.perf.bench_training import budget_steps, row_model


def test_row_model_has_the_rows_widths():
    assert row_model("widths_x2").cfg.channels == scaled_widths(2)["channels"]
    assert row_model("widths_mdnet").cfg.fc == MDNET_WIDTHS["fc"]
    assert row_model("paper").cfg.channels == PRESET_NET.channels


def test_row_model_is_seeded():
    a, b = row_model("widths_x2"), row_model("widths_x2")
    assert all((p == q).all() for p, q in zip(a.parameters(), b.parameters()))


def test_unknown_row_is_one_line():
    with pytest.raises(SystemExit, match="unknown ablation row 'nope'"):
        row_model("nope")


def test_budget_steps():
    assert budget_steps({"epochs": 5, "segments_per_epoch": 1080, "batch_segments": 2}) == 2700


@pytest.mark.parametrize("args, message", [(["--budget-steps", "0"], "--budget-steps must be >= 1"),
                                           (["--row", "widths_x2", "--full", "data"], "does not take --row")])
def test_bad_options_exit_2(args, message):
    r = subprocess.run([sys.executable, "-m", "benchmarks.perf.bench_training", *args], capture_output=True, text=True)
    assert r.returncode == 2 and message in r.stderr
