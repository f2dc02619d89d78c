"""benchmarks.experiments.robustness: kept frames re-simulated under presets and noise rates, tracked, tabled and
plotted."""

from __future__ import annotations

import csv

import numpy as np
import pytest

from tests.synthetic import kept_sequence


def test_sweep_tables_arscore_per_tracker_against_the_noise_rate(tmp_path):
    from benchmarks.experiments.robustness import resimulate, sweep, write_outputs

    seq, frames = kept_sequence(tmp_path)
    # the ideal preset re-simulates the sequence's own events
    resimulate(seq, frames, tmp_path / "again.h5", {"preset": "ideal"})
    from dvsot.dataset import Dataset
    from dvsot.events.batch import EventBatch

    with Dataset(seq) as a, Dataset(tmp_path / "again.h5") as b:
        ea, eb = EventBatch.concatenate(list(a.chunks())), EventBatch.concatenate(list(b.chunks()))
    assert np.array_equal(ea.t, eb.t) and np.array_equal(ea.x, eb.x) and np.array_equal(ea.p, eb.p)

    rows = sweep(seq, frames, ["rct"], ["ideal", "noisy"], [200.0], tmp_path / "out", max_segments=4)
    assert [r["variant"] for r in rows] == ["ideal_noise200", "noisy_noise200"]
    assert rows[0]["measured_noise_hz"] == pytest.approx(200, rel=0.1) and rows[0]["set_shot_noise_hz"] == 200
    assert all(0 <= r["rct_ARscore"] <= 1 for r in rows)
    write_outputs(rows, ["rct"], tmp_path / "out", "seq")
    with open(tmp_path / "out" / "robustness.csv") as f:
        assert len(list(csv.DictReader(f))) == 2
    assert "rct ARscore" in (tmp_path / "out" / "robustness.md").read_text()
    assert (tmp_path / "out" / "robustness.png").stat().st_size > 1000


def test_frames_that_do_not_match_the_sequence_are_refused(tmp_path):
    from benchmarks.experiments.robustness import resimulate
    from dvsot.core.errors import UserError

    seq, frames = kept_sequence(tmp_path, n=12)
    (frames / "000011.npy").unlink()
    with pytest.raises(UserError, match=r"11 frames \(\.npy\), but .* has 12 render samples"):
        resimulate(seq, frames, tmp_path / "x.h5", {"preset": "davis346"})
    assert not (tmp_path / "x.h5").exists()


def test_several_event_seeds_give_a_row_each_and_a_mean_with_its_spread(tmp_path):
    from benchmarks.experiments.robustness import summarise, sweep, write_outputs

    seq, frames = kept_sequence(tmp_path)
    rows = sweep(seq, frames, ["rct"], ["noisy"], [None, 50.0], tmp_path / "out", max_segments=4, seeds=[1, 2])
    assert [(r["variant"], r["seed"]) for r in rows] == [("noisy", 1), ("noisy", 2), ("noisy_noise50", 1),
                                                         ("noisy_noise50", 2)]
    assert rows[0]["set_shot_noise_hz"] == 5 and rows[2]["set_shot_noise_hz"] == 50
    assert rows[0]["events"] != rows[1]["events"]  # another seed: other mismatch and noise
    assert (tmp_path / "out" / "noisy_noise50_seed2.h5").exists()
    summary = summarise(rows, ["rct"])
    scores = [rows[2]["rct_ARscore"], rows[3]["rct_ARscore"]]
    assert summary[1]["seeds"] == 2 and summary[1]["rct_ARscore"] == pytest.approx(np.mean(scores))
    assert summary[1]["rct_ARscore_std"] == pytest.approx(abs(scores[0] - scores[1]) / np.sqrt(2))
    write_outputs(rows, ["rct"], tmp_path / "out", "seq")
    text = (tmp_path / "out" / "robustness.md").read_text()
    assert "| seeds |" in text and f"{summary[1]['rct_ARscore']:.3f} ± " in text


def test_noise_rate_arguments():
    import argparse

    from benchmarks.experiments.robustness import noise_rate

    assert noise_rate("preset") is None and noise_rate("2.5") == 2.5
    for bad in ("-1", "nan", "lots"):
        with pytest.raises(argparse.ArgumentTypeError):
            noise_rate(bad)


def test_a_picture_segment_outside_the_sequence_is_refused_before_any_run(tmp_path, monkeypatch, capsys):
    import sys

    from benchmarks.experiments.robustness import main

    seq, frames = kept_sequence(tmp_path, n=21)  # 20 ms: segments 0 and 1
    monkeypatch.setattr(sys, "argv", ["robustness", str(seq), str(frames), "--tracker", "rct",
                                      "--picture-segment", "2", "--out", str(tmp_path / "out")])
    with pytest.raises(SystemExit) as exc:
        main()
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "--picture-segment: 2 is not a segment of" in err and "(0..1)" in err and err.count("\n") == 1
    assert not (tmp_path / "out").exists()


