"""`dvsot train` refuses bad flags and bad outputs at once (exit 2, one line naming the flag or file), before any
training, leaving no file behind; a tiny run still writes the checkpoint and its metadata."""

import json
import sys
from pathlib import Path

import pytest
import torch

from dvsot.cli import main
from sctn.checkpoint import load_checkpoint

sys.path.insert(0, str(Path(__file__).parent))
from synthetic import moving_square_file  # noqa: E402

torch.set_num_threads(1)
TINY = ["--epochs", "1", "--segments-per-epoch", "2", "--batch-segments", "1", "--channels", "2", "2", "2",
        "--fc", "4", "4", "--threads", "1", "--quiet"]


@pytest.fixture(scope="module")
def data(tmp_path_factory) -> Path:
    """A small labelled dataset file (64x48, 60 ms)."""
    d = tmp_path_factory.mktemp("train_data")
    return moving_square_file(d / "syn.h5", width=64, height=48, size=12, duration_ms=60,
                              velocity_px_s=(100.0, 40.0), start=(10.0, 10.0))


@pytest.fixture
def no_training(monkeypatch):
    """Fail the test if training starts: every refusal must come before any work."""
    def boom(*args, **kwargs):
        raise AssertionError("training started")
    monkeypatch.setattr("sctn.train.train", boom)


def snapshot(*dirs: Path) -> dict:
    """Every file (dot files too) under dirs with its bytes."""
    return {str(p): (p.read_bytes() if p.is_file() else None) for d in dirs for p in sorted(d.rglob("*"))}


def assert_refused(argv, words, dirs, capsys) -> None:
    """`dvsot train argv` exits 2 with one line holding every one of words, and no file under dirs changes."""
    before = snapshot(*dirs)
    assert main(["train", *argv]) == 2, argv
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and all(w in err[0] for w in words), (argv, err)
    assert snapshot(*dirs) == before, argv


@pytest.mark.parametrize("flags, words", [
    (["--threads=-1"], ["--threads", ">= 1", "-1"]),
    (["--threads", "0"], ["--threads", ">= 1"]),
    (["--lr", "nan"], ["--lr", "finite", "nan"]),
    (["--lr", "inf"], ["--lr", "finite", "inf"]),
    (["--lr", "-1"], ["--lr", "positive"]),
    (["--max-minutes=-1"], ["--max-minutes", "positive", "-1"]),
    (["--max-minutes", "0"], ["--max-minutes", "positive"]),
    (["--max-minutes", "nan"], ["--max-minutes", "finite"]),
    (["--max-minutes", "inf"], ["--max-minutes", "finite"]),
    (["--ops-penalty", "inf"], ["--ops-penalty", "finite"]),
    (["--ops-penalty", "nan"], ["--ops-penalty", ">= 0"]),
    (["--seed=-1"], ["--seed", ">= 0"]),
    (["--epochs", "0"], ["--epochs", ">= 1"]),
    (["--segments-per-epoch=-3"], ["--segments-per-epoch", ">= 1"]),
    (["--batch-segments", "0"], ["--batch-segments", ">= 1"]),
])
def test_bad_numeric_flags_name_the_flag(data, tmp_path, capsys, no_training, flags, words):
    assert_refused(["--data", str(data), "-o", str(tmp_path / "m.pt"), *flags], words, [tmp_path, data.parent], capsys)


def test_output_that_is_a_directory_is_refused_before_training(data, tmp_path, capsys, no_training):
    (tmp_path / "adir").mkdir()
    assert_refused(["--data", str(data), "-o", str(tmp_path / "adir"), "--quiet"], ["adir", "-o", "directory"],
                   [tmp_path, data.parent], capsys)
    (tmp_path / "m.json").mkdir()  # the metadata file's place
    assert_refused(["--data", str(data), "-o", str(tmp_path / "m.pt"), "--quiet"], ["m.json", "directory"],
                   [tmp_path, data.parent], capsys)


def test_output_whose_metadata_would_replace_it_is_refused(data, tmp_path, capsys, no_training):
    assert_refused(["--data", str(data), "-o", str(tmp_path / "ck.json"), "--quiet"], ["ck.json", "-o", ".json"],
                   [tmp_path, data.parent], capsys)
    (tmp_path / "old.json").write_text("{}")  # an existing output is kept too
    assert_refused(["--data", str(data), "-o", str(tmp_path / "old.json"), "--quiet"], ["old.json", ".json"],
                   [tmp_path, data.parent], capsys)


def test_output_that_is_a_data_file_is_refused(data, tmp_path, capsys, no_training):
    assert_refused(["--data", str(data), "-o", str(data), "--quiet"], ["syn.h5", "input"], [tmp_path, data.parent],
                   capsys)
    copy = tmp_path / "d.json"  # a data file in the metadata's place
    copy.write_bytes(data.read_bytes())
    assert_refused(["--data", str(copy), "--split", "any", "-o", str(tmp_path / "d.pt"), "--quiet"], ["d.json", "input"],
                   [tmp_path, data.parent], capsys)


def test_tiny_run_writes_the_checkpoint_and_its_metadata(data, tmp_path, capsys):
    out = tmp_path / "m.pt"
    assert main(["train", "--data", str(data), "-o", str(out), *TINY]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["checkpoint"] == str(out) and summary["steps"] == 2
    model, meta = load_checkpoint(out)
    assert model.cfg.channels == (2, 2, 2) and meta["train_config"]["lr"] == 2e-3
    assert json.loads(out.with_suffix(".json").read_text())["train_config"]["epochs"] == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.json", "m.pt"]
