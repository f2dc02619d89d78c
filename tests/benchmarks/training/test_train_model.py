"""`benchmarks.train_model` makes every refusal `dvsot train` makes, naming parameters where the command names flags,
before any training; a model registered once in the training registry is trained by both."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
import torch
from synthetic import small_square_file

import benchmarks
from benchmarks.training import registry
from dvsot.cli import build_parser, main
from dvsot.core.errors import RunError, UserError

torch.set_num_threads(1)
TINY = {"epochs": 1, "segments_per_epoch": 2, "batch_segments": 1, "channels": (2, 2, 2), "fc": (4, 4)}
TINY_FLAGS = ["--epochs", "1", "--segments-per-epoch", "2", "--batch-segments", "1", "--channels", "2", "2", "2",
              "--fc", "4", "4", "--quiet"]


@pytest.fixture(scope="module")
def data(tmp_path_factory) -> Path:
    """A small labelled dataset file (64x48, 60 ms)."""
    return small_square_file(tmp_path_factory.mktemp("train_model_data"))


@pytest.fixture
def no_training(refuse_calls):
    """Fail the test if any model's training starts: every refusal comes before any work."""
    refuse_calls("sctn.training.snn.train", "sctn.ann.train_twin", "benchmarks.trackers.siamfc.train.train_siamfc")


def names(message: str, word: str) -> bool:
    """Whether message names `word` as a word of its own (not inside a path)."""
    return re.search(rf"(^|[\s(]){re.escape(word)}([\s:]|$)", message) is not None


CASES = [  # (python keyword arguments, command flags, parameter, flag)
    ({"epochs": 0}, ["--epochs", "0"], "epochs", "--epochs"),
    ({"segments_per_epoch": -3}, ["--segments-per-epoch=-3"], "segments_per_epoch", "--segments-per-epoch"),
    ({"lr": float("nan")}, ["--lr", "nan"], "lr", "--lr"),
    ({"threads": 0}, ["--threads", "0"], "threads", "--threads"),
    ({"tail_steps": -1}, ["--tail-steps=-1"], "tail_steps", "--tail-steps"),
    ({"channels": (0, 2, 2)}, ["--channels", "0", "2", "2"], "channels", "--channels"),
    ({"model": "siamfc", "init": "fluctuation"}, ["--model", "siamfc", "--init", "fluctuation"], "init", "--init"),
    ({"model": "sctn_ann", "ops_penalty": 1.0}, ["--model", "sctn_ann", "--ops-penalty", "1"], "ops_penalty",
     "--ops-penalty"),
    ({"val_arscore_every": 5}, ["--val-arscore-every", "5"], "val_arscore_every", "--val-arscore-every"),
    ({"val_arscore_segments": 0}, ["--val-arscore-segments", "0"], "val_arscore_segments", "--val-arscore-segments"),
]


@pytest.mark.parametrize("kwargs, flags, param, flag", CASES)
def test_the_same_refusal_from_python_and_from_the_command(data, tmp_path, capsys, no_training, kwargs, flags, param,
                                                          flag):
    out = tmp_path / "m.pt"
    with pytest.raises(UserError) as caught:
        benchmarks.train_model(data=[data], out_path=out, **kwargs)
    text = str(caught.value)
    assert names(text, param) and not names(text, flag), text
    assert main(["train", "--data", str(data), "-o", str(out), *flags]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and names(err[0], flag) and not names(err[0], param), err
    assert sorted(tmp_path.iterdir()) == []


def test_an_output_that_is_an_input_is_refused_both_ways(data, capsys, no_training):
    before = data.read_bytes()
    with pytest.raises(UserError, match="out_path would overwrite an input file"):
        benchmarks.train_model(data=[data], out_path=data)
    assert main(["train", "--data", str(data), "-o", str(data)]) == 2
    assert "-o would overwrite an input file" in capsys.readouterr().err
    assert data.read_bytes() == before


def test_validation_apart_from_training_both_ways(data, tmp_path, capsys, no_training):
    with pytest.raises(UserError, match=r"in both data and val_data"):
        benchmarks.train_model(data=[data], val_data=[data], out_path=tmp_path / "m.pt")
    assert main(["train", "--data", str(data), "--val-data", str(data), "-o", str(tmp_path / "m.pt")]) == 2
    assert "in both --data and --val-data" in capsys.readouterr().err


def test_a_silent_network_is_not_saved_from_python(data, tmp_path, monkeypatch):
    def silent(files, cfg, progress=True):
        from sctn.network import SCTN

        return SCTN(cfg.network), {"val": [{"vmax_max": 0.0}], "silent": True, "val_segments": 2}

    monkeypatch.setattr("sctn.training.snn.train", silent)
    out = tmp_path / "m.pt"
    out.write_bytes(b"kept")
    with pytest.raises(RunError, match="silent.*another seed or init calibrate / fluctuation"):
        benchmarks.train_model(data=[data], out_path=out, progress=False, **TINY)
    assert out.read_bytes() == b"kept" and sorted(p.name for p in tmp_path.iterdir()) == ["m.pt"]


def test_a_model_registered_once_trains_from_python_and_from_the_command(data, tmp_path, capsys, monkeypatch):
    calls = []

    def train_toy(files, cfg, progress=True):
        from sctn.network import SCTN

        calls.append((list(map(str, files)), cfg.epochs, cfg.segments_per_epoch))
        return SCTN(cfg.network), {"val": [], "steps": 1, "minutes": 0.0, "train_segments": 1, "val_segments": 0,
                                   "train_loss": []}

    monkeypatch.setitem(registry.TRAINERS, "toy", registry.Trainer(
        train=f"{__name__}:_toy", config="sctn.training.snn:TrainConfig", network="sctn.network:NetworkConfig",
        tracker="benchmarks.training.run:sctn_tracker", settings=("channels", "fc"),
        defaults={"bias": False, "no_background_neuron": False}))
    monkeypatch.setattr(f"{__name__}._toy", train_toy, raising=False)
    summary = benchmarks.train_model("toy", [data], tmp_path / "a.pt", progress=False, **TINY)
    assert summary["model"] == "toy" and (tmp_path / "a.pt").is_file()
    assert "toy" in build_parser()._subparsers._group_actions[0].choices["train"].format_help()
    assert main(["train", "--model", "toy", "--data", str(data), "-o", str(tmp_path / "b.pt"), *TINY_FLAGS]) == 0
    assert calls == [([str(data)], 1, 2)] * 2
    with pytest.raises(UserError, match="init: not a setting of model toy"):
        benchmarks.train_model("toy", [data], tmp_path / "c.pt", init="calibrate")
