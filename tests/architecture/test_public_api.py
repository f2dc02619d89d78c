"""The packages' public faces: every name in __all__ resolves, `import` stays light, and README's Python block runs."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
HEAVY = ("torch", "bpy", "cv2", "numpy", "h5py")


def _run(code: str, cwd: Path = ROOT, timeout: float = 120) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    return subprocess.run([sys.executable, "-c", code], cwd=cwd, env=env, capture_output=True, text=True,
                          timeout=timeout)


def test_import_and_help_stay_light():
    code = ("import sys, dvsot, sctn, benchmarks\n"
            "from dvsot.cli import main\n"
            "try:\n    main(['--help'])\nexcept SystemExit:\n    pass\n"
            f"print(sorted(m for m in sys.modules if m.split('.')[0] in {HEAVY!r}))\n")
    out = _run(code)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip().splitlines()[-1] == "[]"


@pytest.mark.parametrize("package", ["dvsot", "sctn", "benchmarks"])
def test_every_public_name_resolves(package):
    import importlib

    mod = importlib.import_module(package)
    assert mod.__all__ and set(mod.__all__) <= set(dir(mod))
    for name in mod.__all__:
        assert getattr(mod, name) is not None, name
    assert not hasattr(mod, "no_such_name")  # hasattr: AttributeError, not another exception


def test_generate_is_the_function_of_its_module():
    import types

    import dvsot
    from dvsot.pipeline import generate as module

    assert isinstance(dvsot.generate, types.FunctionType) and dvsot.generate is module.generate
    assert not _has_module("dvsot.generate")  # the old callable module is gone


@pytest.mark.parametrize("old, new, name", [("dvsot.config", "dvsot.scene", "load_scene"),
                                            ("dvsot.torchdata", "dvsot.dataset.torchdata", "SegmentDataset"),
                                            ("dvsot.errors", "dvsot.core.errors", "UserError")])
def test_old_public_paths_warn_and_still_import(old, new, name, monkeypatch):
    import importlib

    monkeypatch.delitem(sys.modules, old, raising=False)
    with pytest.warns(DeprecationWarning, match=f"{old} is deprecated: import {new}"):
        mod = importlib.import_module(old)
    assert getattr(mod, name) is getattr(importlib.import_module(new), name)


@pytest.mark.parametrize("old", ["dvsot.exchange", "dvsot.recordings", "dvsot.textevents", "dvsot.preview",
                                 "dvsot.sampling", "dvsot.templates", "dvsot.limits", "dvsot.yaml12",
                                 "dvsot.strict", "dvsot.defaults", "dvsot.lazy", "dvsot.dataset.safe_names",
                                 "benchmarks.ablation", "benchmarks.regression"])
def test_paths_only_the_project_used_are_gone(old):
    assert not _has_module(old)


def _has_module(dotted: str) -> bool:
    """Whether the package above `dotted` holds a module or package of its last name (a file, not an import:
    an editable install may find the name in another checkout)."""
    import importlib
    import pkgutil

    parent, _, name = dotted.rpartition(".")
    return any(m.name == name for m in pkgutil.iter_modules(importlib.import_module(parent).__path__))


def test_training_is_plain_functions_from_their_modules():
    import benchmarks
    import sctn
    from benchmarks.trackers.siamfc.train import train_siamfc
    from sctn.ann import train_twin
    from sctn.training.snn import train

    assert sctn.train is train and sctn.train_twin is train_twin and benchmarks.train_siamfc is train_siamfc
    assert "sctn.train" not in sys.modules and not (Path(sctn.__file__).parent / "train.py").exists()


def test_a_call_through_the_package_meets_a_patch(monkeypatch):
    import sctn

    monkeypatch.setattr("sctn.training.snn.train", lambda *a, **k: ("patched", a, k))
    assert sctn.train(["f.h5"], cfg=None) == ("patched", (["f.h5"],), {"cfg": None})


def readme_block() -> str:
    """The Python block of README.md between the python-api markers."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    m = re.search(r"<!-- python-api:start -->\s*```python\n(.*?)```\s*<!-- python-api:end -->", text, re.S)
    assert m, "README.md: no python-api block"
    return m.group(1)


def test_the_readme_python_block_runs_as_written(tmp_path):
    pytest.importorskip("bpy")
    (tmp_path / "blender_scenes").symlink_to(ROOT / "blender_scenes")  # the block's paths are the repository's
    out = _run(readme_block(), cwd=tmp_path, timeout=900)  # a loaded machine: minutes, not seconds
    assert out.returncode == 0, out.stderr[-2000:]
    lines = out.stdout.strip().splitlines()
    assert re.fullmatch(r"quickstart 80x60 \d+ segments, \d+ events in the first", lines[0]), lines
    n = int(lines[0].split()[2])
    assert n == 10  # 0.1 s of 10 ms segments
    m = re.fullmatch(r"rct quickstart A=(\S+) R=(\S+) ARscore=(\S+)", lines[1])
    assert m and all(0.0 <= float(v) <= 1.0 for v in m.groups()), lines
    m = re.fullmatch(r"(\d+) segments with a box, (\d+) batches", lines[2])
    assert m and 1 <= int(m.group(1)) <= n and int(m.group(2)) == -(-int(m.group(1)) // 4), lines
    assert (tmp_path / "quickstart-api.h5").is_file()
    report = tmp_path / "bench-api"
    assert {"results.json", "table.txt", "run.json"} <= {p.name for p in report.iterdir()}
    assert (report / "rct").is_dir()
