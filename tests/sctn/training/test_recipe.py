"""One recipe: `dvsot train` with no flags builds TrainConfig() (the twin: its TwinConfig network), TrainConfig's
defaults are the recipe a shipped checkpoint records, and a checkpoint trained with another recipe loads with one
note naming each setting that differs."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import pytest

from dvsot.cli import main
from tests.synthetic import moving_square_file


class _Built(Exception):
    """Raised by the patched trainer: the config was built, no training runs."""


@pytest.fixture(scope="module")
def data(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("recipe")
    return moving_square_file(d / "syn.h5", width=64, height=48, size=12, duration_ms=40,
                              velocity_px_s=(100.0, 40.0), start=(10.0, 10.0))


@pytest.mark.parametrize("model, trainer", [("sctn", "sctn.training.snn.train"), ("sctn_ann", "sctn.ann.train_twin")])
def test_train_with_no_flags_builds_the_recipe(model: str, trainer: str, data: Path, tmp_path: Path,
                                               monkeypatch) -> None:
    from sctn.ann import TwinConfig
    from sctn.training.snn import TrainConfig

    built = []

    def capture(files, cfg, **kwargs):
        built.append(cfg)
        raise _Built

    monkeypatch.setattr(trainer, capture)
    with pytest.raises(_Built):
        main(["train", "--model", model, "--data", str(data), "-o", str(tmp_path / "m.pt"), "--quiet"])
    expected = TrainConfig() if model == "sctn" else TrainConfig(network=TwinConfig())
    assert built == [expected] and type(built[0].network) is type(expected.network)
    assert not (tmp_path / "m.pt").exists()


def test_the_recipe_is_what_the_shipped_twin_records() -> None:
    """The twin ships trained with the recipe: its recorded settings are TrainConfig's defaults, setting by setting."""
    from sctn.ann import TwinConfig, default_twin_path
    from sctn.training.snn import RUN_SETTINGS, TrainConfig, recipe, training_note

    recorded = json.loads(default_twin_path().with_suffix(".json").read_text())["train_config"]
    preset = recipe(TwinConfig())
    assert {k: v for k, v in recorded.items() if k in preset and k != "network"} == \
        {k: v for k, v in preset.items() if k != "network"}
    assert {k: recorded["network"][k] for k in preset["network"]} == preset["network"]
    assert training_note(recorded, TwinConfig(), skip_network=()) is None
    # what the recipe leaves out shapes nothing trained; everything else TrainConfig has is in it
    assert set(preset) | set(RUN_SETTINGS) == set(TrainConfig.model_fields)
    assert TrainConfig().planned_steps(10**6) == recorded["epochs"] * recorded["segments_per_epoch"] // \
        recorded["batch_segments"]


def _notes(call) -> list[str]:
    from sctn.checkpoint import TrainingRuleWarning

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        call()
    return [str(w.message) for w in caught if issubclass(w.category, TrainingRuleWarning)]


@pytest.mark.parametrize("name", ["dvsot21", "varied"])
def test_the_shipped_sctn_checkpoints_are_trained_with_the_recipe(name: str) -> None:
    """sctn_dvsot21 and its varied sibling are seed 0 of the recipe: their recorded settings are TrainConfig's
    defaults, setting by setting, and they load without a note."""
    from sctn.checkpoint import load_checkpoint, shipped_checkpoint_path
    from sctn.training.snn import recipe, training_note

    path = shipped_checkpoint_path(name)
    recorded = json.loads(path.with_suffix(".json").read_text())["train_config"]
    preset = recipe()
    assert {k: v for k, v in recorded.items() if k in preset and k != "network"} == \
        {k: v for k, v in preset.items() if k != "network"}
    assert {k: recorded["network"][k] for k in preset["network"]} == preset["network"]
    assert recorded["seed"] == 0 and training_note(recorded) is None
    assert _notes(lambda: load_checkpoint(path)) == []


def test_an_older_recipe_is_named_setting_by_setting(tmp_path: Path) -> None:
    from sctn.ann import SCTNTwin, TwinConfig, load_twin
    from sctn.checkpoint import load_checkpoint, save_checkpoint
    from sctn.network import SCTN
    from sctn.training.snn import TrainConfig

    old = TrainConfig(epochs=3, segments_per_epoch=400, batch_segments=4, lr=2e-3, loss="linear").model_dump()
    path = save_checkpoint(tmp_path / "old.pt", SCTN(), {"train_config": old})
    notes = _notes(lambda: load_checkpoint(path))
    assert len(notes) == 1 and notes[0].startswith(f"{path}: trained with another recipe")
    for phrase in ("epochs 3 (the recipe's 1)", "segments_per_epoch 400", "batch_segments 4", "lr 0.002",
                   "loss 'linear' (the recipe's 'exp')"):
        assert phrase in notes[0], phrase
    # which seed, when it validated and a time limit shape nothing trained: no note for them
    other_run = TrainConfig(seed=4, val_every=7, val_segments=3, max_minutes=5.0).model_dump()
    assert _notes(lambda: load_checkpoint(save_checkpoint(tmp_path / "s.pt", SCTN(), {"train_config": other_run}))) \
        == []
    # a setting recorded before it existed ran as the recipe has it (lr_schedule), or as its old flag said (init)
    legacy = {k: v for k, v in TrainConfig().model_dump().items() if k not in ("lr_schedule", "init")}
    assert _notes(lambda: load_checkpoint(save_checkpoint(tmp_path / "l.pt", SCTN(), {"train_config": legacy}))) == []
    # the twin's note compares with the twin's network
    twin_old = TrainConfig(lr=1e-3, network=TwinConfig(input="sum")).model_dump()
    twin = save_checkpoint(tmp_path / "t.pt", SCTNTwin(TwinConfig(input="sum")), {"train_config": twin_old},
                           kind="sctn_ann")
    notes = _notes(lambda: load_twin(twin))
    assert len(notes) == 1 and "lr 0.001" in notes[0] and "network input 'sum' (the recipe's 'bins')" in notes[0]
