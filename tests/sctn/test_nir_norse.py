"""The exported graph in Norse, a second SNN library, as a user loads it (`norse.torch.from_nir`): with the `euler`
constants and a reset by subtraction its spikes and the target's V_max equal dvsot's.

Norse is no dependency of dvsot: this runs only where DVSOT_NORSE_PYTHON names a Python that has torch, nir and
norse (docs/nir.md), and is skipped elsewhere (CI holds the same equality with sctn/nir_sim.py instead).
"""

from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path

import pytest

from benchmarks.experiments.nir_check import reference
from tests.synthetic import moving_square_file

ROOT = Path(__file__).resolve().parents[2]
NORSE_PYTHON = os.environ.get("DVSOT_NORSE_PYTHON")


@pytest.mark.skipif(not NORSE_PYTHON, reason="set DVSOT_NORSE_PYTHON to a Python with torch, nir and norse")
def test_norse_runs_the_euler_graph_as_dvsot(tmp_path):
    data = moving_square_file(tmp_path / "square.h5", duration_ms=40, size=40)
    out = tmp_path / "check"
    reference([data], out, None, segments=2, candidates=4, seed=0)
    subprocess.run(
        [NORSE_PYTHON, str(ROOT / "benchmarks" / "experiments" / "nir_check.py"), "norse", "--out", str(out)],
        check=True,
        capture_output=True,
        env={**os.environ, "PYTHONPATH": ""},
    )
    runs = json.loads((out / "norse.json").read_text())
    (same,) = [r for name, r in runs.items() if name.endswith("euler graph, reset_subtract")]
    assert all(layer["differ"] == 0 for layer in same["layers"].values()), same
    assert same["layers"]["conv3_lif"]["dvsot"] > 0
    assert same["vmax_beyond_tolerance"] == 0, same
    (nir_reset,) = [r for name, r in runs.items() if name.endswith("euler graph, reset_value")]
    assert nir_reset["layers"]["conv1_lif"]["differ"] > 0  # NIR's reset to v_reset is another network
