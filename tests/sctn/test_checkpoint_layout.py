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


def test_shipped_checkpoint_is_the_paper_preset_and_silent_on_an_empty_input():
    import warnings

    from sctn.checkpoint import load_checkpoint

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        model, meta = load_checkpoint(None)
    # no legacy-layout note; one line saying it was trained with the old error-time rule (no error_time recorded)
    assert [type(w.message).__name__ for w in caught] == ["TrainingRuleWarning"]
    assert "sctn_dvsot21.pt: trained with the old error-time rule" in str(caught[0].message)
    assert "\n" not in str(caught[0].message)
    assert model.cfg.steps == 10 and model.cfg.tail_steps == 0 and not model.cfg.bias
    cfg = meta["train_config"]
    assert cfg["loss"] == "exp" and not cfg["squared_error"] and not cfg["background_term"]
    assert cfg["ops_penalty"] == 0 and not cfg["calibrate"]
    with torch.no_grad():
        volts, spikes = model.forward_record(torch.zeros(2, 10, 2, 107, 107))
    assert [float(s.sum()) for s in spikes] == [0.0] * 7 and float(volts.abs().max()) == 0.0
