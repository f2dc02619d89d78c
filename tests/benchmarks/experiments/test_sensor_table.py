"""benchmarks.experiments.sensor_table: a split's kept frames re-simulated per preset, benchmarked, tabled, staged."""

from __future__ import annotations

import csv
import json

import pytest

from tests.synthetic import kept_sequence


@pytest.fixture
def split(tmp_path):
    """data/ with two test sequences (their frames in frames/<name>/) and a train sequence without kept frames."""
    data, frames = tmp_path / "data", tmp_path / "frames"
    data.mkdir()
    kept_sequence(data, n=31, name="a", frames_dir=frames / "a")
    kept_sequence(data, n=31, name="b", frames_dir=frames / "b", start=(40, 30))
    kept_sequence(data, n=11, name="c", frames_dir=tmp_path / "elsewhere", split="train")
    return data, frames


def table(data, frames, out, *extra):
    from benchmarks.experiments.sensor_table import main

    return main(["--data", str(data), "--frames", str(frames), "--tracker", "rct", "--max-segments", "3",
                 "--jobs", "1", "--quiet", "--out", str(out), *extra])


def _contents(directory):
    """{relative path: bytes} of every file under a directory, hidden ones included."""
    return {str(p.relative_to(directory)): p.read_bytes() for p in sorted(directory.rglob("*")) if p.is_file()}


def test_the_table_under_two_presets(split, tmp_path, capsys):
    from benchmarks.bench.plan import run_benchmark
    from dvsot.dataset import Dataset

    data, frames = split
    out = tmp_path / "out"
    assert table(data, frames, out, "--preset", "ideal", "--preset", "davis346", "--picture", "b:1") == 0
    assert sorted(p.name for p in (out / "ideal").glob("*.h5")) == ["a.h5", "b.h5"]  # the train sequence: not asked
    assert (out / "davis346" / "bench" / "results.md").is_file() and (out / "segment.png").read_bytes()[
        :4
    ] == b"\x89PNG"
    with open(out / "table.csv") as f:
        rows = list(csv.DictReader(f))
    assert [(r["tracker"], r["sequence"]) for r in rows] == [("rct", "all"), ("rct", "a"), ("rct", "b")]
    # each preset's columns are its own bench run's pooled cell
    for preset in ("ideal", "davis346"):
        pooled = json.loads((out / preset / "bench" / "results.json").read_text())["rct"]["all"]
        assert float(rows[0][f"{preset}_ARscore"]) == pytest.approx(pooled["ARscore"], abs=1e-4)
    # ideal with the sequences' own event seed re-simulates the split's own events: the same table as `dvsot bench`
    with Dataset(data / "a.h5") as ds:
        assert int(rows[1]["ideal_events"]) == ds.num_events
    assert int(rows[1]["davis346_events"]) != ds.num_events
    bench = run_benchmark(["rct"], [str(data)], "test", tmp_path / "bench", 1, max_segments=3, progress=False)
    for metric in ("A", "R", "ARscore"):
        assert float(rows[0][f"ideal_{metric}"]) == pytest.approx(bench.summary["rct"]["all"][metric], abs=1e-4)
    text = (out / "table.md").read_text()
    assert "| tracker | ideal ARscore | ideal A | ideal R | davis346 ARscore | davis346 A | davis346 R |" in text
    row = next(line for line in text.splitlines() if line.startswith("| rct |"))
    assert row.count("|") == 8 and f"{float(rows[0]['davis346_ARscore']):.3f}" in row
    assert "| rct |" in capsys.readouterr().out


def test_a_sequence_without_kept_frames_is_an_error_naming_it(split, tmp_path, capsys):
    import shutil

    data, frames = split
    shutil.rmtree(frames / "b")
    out = tmp_path / "out"
    assert table(data, frames, out, "--preset", "ideal") == 2
    err = capsys.readouterr().err
    assert "no kept frames for 1 sequence(s)" in err and "'b'" in err and err.count("\n") == 1
    assert not out.exists()
    (frames / "b").mkdir()  # there, but empty
    assert table(data, frames, out, "--preset", "ideal") == 2
    assert "0 frames (.npy), but" in capsys.readouterr().err and not out.exists()


def test_bad_picture_and_tracker_option_are_refused_before_any_simulation(split, tmp_path, capsys, monkeypatch):
    import benchmarks.experiments.robustness as robustness

    data, frames = split
    monkeypatch.setattr(robustness, "resimulate", lambda *a, **k: pytest.fail("simulated before the checks"))
    out = tmp_path / "out"
    assert table(data, frames, out, "--preset", "ideal", "--picture", "b:3") == 2
    assert "--picture: 3 is not a segment of" in capsys.readouterr().err
    assert table(data, frames, out, "--preset", "ideal", "--picture", "z:0") == 2
    assert "no sequence 'z'" in capsys.readouterr().err
    assert table(data, frames, out, "--preset", "ideal", "--option", "rct.no_such=1") == 2
    assert "rct.no_such" in capsys.readouterr().err and not out.exists()


