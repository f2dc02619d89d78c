"""`dvsot bench`'s energy output states each tracker's energy as it ran, from sctn.energy_run.energy_as_run on the
run's own results: per evaluation, tracked segment, initialisation and sequence, each split into synaptic operations
and neuron-state updates, with the paper's convention named; on a synthetic run and on a tiny real one."""

from __future__ import annotations

import json

import numpy as np
import pytest

from benchmarks.analysis.energy_table import AS_RUN_BASES, PAPER_CONVENTION, energy_as_run_rows, format_energy_as_run
from benchmarks.evaluation.protocol import SequenceResult
from sctn.energy_run import energy_as_run
from tests.synthetic import moving_square_file


def _result(tracker: str, sequence: str, tracked: int, inits: list[int], seg: dict | None,
            init: dict | None) -> SequenceResult:
    n = tracked + len(inits)
    return SequenceResult(tracker, sequence, np.full(n, 0.8), np.zeros((n, 4)), inits, 1.0, tracked,
                          energy=seg, init_energy=init)


SNN_SEG = {"ac_ops": 2.56e6, "mac_ops": 0.0, "state_updates": 4e6, "activations": 0.0, "evaluations": 256}
SNN_INIT = {"ac_ops": 1e7, "mac_ops": 3e9, "state_updates": 2e7, "activations": 0.0}
ANN_SEG = {"ac_ops": 0.0, "mac_ops": 5e8, "state_updates": 0.0, "activations": 1e6, "evaluations": 256}
ANN_INIT = {"ac_ops": 0.0, "mac_ops": 9e9, "state_updates": 0.0, "activations": 5e6}


def synthetic_results() -> list[SequenceResult]:
    return [_result("sctn", "a", 20, [0, 9], SNN_SEG, SNN_INIT), _result("sctn", "b", 10, [0], SNN_SEG, SNN_INIT),
            _result("sctn_ann", "a", 21, [0], ANN_SEG, ANN_INIT),
            _result("still", "a", 22, [0], None, None)]  # a tracker that counts nothing


def test_rows_are_the_one_function_per_tracker_and_the_text_names_every_basis() -> None:
    results = synthetic_results()
    rows = energy_as_run_rows(results)
    assert list(rows) == ["sctn", "sctn_ann"]  # "still" counted nothing
    assert rows["sctn"] == energy_as_run(results[:2]) and rows["sctn_ann"] == energy_as_run(results[2:3])
    sctn = rows["sctn"]
    # per sequence: (2 inits + 20 segments, 1 init + 10 segments) averaged
    assert sctn["per_sequence"]["synaptic"]["ac_ops"] == pytest.approx((2 * 1e7 + 20 * 2.56e6 + 1e7 + 10 * 2.56e6) / 2)
    text = format_energy_as_run(rows)
    lines = text.splitlines()
    for name in rows:
        for key, basis in AS_RUN_BASES:
            line = next(ln for ln in lines if ln.startswith(f"{name:12s} {basis:20s}"))
            b = rows[name][key]
            assert f"{b['synaptic']['energy_pj']:.3g}" in line and f"{b['state']['energy_pj']:.3g}" in line
            assert line.rstrip().endswith(f"{b['energy_pj'] / sctn[key]['energy_pj']:.3g}")  # x sctn
        paper = next(ln for ln in lines if ln.startswith(f"{name:12s} {'paper convention':20s}"))
        assert f"{rows[name]['paper_convention']['energy_pj']:.3g}" in paper
    assert PAPER_CONVENTION in text and "C-LIF" in text and "activations" in text
    assert format_energy_as_run({}) == ""


def test_a_tiny_bench_run_prints_and_writes_its_energy_as_run(tmp_path) -> None:
    from benchmarks.bench.plan import run_benchmark, tables_text

    data = moving_square_file(tmp_path / "s.h5", duration_ms=60, seed=4, split="test")
    shown = []
    run = run_benchmark(["sctn"], [str(data)], out_dir=tmp_path / "out", jobs=1, progress=False,
                        options=["sctn.n_candidates=12", "sctn.finetune_iters=2", "sctn.energy_every=1"],
                        show=shown.append)
    assert not run.failed
    as_run = run.energy["as_run"]
    assert list(as_run) == ["sctn"] and as_run["sctn"] == energy_as_run(run.results)
    assert as_run["sctn"]["evaluations_per_segment"] == 12 and as_run["sctn"]["per_initialisation"]["energy_pj"] > 0
    assert "energy of each tracker as it ran" in tables_text(shown[0])
    written = json.loads((tmp_path / "out" / "energy.json").read_text())
    assert written["as_run"]["sctn"]["per_sequence"]["energy_pj"] == pytest.approx(
        as_run["sctn"]["per_sequence"]["energy_pj"])
