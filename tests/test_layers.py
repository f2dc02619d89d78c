"""The layers of docs/ARCHITECTURE.md, read from the code: core of dvsot <- sctn <- benchmarks <- dvsot/commands.

Every import under dvsot/, sctn/ and benchmarks/ counts: top-level, inside functions, relative, and
`importlib.import_module("...")` with a literal name. Only dvsot/blender/ may import bpy (or Blender's
mathutils / bmesh).
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("dvsot", "sctn", "benchmarks")
RANK = {"core": 0, "sctn": 1, "benchmarks": 2, "commands": 3}
BLENDER_MODULES = {"bpy", "mathutils", "bmesh"}

# (importing module, imported module) edges against the order that are a known design need, each with why.
# Empty: every edge the first run of this test found was fixed instead.
EXCEPTIONS: set[tuple[str, str]] = set()


def layer(module: str) -> str | None:
    """The layer of a dotted module name; None for modules outside the project (numpy, torch, ...)."""
    top = module.split(".")[0]
    if top in BLENDER_MODULES:
        return "bpy"
    if module == "dvsot.cli" or module == "dvsot.commands" or module.startswith("dvsot.commands."):
        return "commands"
    if top == "dvsot":
        return "core"
    if top in ("sctn", "benchmarks"):
        return top
    return None


def module_name(path: Path, root: Path) -> str:
    """The dotted name of a source file under root (a package's __init__.py is the package)."""
    parts = list(path.relative_to(root).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imports(path: Path, root: Path) -> list[tuple[int, str]]:
    """(line, imported module) for every import statement and literal importlib.import_module call in a file."""
    name = module_name(path, root)
    package = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
        if isinstance(node, ast.Import):
            found += [(node.lineno, a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[: len(package) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            # `from dvsot import cli` names a submodule of another layer than its package: count that too
            found.append((node.lineno, target))
            found += [(node.lineno, f"{target}.{a.name}") for a in node.names
                      if layer(f"{target}.{a.name}") != layer(target)]
        elif (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == "import_module"
              and node.args and isinstance(node.args[0], ast.Constant) and isinstance(node.args[0].value, str)):
            found.append((node.lineno, node.args[0].value))
    return found


def violations(root: Path, exceptions: set[tuple[str, str]] = frozenset()) -> list[str]:
    """Every import edge under root's packages that goes against the layer order, one line each."""
    bad = []
    for pkg in PACKAGES:
        for path in sorted((root / pkg).rglob("*.py")):
            src = module_name(path, root)
            here = layer(src)
            for line, target in imports(path, root):
                there = layer(target)
                if there is None or (src, target) in exceptions:
                    continue
                where = f"{path.relative_to(root)}:{line}: {src} imports {target}"
                if there == "bpy":
                    if not (src == "dvsot.blender" or src.startswith("dvsot.blender.")):
                        bad.append(f"{where} (only dvsot/blender/ may import Blender's modules)")
                elif RANK[there] > RANK[here]:
                    bad.append(f"{where} ({here} may not import from {there}, a later layer)")
    return bad


def test_the_project_keeps_its_layers():
    assert violations(ROOT, EXCEPTIONS) == []


def test_inference_does_not_import_training():
    # the tracker fine-tunes (sctn.finetune) but never needs the training loop
    assert [t for _, t in imports(ROOT / "sctn/tracker.py", ROOT) if t.startswith("sctn.train")] == []


def _write(root: Path, rel: str, text: str) -> None:
    path = root / rel
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)


def test_the_checker_finds_each_kind_of_bad_edge(tmp_path):
    for pkg in ("dvsot", "dvsot/commands", "dvsot/blender", "sctn", "benchmarks"):
        _write(tmp_path, f"{pkg}/__init__.py", "")
    _write(tmp_path, "dvsot/fine.py", "import numpy\nfrom dvsot import events\nfrom . import boxes\n")
    _write(tmp_path, "dvsot/blender/scene.py", "import bpy\nfrom mathutils import Vector\n")
    _write(tmp_path, "dvsot/commands/bench.py", "import sctn.tracker\nimport benchmarks.metrics\n")
    _write(tmp_path, "dvsot/cli.py", "import importlib\nimportlib.import_module('dvsot.commands.bench')\n")
    _write(tmp_path, "benchmarks/ok.py", "from sctn.network import SCTN\nfrom dvsot.dataset import Dataset\n")
    _write(tmp_path, "dvsot/up.py", "def f():\n    from sctn.network import SCTN\n")
    _write(tmp_path, "dvsot/rel.py", "from .commands import bench\n")
    _write(tmp_path, "dvsot/gen.py", "def f():\n    import bpy\n")
    _write(tmp_path, "sctn/cmd.py", "from dvsot import cli\n")
    _write(tmp_path, "benchmarks/lazy.py", "import importlib\nm = importlib.import_module('dvsot.commands.info')\n")
    found = violations(tmp_path)
    assert [line.split(": ")[1].split(" (")[0] for line in found] == [
        "dvsot.gen imports bpy", "dvsot.rel imports dvsot.commands",
        "dvsot.up imports sctn.network", "sctn.cmd imports dvsot.cli", "benchmarks.lazy imports dvsot.commands.info"]
    assert found[2].startswith("dvsot/up.py:2: ")
    assert len(violations(tmp_path, {("dvsot.up", "sctn.network")})) == len(found) - 1
