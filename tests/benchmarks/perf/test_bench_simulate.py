"""bench_simulate refuses reference simulators it cannot run, before timing anything."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[3]


@pytest.fixture()
def inputs(tmp_path: Path) -> tuple[Path, Path, Path]:
    """Two tiny PNG frames, their timestamps, and a 'Python' that fails whatever it runs."""
    import cv2

    frames = tmp_path / "frames"
    frames.mkdir()
    for i in range(2):
        cv2.imwrite(str(frames / f"f{i}.png"), np.full((4, 6), 50 + 100 * i, np.uint8))
    times = tmp_path / "t.txt"
    times.write_text("0\n0.001\n")
    broken = tmp_path / "broken-python"
    broken.write_text("#!/bin/sh\necho 'ModuleNotFoundError: no such module' >&2\nexit 1\n")
    broken.chmod(0o755)
    return frames, times, broken


def _bench(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "benchmarks.perf.bench_simulate", *args], cwd=ROOT,
                          capture_output=True, text=True, timeout=60)


def test_v2e_python_without_its_source_is_refused(inputs: tuple[Path, Path, Path]) -> None:
    frames, times, _ = inputs
    done = _bench(str(frames), "--timestamps", str(times), "--v2e-python", sys.executable)
    assert done.returncode == 2 and done.stdout == ""
    assert "--v2e-python and --v2e-src go together" in done.stderr


def test_v2e_that_does_not_import_is_refused(inputs: tuple[Path, Path, Path], tmp_path: Path) -> None:
    frames, times, broken = inputs
    done = _bench(str(frames), "--timestamps", str(times), "--v2e-python", str(broken), "--v2e-src", str(tmp_path))
    assert done.returncode == 2 and done.stdout == ""
    assert "does not import v2ecore.emulator: ModuleNotFoundError: no such module" in done.stderr


def test_named_esim_python_that_does_not_import_is_refused(inputs: tuple[Path, Path, Path]) -> None:
    frames, times, broken = inputs
    done = _bench(str(frames), "--timestamps", str(times), "--esim-python", str(broken))
    assert done.returncode == 2 and done.stdout == ""
    assert f"--esim-python {broken} does not import esim_py" in done.stderr