def test_the_picture_shows_every_variant_of_a_sweep(tmp_path, monkeypatch):
    import sys

    from benchmarks.experiments.robustness import main

    seq, frames = kept_sequence(tmp_path, n=21)
    monkeypatch.setattr(sys, "argv", ["robustness", str(seq), str(frames), "--tracker", "rct", "--preset", "ideal",
                                      "--preset", "davis346", "--event-seed", "4", "5", "--picture-segment", "1",
                                      "--out", str(tmp_path / "out")])
    main()
    assert (tmp_path / "out" / "segment.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert sorted(p.name for p in (tmp_path / "out").glob("*.h5")) == [
        "davis346_seed4.h5", "davis346_seed5.h5", "ideal_seed4.h5", "ideal_seed5.h5"]


def _contents(directory):
    """{relative path: bytes} of every file under a directory, hidden ones included."""
    return {str(p.relative_to(directory)): p.read_bytes() for p in sorted(directory.rglob("*")) if p.is_file()}


def test_out_holds_one_run_whole_and_a_rerun_replaces_it(tmp_path, monkeypatch):
    import json
    import sys

    from benchmarks.experiments.robustness import main

    seq, frames = kept_sequence(tmp_path, n=21)
    out = tmp_path / "out"

    def sweep_into(*variant_args):
        monkeypatch.setattr(sys, "argv", ["robustness", str(seq), str(frames), "--tracker", "rct", *variant_args,
                                          "--out", str(out)])
        main()

    sweep_into("--preset", "ideal", "--preset", "noisy")
    assert sorted(p.name for p in out.iterdir()) == ["ideal.h5", "noisy.h5", "robustness.csv", "robustness.md",
                                                     "robustness.png", "run.json"]
    manifest = json.loads((out / "run.json").read_text())
    assert manifest["format"] == "dvsot-run" and "noisy.h5" in manifest["files"]
    # the next run writes other variants: the previous run's files it does not write go, nothing is mixed
    sweep_into("--preset", "davis346", "--noise-hz", "10")
    assert sorted(p.name for p in out.iterdir()) == ["davis346_noise10.h5", "robustness.csv", "robustness.md",
                                                     "robustness.png", "run.json"]
    assert "noisy" not in (out / "robustness.csv").read_text()


def test_an_interrupted_sweep_leaves_out_as_it_was(tmp_path, monkeypatch):
    import sys

    import benchmarks.evaluation.runner as runner
    from benchmarks.experiments.robustness import main

    seq, frames = kept_sequence(tmp_path, n=21)
    out = tmp_path / "out"
    monkeypatch.setattr(sys, "argv", ["robustness", str(seq), str(frames), "--tracker", "rct", "--out", str(out)])
    main()
    before = _contents(out)
    real, calls = runner.benchmark, []

    def interrupted(*args, **kwargs):  # each run's second variant's tracking is where Ctrl-C lands
        calls.append(args)
        if len(calls) % 2 == 0:
            raise KeyboardInterrupt
        return real(*args, **kwargs)

    monkeypatch.setattr(runner, "benchmark", interrupted)
    monkeypatch.setattr(sys, "argv", ["robustness", str(seq), str(frames), "--tracker", "rct", "--preset", "ideal",
                                      "--preset", "noisy", "--out", str(out)])
    with pytest.raises(SystemExit) as stop:  # one line and 130, as dvsot's commands
        main()
    assert stop.value.code == 130
    assert len(calls) == 2 and _contents(out) == before  # no new file, no temp, the old files untouched
    # into a directory that did not exist: nothing at all is left
    monkeypatch.setattr(sys, "argv", ["robustness", str(seq), str(frames), "--tracker", "rct", "--preset", "ideal",
                                      "--preset", "noisy", "--out", str(tmp_path / "fresh")])
    with pytest.raises(SystemExit):
        main()
    assert not (tmp_path / "fresh").exists()


def test_an_out_that_holds_other_files_is_refused_before_any_work(tmp_path, monkeypatch, capsys):
    import sys

    import benchmarks.evaluation.runner as runner
    from benchmarks.experiments.robustness import main

    seq, frames = kept_sequence(tmp_path, n=21)
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    monkeypatch.setattr(runner, "benchmark", lambda *a, **k: pytest.fail("tracked before the check"))
    monkeypatch.setattr(sys, "argv", ["robustness", str(seq), str(frames), "--tracker", "rct", "--out", str(out)])
    with pytest.raises(SystemExit) as exc:
        main()
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "--out holds files that are not an earlier run's" in err and "notes.txt" in err and err.count("\n") == 1
    assert _contents(out) == {"notes.txt": b"mine"}
