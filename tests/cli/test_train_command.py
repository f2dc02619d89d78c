"""`dvsot train` refuses bad flags and bad outputs at once (exit 2, one line naming the flag or file), before any
training, leaving no file behind; a tiny run still writes the checkpoint and its metadata."""

import json
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from dvsot.cli import main
from sctn.checkpoint import load_checkpoint

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from synthetic import moving_square_file, small_square_file  # noqa: E402

torch.set_num_threads(1)
TINY = ["--epochs", "1", "--segments-per-epoch", "2", "--batch-segments", "1", "--channels", "2", "2", "2",
        "--fc", "4", "4", "--threads", "1", "--quiet"]


@pytest.fixture(scope="module")
def data(tmp_path_factory) -> Path:
    """A small labelled dataset file (64x48, 60 ms)."""
    return small_square_file(tmp_path_factory.mktemp("train_data"))


@pytest.fixture
def no_training(refuse_calls):
    """Fail the test if training starts: every refusal must come before any work."""
    refuse_calls("sctn.training.snn.train")


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
    assert_refused(
        ["--data", str(copy), "--split", "any", "-o", str(tmp_path / "d.pt"), "--quiet"],
        ["d.json", "input"],
        [tmp_path, data.parent],
        capsys,
    )


def test_tiny_run_writes_the_checkpoint_and_its_metadata(data, tmp_path, capsys):
    out = tmp_path / "m.pt"
    assert main(["train", "--data", str(data), "-o", str(out), *TINY]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["checkpoint"] == str(out) and summary["steps"] == 2
    model, meta = load_checkpoint(out)
    from sctn.training.snn import TrainConfig

    assert model.cfg.channels == (2, 2, 2) and meta["train_config"]["lr"] == TrainConfig().lr  # the recipe's
    assert json.loads(out.with_suffix(".json").read_text())["train_config"]["epochs"] == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.json", "m.pt"]


def test_calibration_is_a_deviation_off_by_default(data, tmp_path, capsys):
    """`dvsot train` trains the paper preset: no data-driven initial scale unless --calibrate asks for it."""
    out = tmp_path / "m.pt"
    assert main(["train", "--data", str(data), "-o", str(out), *TINY, "--calibrate"]) == 0
    capsys.readouterr()
    assert load_checkpoint(out)[1]["train_config"]["init"] == "calibrate"
    from dvsot.cli import build_parser
    assert build_parser().parse_args(["train"]).calibrate is None  # unset: TrainConfig's default (kaiming)
    assert build_parser().parse_args(["train"]).init is None


def test_a_silent_network_is_refused_and_the_old_checkpoint_kept(data, tmp_path, capsys, monkeypatch):
    """Training that ends with a target output that never rises above 0 exits 1 naming the file; -o keeps its bytes."""
    import sctn.training.snn
    from sctn.network import SCTN, NetworkConfig

    def dead(files, cfg, progress=True):
        model = SCTN(NetworkConfig(channels=(2, 2, 2), fc=(4, 4)))
        with torch.no_grad():
            for p in model.parameters():
                p.zero_()
        with sctn.training.snn.Dataset(files[0]) as ds:
            segs = [ds.segment(i) for i in sctn.training.snn.usable_segments(ds, cfg.min_box_px)[:2]]
        x, iou, pos = sctn.training.snn.segment_batch(
            [(s.events, s.t0_us, s.box) for s in segs], [(64, 48)] * len(segs), np.random.default_rng(0), model.cfg
        )
        final = sctn.training.snn.evaluate(model, x, iou, pos, cfg)
        assert final["vmax_max"] == 0.0  # zero weights: no current, no voltage, on every sample
        return model, {"val": [final], "silent": final["vmax_max"] <= 0, "steps": 0, "minutes": 0.0,
                       "train_segments": 2, "val_segments": 2}

    monkeypatch.setattr("sctn.training.snn.train", dead)  # the registry looks its trainer up at each run
    out = tmp_path / "m.pt"
    out.write_bytes(b"a good checkpoint")
    assert main(["train", "--data", str(data), "-o", str(out), *TINY]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(out) in err[0] and "silent" in err[0], err
    assert out.read_bytes() == b"a good checkpoint" and sorted(p.name for p in tmp_path.iterdir()) == ["m.pt"]


def test_validation_files_learning_curves_and_arscore_in_the_history(data, tmp_path, capsys):
    """--val-data validates on its own files (every training segment then trains); each validation entry has the
    loss, accuracy, target V_max on positives and the training loss since the last one; --val-arscore-every adds
    the validation sequences' ARscore; all of it lands in the checkpoint's .json."""
    val = moving_square_file(tmp_path / "val.h5", width=64, height=48, size=12, duration_ms=40,
                             velocity_px_s=(-80.0, 30.0), start=(40.0, 10.0), split="val", seed=3)
    out = tmp_path / "m.pt"
    args = ["train", "--data", str(data), "-o", str(out), *TINY, "--val-data", str(val), "--val-every", "1",
            "--val-segments", "2", "--val-arscore-every", "2", "--val-arscore-segments", "3"]
    assert main(args) == 0
    capsys.readouterr()
    meta = json.loads(out.with_suffix(".json").read_text())
    history = meta["history"]
    assert history["validation"] == "files" and history["val_segments"] == 2 and history["steps"] == 2
    assert history["train_segments"] == 6  # 60 ms: all six usable segments train, none held out
    steps = [v["step"] for v in history["val"]]
    assert steps[:2] == [1, 2]
    assert all({"loss", "accuracy", "vmax_pos", "train_loss_mean"} <= set(v) for v in history["val"])
    assert "arscore" not in history["val"][0] and 0.0 <= history["val"][1]["arscore"] <= 1.0
    assert isinstance(history["nearly_silent"], bool) and "target_vmax_pos" in history


@pytest.mark.parametrize("model, extra, figures", [
    ("sctn_ann", ["--channels", "2", "2", "2", "--fc", "4", "4"], {"loss", "accuracy", "vmax_pos"}),
    ("siamfc", [], {"loss", "centre_error_px"}),
])
def test_every_model_takes_the_validation_flags_and_draws_a_curve(data, tmp_path, capsys, model, extra, figures):
    """The twin and SiamFC validate on --val-data as SCTN does: every --val-every steps the validation figures and
    the training loss since the last one, every --val-arscore-every steps and at the end the validation ARscore, in
    the checkpoint's .json that learning_curves reads."""
    from benchmarks.analysis.learning_curves import main as curves_main
    from benchmarks.analysis.learning_curves import read_curves

    val = moving_square_file(tmp_path / "val.h5", width=64, height=48, size=12, duration_ms=40,
                             velocity_px_s=(-80.0, 30.0), start=(40.0, 10.0), split="val", seed=3)
    out = tmp_path / f"{model}.pt"
    tiny = ["--epochs", "1", "--segments-per-epoch", "3", "--batch-segments", "1", "--threads", "1", "--quiet"]
    assert main(["train", "--model", model, "--data", str(data), "-o", str(out), *tiny, *extra, "--val-data", str(val),
                 "--val-every", "1", "--val-segments", "2", "--val-arscore-every", "2",
                 "--val-arscore-segments", "3"]) == 0
    quiet = capsys.readouterr()
    assert not [line for line in (quiet.out + quiet.err).splitlines() if line.startswith("step ")]  # --quiet
    meta = json.loads(out.with_suffix(".json").read_text())
    history = meta["history"]
    assert meta["model"] == model and meta["train_config"]["val_arscore_every"] == 2
    assert history["validation"] == "files" and history["val_segments"] == 2 and history["steps"] == 3
    assert history["train_segments"] == 6  # every usable training segment trains: none held out
    assert [v["step"] for v in history["val"]] == [1, 2, 3, 3]
    assert all(figures | {"train_loss_mean"} <= set(v) for v in history["val"])
    with_score = [v["step"] for v in history["val"] if "arscore" in v]
    assert with_score == [2, 3]  # every 2 steps, and the final entry (step 3) though 2 does not divide it
    assert all(0.0 <= v["arscore"] <= 1.0 for v in history["val"] if "arscore" in v)
    curve = read_curves(out.with_suffix(".json"))
    assert curve["model"] == model and [s for s, _ in curve["arscore"]] == [2, 3]
    assert curves_main([str(out.with_suffix(".json")), "-o", str(tmp_path / "c.png")]) == 0
    assert f"{model}: mean curve" in capsys.readouterr().out


def test_siamfc_without_validation_files_holds_out_every_tenth_segment(data, tmp_path, capsys):
    out = tmp_path / "s.pt"
    assert main(["train", "--model", "siamfc", "--data", str(data), "-o", str(out), "--epochs", "1",
                 "--segments-per-epoch", "1", "--batch-segments", "1", "--threads", "1", "--quiet"]) == 0
    capsys.readouterr()
    history = json.loads(out.with_suffix(".json").read_text())["history"]
    assert history["validation"] == "held_out" and history["train_segments"] == 5 and history["val_segments"] == 1
    assert "arscore" not in history["val"][-1]
    assert main(["train", "--model", "siamfc", "--data", str(data), "-o", str(out), "--val-arscore-every", "2",
                 "--quiet"]) == 2
    assert "--val-arscore-every needs --val-data" in capsys.readouterr().err


def test_validation_flags_are_refused_before_training(data, tmp_path, capsys, no_training):
    out = tmp_path / "m.pt"
    assert main(["train", "--data", str(data), "-o", str(out), *TINY, "--val-data", str(data)]) == 2
    assert "in both --data and --val-data" in capsys.readouterr().err
    assert main(["train", "--data", str(data), "-o", str(out), *TINY, "--val-arscore-every", "5"]) == 2
    assert "--val-arscore-every needs --val-data" in capsys.readouterr().err
    assert main(["train", "--model", "siamfc", "--data", str(data), "-o", str(out), "--init", "fluctuation"]) == 2
    assert "--init: not a setting of --model siamfc" in capsys.readouterr().err
    assert main(["train", "--data", str(data), "-o", str(out), *TINY, "--val-every", "0"]) == 2
    assert "--val-every must be" in capsys.readouterr().err
    assert not out.exists()
