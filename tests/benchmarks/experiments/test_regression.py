"""The CI metric checks: fail when a metric moves beyond its tolerance; the real tiny benchmark vs the reference; the
declared-latency streaming run vs its reference, and a changed figure failing it."""

import json
import math

import pytest

from benchmarks.experiments import regression
from benchmarks.experiments.regression import (
    REFERENCE,
    STREAM_LATENCY,
    STREAM_OPTIONS,
    STREAM_REFERENCE,
    STREAM_SEQUENCE,
    STREAM_SETTINGS,
    STREAM_TOLERANCE,
    STREAM_TRACKERS,
    TOLERANCE,
    compare,
    run_ci_benchmark,
    run_ci_stream,
)

REF = {"sctn": {"A": 0.7, "R": 0.9, "ARscore": 0.85}, "rct": {"A": 0.5, "R": 0.6, "ARscore": 0.58}}


def test_compare_flags_changes_beyond_tolerance_in_either_direction():
    assert compare(REF, REF) == []
    better = {k: {m: v + 0.1 for m, v in d.items()} for k, d in REF.items()}
    gains = compare(REF, better)
    assert len(gains) == 6 and all("lock it in with --update-reference" in g for g in gains)
    # the tolerance is twice the seed spread where that is larger than the floor
    assert compare(REF, better, spread={"sctn": {"A": 0.06, "R": 0.06, "ARscore": 0.06},
                                        "rct": {"A": 0.06, "R": 0.06, "ARscore": 0.06}}) == []
    slight = json.loads(json.dumps(REF))
    slight["sctn"]["ARscore"] -= TOLERANCE["ARscore"] * 0.9
    assert compare(REF, slight) == []
    worse = json.loads(json.dumps(REF))
    worse["sctn"]["ARscore"] -= TOLERANCE["ARscore"] + 0.01
    problems = compare(REF, worse)
    assert len(problems) == 1 and problems[0].startswith("sctn ARscore")
    assert compare(REF, {"sctn": REF["sctn"]}) == ["rct: missing from this run"]


@pytest.mark.blender
def test_ci_benchmark_meets_the_committed_reference(tmp_path):
    # seed 0 is deterministic: held to the floor tolerance, in both directions (the seed spread, stored beside
    # it, is what `python -m benchmarks.experiments.regression` reports a change against)
    ref = json.loads(REFERENCE.read_text())
    current = run_ci_benchmark(tmp_path)
    assert compare(ref["metrics"], current) == [], (current, ref)


FIGURES = {"sctn declared:loihi": {"A": 0.25, "R": 0.125, "ARscore": 0.13, "AUC": 0.26, "P@20": 0.3, "queries": 72,
                                   "calls": 71, "latency_mean_s": 4.0e-4, "latency_p50_s": 3.9e-4,
                                   "latency_p90_s": 4.5e-4, "latency_max_s": 6.1e-4}}


@pytest.mark.parametrize("figure, delta, flagged", [
    ("ARscore", 1e-6, True), ("ARscore", -1e-6, True), ("ARscore", 1e-11, False), ("A", -2e-9, True),
    ("calls", 1, True), ("queries", -1, True), ("latency_p90_s", 1e-9, True), ("latency_max_s", 1e-13, False),
    ("latency_mean_s", math.nan, True),
])
def test_stream_compare_flags_a_figure_moved_beyond_its_tolerance(figure, delta, flagged):
    changed = json.loads(json.dumps(FIGURES))
    changed["sctn declared:loihi"][figure] += delta
    for ref, cur in ((FIGURES, changed), (changed, FIGURES)):  # a change either way
        problems = compare(ref, cur, STREAM_TOLERANCE)
        if flagged:
            assert len(problems) == 1 and problems[0].startswith(f"sctn declared:loihi {figure} "), problems
        else:
            assert problems == []


@pytest.fixture(scope="module")
def stream_figures(tmp_path_factory):
    return run_ci_stream(tmp_path_factory.mktemp("ci-stream"))


def test_ci_stream_run_meets_the_committed_reference(stream_figures):
    ref = json.loads(STREAM_REFERENCE.read_text())
    # the reference says how it was made, and that is what the code runs
    assert (ref["trackers"], ref["options"], ref["settings"]) == (list(STREAM_TRACKERS), list(STREAM_OPTIONS),
                                                                  STREAM_SETTINGS)
    assert {k: v for k, v in ref["sequence"].items() if k != "made_by"} == STREAM_SEQUENCE
    rows = [t + p for t in STREAM_TRACKERS for p in ("", " (predictive)")]
    assert set(ref["figures"]) == {f"{r} {m}" for r in rows for m in ("free", *STREAM_LATENCY)}
    assert compare(ref["figures"], stream_figures, regression.stream_tolerance(ref)) == [], stream_figures
    # the two profiles time SCTN's calls differently: the loihi row is a different run, not a copy
    assert stream_figures["sctn declared:loihi"]["calls"] > stream_figures["sctn declared:cpu"]["calls"]


def test_ci_stream_regression_fails_on_a_changed_reference_figure(stream_figures, tmp_path, monkeypatch, capsys):
    ref = json.loads(STREAM_REFERENCE.read_text())
    monkeypatch.setattr(regression, "run_ci_stream", lambda workdir: stream_figures)  # the run above, not a rerun
    monkeypatch.setattr(regression, "STREAM_REFERENCE", tmp_path / "ci_stream.json")
    (tmp_path / "ci_stream.json").write_text(json.dumps(ref))
    assert regression.main(["--stream"]) == 0
    ref["figures"]["sctn declared:loihi"]["ARscore"] += 0.05  # beyond both tolerances
    ref["figures"]["siamfc (predictive) declared:cpu"]["calls"] -= 5
    (tmp_path / "ci_stream.json").write_text(json.dumps(ref))
    capsys.readouterr()
    assert regression.main(["--stream"]) == 1
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith("REGRESSION: ")]
    assert len(err) == 2 and "sctn declared:loihi ARscore" in err[0] + err[1]
    assert any("siamfc (predictive) declared:cpu calls" in e for e in err)


def test_stream_tolerance_is_exact_on_the_references_platform_only():
    here = {"platform": regression.platform_signature()}
    assert regression.stream_tolerance(here) is STREAM_TOLERANCE
    elsewhere = {"platform": {**here["platform"], "cpu_capability": "another"}}
    assert regression.stream_tolerance(elsewhere) is regression.STREAM_TOLERANCE_ELSEWHERE
    assert regression.stream_tolerance({}) is regression.STREAM_TOLERANCE_ELSEWHERE
