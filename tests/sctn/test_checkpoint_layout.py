"""The network layout a checkpoint holds: the older layout (biases, tail steps) loads with a note naming the
file; the shipped checkpoint is the paper preset, silent on an empty input."""

import pytest
import torch

from sctn.network import SCTN, NetworkConfig

torch.set_num_threads(1)


def test_legacy_checkpoint_loads_with_a_note_naming_the_file(tmp_path):
    from sctn.checkpoint import LegacyLayoutWarning, load_checkpoint, save_checkpoint

    old = SCTN(NetworkConfig(bias=True, tail_steps=2))
    path = save_checkpoint(tmp_path / "old.pt", old, {})
    blob = torch.load(path, weights_only=True)
    del blob["config"]["bias"]  # as written before the bias became a setting
    torch.save(blob, path)
    with pytest.warns(LegacyLayoutWarning, match=r"old\.pt: not the paper preset: layers with biases.*2 empty tail"):
        model, _ = load_checkpoint(path)
    assert model.cfg.bias and model.cfg.tail_steps == 2
    save_checkpoint(tmp_path / "new.pt", SCTN(), {})
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        load_checkpoint(tmp_path / "new.pt")


@pytest.mark.parametrize("name", ["dvsot21", "varied"])
def test_shipped_checkpoint_is_the_paper_preset_and_silent_on_an_empty_input(name):
    import warnings

    from sctn.checkpoint import TrainingRuleWarning, load_checkpoint, shipped_checkpoint_path

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        model, meta = load_checkpoint(shipped_checkpoint_path(name))
    # today's layout, rule and initialisation; a note, if any, names only the training budget it ran longer for
    notes = [str(w.message) for w in caught]
    assert all(issubclass(w.category, TrainingRuleWarning) for w in caught), notes
    for note in notes:
        named = {phrase.split(" ")[0] for phrase in note.split("`dvsot train`'s: ")[1].split(", ")}
        assert named <= {"epochs", "segments_per_epoch"}, note
    assert model.cfg.steps == 10 and model.cfg.tail_steps == 0 and not model.cfg.bias
    cfg = meta["train_config"]
    assert cfg["loss"] == "exp" and not cfg["squared_error"] and not cfg["background_term"]
    # keys a run's .json lacks were not settings yet when it was written: their default then is today's
    assert cfg["ops_penalty"] == 0 and not cfg.get("calibrate", False)
    assert cfg["error_time"] == "stca" and cfg["init"] == "kaiming" and cfg.get("lr_schedule", "constant") == "constant"
    with torch.no_grad():
        volts, spikes = model.forward_record(torch.zeros(2, 10, 2, 107, 107))
    assert [float(s.sum()) for s in spikes] == [0.0] * 7 and float(volts.abs().max()) == 0.0


def test_an_unknown_shipped_name_is_refused_naming_the_choices():
    from dvsot.core.errors import UserError
    from sctn.checkpoint import SHIPPED, shipped_checkpoint_path

    assert all(shipped_checkpoint_path(name).is_file() for name in SHIPPED)
    with pytest.raises(
        UserError, match=r"'nope': no shipped SCTN checkpoint of that name \(choose from dvsot21, varied\)"
    ):
        shipped_checkpoint_path("nope")
