"""`dvsot train --model siamrpn` writes a checkpoint with its JSON, `dvsot bench --tracker siamrpn --checkpoint` scores
it on a synthetic file; with neither a checkpoint given nor one shipped the trackers trained here say so in one line
(exit 2)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest
import torch

from dvsot.cli import main

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from synthetic import moving_square_file  # noqa: E402

torch.set_num_threads(1)


@pytest.fixture(scope="module")
def data(tmp_path_factory) -> tuple[Path, Path]:
    """A training file and a test directory, small (64x48)."""
    d = tmp_path_factory.mktemp("trained_here")
    train = moving_square_file(d / "train.h5", width=64, height=48, size=12, duration_ms=60,
                               velocity_px_s=(100.0, 40.0), start=(10.0, 10.0))
    (d / "test").mkdir()
    moving_square_file(d / "test" / "t.h5", width=64, height=48, size=12, duration_ms=60,
                       velocity_px_s=(-80.0, 30.0), start=(40.0, 10.0), split="test", seed=3)
    return train, d / "test"


def test_train_siamrpn_then_bench_it(data, tmp_path, capsys):
    train, test = data
    out = tmp_path / "siamrpn.pt"
    assert main(["train", "--model", "siamrpn", "--data", str(train), "-o", str(out), "--epochs", "1",
                 "--segments-per-epoch", "2", "--batch-segments", "1", "--threads", "1", "--quiet"]) == 0
    capsys.readouterr()
    meta = json.loads(out.with_suffix(".json").read_text())
    assert meta["model"] == "siamrpn" and meta["history"]["steps"] == 2 and meta["data"][0]["file"] == str(train)
    assert meta["config"]["ratios"] == [0.33, 0.5, 1.0, 2.0, 3.0] and "train_config" in meta
    bench = tmp_path / "bench"
    assert main(["bench", "--tracker", "siamrpn", "--checkpoint", str(out), "--data", str(test), "--out", str(bench),
                 "--jobs", "1", "--no-energy", "--quiet"]) == 0
    results = json.loads((bench / "results.json").read_text())
    assert "siamrpn" in json.dumps(results)
    assert (bench / "siamrpn").is_dir()


@pytest.mark.parametrize("name", ["goturn", "siamrpn", "siammask", "ocean", "automatch"])
def test_bench_without_a_checkpoint_says_none_ships_and_scores_nothing(data, tmp_path, capsys, monkeypatch, name):
    from benchmarks.trackers import trained_here

    (tmp_path / "shipped").mkdir()  # no checkpoint there, whatever ships with the package
    monkeypatch.setattr(trained_here, "CHECKPOINT_DIR", tmp_path / "shipped")
    _, test = data
    bench = tmp_path / "bench"
    assert main(["bench", "--tracker", name, "--data", str(test), "--out", str(bench), "--jobs", "1", "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"{name}: no shipped checkpoint exists" in err[0] and f"--model {name}" in err[0]
    assert not bench.exists()


def test_bench_refuses_another_models_checkpoint(data, tmp_path, capsys):
    from benchmarks.trackers.goturn.model import GOTURN
    from sctn.checkpoint import save_checkpoint

    _, test = data
    ckpt = save_checkpoint(tmp_path / "g.pt", GOTURN(), {}, kind="goturn")
    bench = tmp_path / "bench"
    assert main(["bench", "--tracker", "siammask", "--checkpoint", str(ckpt), "--data", str(test), "--out",
                 str(bench), "--jobs", "1", "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].endswith(f"{ckpt}: holds a goturn model, not a siammask one (a checkpoint of the "
                                             "goturn tracker)")
    assert not bench.exists()


def test_bench_refuses_a_frame_size_the_network_cannot_take_before_scoring(tmp_path, capsys):
    from benchmarks.trackers.siamrpn.model import SiamRPN
    from sctn.checkpoint import save_checkpoint

    (tmp_path / "tiny").mkdir()
    tiny = moving_square_file(tmp_path / "tiny" / "t.h5", width=6, height=6, size=3, duration_ms=40,
                              velocity_px_s=(20.0, 0.0), start=(1.0, 1.0), split="test")
    ckpt = save_checkpoint(tmp_path / "r.pt", SiamRPN(), {}, kind="siamrpn")
    bench = tmp_path / "bench"
    assert main(["bench", "--tracker", "siamrpn", "--checkpoint", str(ckpt), "--data", str(tmp_path / "tiny"),
                 "--out", str(bench), "--jobs", "1", "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].endswith(f"{tiny}: siamrpn: a 6x6 px frame is smaller than the 8x8 px this "
                                             "network's crops need"), err
    assert not bench.exists()
