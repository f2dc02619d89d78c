"""The CI metric check: fails when a metric is pushed below its tolerance; the real tiny benchmark vs the reference."""

import json

import pytest

from benchmarks.experiments.regression import REFERENCE, TOLERANCE, compare, run_ci_benchmark

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
