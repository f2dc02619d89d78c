"""Crafted checkpoint fields are refused on open in one line naming what is wrong: an unknown version, a digest of
the wrong type, a config with no time steps, learned time constants whose kernel is not finite (NaN in NIR)."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
import torch

from dvsot.cli import main
from dvsot.core.errors import UserError
from sctn.checkpoint import DIGEST_KEY, default_checkpoint_path, load_checkpoint, weights_digest

torch.set_num_threads(1)


def _crafted(tmp_path: Path, change) -> Path:
    """A copy of the shipped SCTN checkpoint with change(blob) applied; its weights' digest kept true to them."""
    blob = torch.load(default_checkpoint_path(), map_location="cpu", weights_only=True)
    change(blob)
    if isinstance(blob["meta"].get(DIGEST_KEY), str):
        blob["meta"][DIGEST_KEY] = weights_digest(blob["state_dict"])
    out = tmp_path / "c.pt"
    torch.save(blob, out)
    shutil.copy(default_checkpoint_path().with_suffix(".json"), tmp_path / "c.json")
    return out


def _set(*keys, value):
    def change(blob):
        d = blob
        for k in keys[:-1]:
            d = d[k]
        d[keys[-1]] = value
    return change


def _huge_time_constant(blob):
    name = next(k for k in blob["state_dict"] if k.endswith("p_s"))
    blob["state_dict"][name][0] = 1e30


@pytest.mark.parametrize("change, words", [
    (_set("version", value=99), r"SCTN checkpoint version 99 is not one this dvsot reads \(1\)"),
    (_set("version", value=True), r"SCTN checkpoint version True is not one"),
    (_set("meta", DIGEST_KEY, value=12345), rf"damaged SCTN checkpoint: its {DIGEST_KEY} is int 12345"),
    (_set("config", "steps", value=0), r"config field 'steps' is 0 \(input should be greater than or equal to 1"),
    (_set("config", "steps", value=-3), r"config field 'steps' is -3"),
    (_huge_time_constant, r"C-LIF layer 0 channel 0 has time constants .* alpha_s 1e\+30 ms, whose PSP kernel is "
                          r"not finite"),
])
def test_crafted_checkpoint_fields_are_refused(tmp_path: Path, change, words) -> None:
    path = _crafted(tmp_path, change)
    with pytest.raises(UserError, match=rf"^{tmp_path}/c\.pt: .*{words}"):
        load_checkpoint(path)


def test_export_model_refuses_an_extreme_time_constant_in_one_line(tmp_path: Path, capsys) -> None:
    path = _crafted(tmp_path, _huge_time_constant)
    out = tmp_path / "m.nir"
    assert main(["export-model", str(path), "-o", str(out)]) == 2
    # the shipped checkpoint's one-line note on its recipe is not an error
    err = [line for line in capsys.readouterr().err.strip().splitlines() if ": note: " not in line]
    assert len(err) == 1 and "not finite" in err[0] and not out.exists()


def test_an_untouched_copy_loads(tmp_path: Path) -> None:
    model, meta = load_checkpoint(_crafted(tmp_path, lambda blob: None))
    assert model.cfg.steps == 10 and isinstance(meta[DIGEST_KEY], str)