def test_out_holds_one_run_whole(split, tmp_path, monkeypatch, capsys):
    import benchmarks.bench.plan as plan

    data, frames = split
    out = tmp_path / "out"
    assert table(data, frames, out, "--preset", "ideal", "--preset", "noisy") == 0
    manifest = json.loads((out / "run.json").read_text())
    assert manifest["format"] == "dvsot-run" and "noisy/bench/rct/b.txt" in manifest["files"]
    # the next run: one of the presets, one sequence; the previous run's other files go in its commit (those in
    # noisy/bench/ too, which the benchmark run nested in this one knows as the previous run's)
    assert table(data / "a.h5", frames, out, "--preset", "noisy") == 0
    assert sorted(p.name for p in out.iterdir()) == ["noisy", "run.json", "table.csv", "table.md"]
    assert sorted(p.name for p in (out / "noisy").iterdir()) == ["a.h5", "bench"]
    assert (out / "noisy" / "bench" / "rct" / "a.txt").exists()
    assert not (out / "noisy" / "bench" / "rct" / "b.txt").exists()
    before = _contents(out)
    real, calls = plan.run_benchmark, []

    def interrupted(*args, **kwargs):  # Ctrl-C lands in the second preset's tracking
        calls.append(args)
        if len(calls) == 2:
            raise KeyboardInterrupt
        return real(*args, **kwargs)

    monkeypatch.setattr(plan, "run_benchmark", interrupted)
    with pytest.raises(KeyboardInterrupt):
        table(data, frames, out, "--preset", "ideal", "--preset", "noisy")
    assert _contents(out) == before  # no new file or directory, no temp, the old files untouched
    assert sorted(p.name for p in out.iterdir()) == ["noisy", "run.json", "table.csv", "table.md"]
    calls.clear()
    with pytest.raises(KeyboardInterrupt):
        table(data, frames, tmp_path / "fresh", "--preset", "ideal", "--preset", "noisy")
    assert not (tmp_path / "fresh").exists()
    monkeypatch.undo()
    (out / "notes.txt").write_text("mine")
    assert table(data, frames, out, "--preset", "ideal") == 2
    err = capsys.readouterr().err
    assert "holds files that are not an earlier run's" in err and "notes.txt" in err and err.count("\n") == 1


def test_a_tracker_that_raises_on_a_sequence_is_marked_failed_and_the_exit_status_is_1(split, tmp_path, monkeypatch,
                                                                                        capsys):
    import dataclasses

    import benchmarks.evaluation.runner as runner

    data, frames = split
    real = runner.run_one

    def crashing_on_b(tracker, path, *args, **kwargs):  # as run_one reports a tracker that raised
        result = real(tracker, path, *args, **kwargs)
        return dataclasses.replace(result, error="boom") if result.sequence == "b" else result

    monkeypatch.setattr(runner, "run_one", crashing_on_b)
    out = tmp_path / "out"
    assert table(data, frames, out, "--preset", "davis346") == 1
    captured = capsys.readouterr()
    assert "failed: rct on b under davis346: boom" in captured.err
    with open(out / "table.csv") as f:
        rows = {r["sequence"]: r for r in csv.DictReader(f)}
    assert rows["b"]["davis346_error"] == "boom" and rows["all"]["davis346_error"] == ""
    assert rows["all"]["davis346_ARscore"] == rows["a"]["davis346_ARscore"]  # pooled over the sequence that ran
    assert "rct under davis346: failed on b" in (out / "table.md").read_text()


def test_as_rendered_re_simulates_each_file_with_its_own_settings(tmp_path, capsys):
    """A split made with a scene's own thresholds: `ideal` is the preset's fields, `as-rendered` the file's, whose
    table is `dvsot bench`'s on the split itself; a file that records no settings is refused naming it."""
    from benchmarks.bench.plan import run_benchmark
    from dvsot.dataset import Dataset
    from dvsot.events import EventParams

    data, frames = tmp_path / "data", tmp_path / "frames"
    data.mkdir()
    own = EventParams.parse({"preset": "ideal", "cp": 0.3, "cn": 0.35, "refractory_us": 500}, "scene")
    path, _ = kept_sequence(data, n=31, name="a", frames_dir=frames / "a", params=own)
    out = tmp_path / "out"
    assert table(data, frames, out, "--preset", "ideal", "--preset", "as-rendered") == 0
    with open(out / "table.csv") as f:
        rows = list(csv.DictReader(f))
    with Dataset(path) as ds:
        assert int(rows[1]["as-rendered_events"]) == ds.num_events != int(rows[1]["ideal_events"])
    bench = run_benchmark(["rct"], [str(data)], "test", tmp_path / "bench", 1, max_segments=3, progress=False)
    for metric in ("A", "R", "ARscore"):
        assert float(rows[0][f"as-rendered_{metric}"]) == pytest.approx(bench.summary["rct"]["all"][metric], abs=1e-4)
    capsys.readouterr()
    bare = tmp_path / "bare"
    bare.mkdir()
    path, _ = kept_sequence(bare, n=31, name="a", frames_dir=tmp_path / "bare_frames" / "a", record_settings=False)
    assert table(bare, tmp_path / "bare_frames", tmp_path / "out2", "--preset", "as-rendered") == 2
    err = capsys.readouterr().err
    assert "records no simulator settings" in err and str(path) in err and err.count("\n") == 1, err
    assert not (tmp_path / "out2").exists()
