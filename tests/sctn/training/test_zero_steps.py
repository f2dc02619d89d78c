"""A training that would take no step is refused before any work, naming the settings, for every model's trainer."""

from __future__ import annotations

from pathlib import Path

import pytest

from dvsot.cli import main
from sctn.training.loop import TrainConfigError
from tests.synthetic import moving_square_file


def _configs():
    from benchmarks.trackers.siamfc.train import SiamFCTrainConfig
    from sctn.training.snn import TrainConfig

    return [TrainConfig, SiamFCTrainConfig]


@pytest.mark.parametrize("index", [0, 1])
def test_fewer_segments_per_epoch_than_a_batch_is_refused(index: int) -> None:
    config = _configs()[index]
    with pytest.raises(TrainConfigError) as info:
        config(epochs=2, segments_per_epoch=3, batch_segments=4)
    assert info.value.field == "segments_per_epoch" and "batch_segments 4" in info.value.problem
    assert config(epochs=2, segments_per_epoch=4, batch_segments=4).planned_steps(100) == 2


@pytest.mark.parametrize("model", ["sctn", "sctn_ann", "siamfc"])
def test_train_refuses_zero_steps_in_one_line_and_writes_nothing(tmp_path: Path, capsys, model: str) -> None:
    out = tmp_path / "c.pt"
    assert main(["train", "--model", model, "--data", str(tmp_path / "none.h5"), "-o", str(out), "--epochs", "2",
                 "--segments-per-epoch", "3", "--batch-segments", "4", "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--segments-per-epoch is 3, fewer than batch_segments " in err[0]
    assert not out.exists()


def test_too_few_usable_segments_for_a_batch_is_refused_before_training(tmp_path: Path, capsys) -> None:
    data = moving_square_file(tmp_path / "short.h5", duration_ms=40)  # 4 segments, 3 usable for training
    out = tmp_path / "c.pt"
    assert main(["train", "--data", str(data), "-o", str(out), "--epochs", "1", "--batch-segments", "50",
                 "--segments-per-epoch", "50", "--threads", "1", "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "fewer than batch_segments 50" in err[0] and "no training step" in err[0]
    assert not out.exists()
