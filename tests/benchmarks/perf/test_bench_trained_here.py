"""bench_trained_here times all five trackers trained here: on untrained networks when no checkpoint is given or
shipped (IoU None), on the shipped checkpoint when one is at trained_here.default_path (IoU reported), on a given
one before a shipped one; a bad --checkpoint is one line, exit 2, nothing on stdout."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from benchmarks.perf import bench_trained_here as bench
from benchmarks.trackers import trained_here


@pytest.fixture()
def shipped_dir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """An empty directory standing in for the shipped checkpoints, so the test holds whatever ships."""
    d = tmp_path / "shipped"
    d.mkdir()
    monkeypatch.setattr(trained_here, "CHECKPOINT_DIR", d)
    return d


def _run(capsys: pytest.CaptureFixture, *args: str) -> dict:
    assert bench.main(["--segments", "2", "--repeat", "1", *args]) == 0
    return json.loads(capsys.readouterr().out)


def test_all_five_run_untrained_without_a_checkpoint(shipped_dir: Path, capsys: pytest.CaptureFixture) -> None:
    runs = _run(capsys)["runs"]
    assert [r["tracker"] for r in runs] == ["goturn", "siamrpn", "siammask", "ocean", "automatch"]
    for r in runs:
        assert r["weights"].startswith("untrained (timing only: no checkpoint given and none shipped at ")
        assert str(shipped_dir / f"{r['tracker']}_dvsot21.pt") in r["weights"]
        assert r["mean_iou_without_reinit"] is None and r["segments"] == 2 and r["threads"] == 1
        assert r["mac_per_frame"] > 0 and r["segments_per_s"] > 0


def test_a_shipped_checkpoint_is_used_and_a_given_one_wins(shipped_dir: Path, tmp_path: Path,
                                                           capsys: pytest.CaptureFixture) -> None:
    from benchmarks.trackers.automatch.model import AutoMatch
    from benchmarks.trackers.ocean.model import Ocean
    from sctn.checkpoint import save_checkpoint

    shipped = save_checkpoint(shipped_dir / "ocean_dvsot21.pt", Ocean(), {}, kind="ocean")
    runs = _run(capsys, "--tracker", "ocean")["runs"]
    assert len(runs) == 1 and runs[0]["weights"] == "shipped" and runs[0]["checkpoint"] == str(shipped)
    assert isinstance(runs[0]["mean_iou_without_reinit"], float)

    given = save_checkpoint(tmp_path / "a.pt", AutoMatch(), {}, kind="automatch")
    other = save_checkpoint(tmp_path / "o.pt", Ocean(), {}, kind="ocean")
    runs = _run(capsys, "--tracker", "ocean", "--tracker", "automatch", "--checkpoint", f"automatch={given}",
                "--ocean-checkpoint", str(other))["runs"]
    assert [(r["tracker"], r["weights"], r["checkpoint"]) for r in runs] == [
        ("ocean", "given", str(other)), ("automatch", "given", str(given))]


@pytest.mark.parametrize("arg, words", [("nope=x.pt", "'nope' is not one of goturn, siamrpn"),
                                        ("ocean", "give NAME=CKPT"),
                                        ("ocean=missing.pt", "missing.pt: no such checkpoint (given for ocean)")])
def test_a_bad_checkpoint_flag_is_one_line_and_exit_2(arg: str, words: str, shipped_dir: Path,
                                                      capsys: pytest.CaptureFixture) -> None:
    assert bench.main(["--segments", "1", "--repeat", "1", "--checkpoint", arg]) == 2
    out = capsys.readouterr()
    assert out.out == "" and len(out.err.strip().splitlines()) == 1 and words in out.err


def test_another_models_checkpoint_is_refused_naming_the_file(shipped_dir: Path, tmp_path: Path,
                                                              capsys: pytest.CaptureFixture) -> None:
    from benchmarks.trackers.ocean.model import Ocean
    from sctn.checkpoint import save_checkpoint

    wrong = save_checkpoint(tmp_path / "o.pt", Ocean(), {}, kind="ocean")
    assert bench.main(["--segments", "1", "--repeat", "1", "--tracker", "automatch",
                       "--checkpoint", f"automatch={wrong}"]) == 2
    out = capsys.readouterr()
    err = out.err.strip()
    assert out.out == "" and "\n" not in err and err.startswith(f"{wrong}: holds ") and "not an automatch one" in err
