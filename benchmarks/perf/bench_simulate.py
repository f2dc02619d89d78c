"""Time `dvsot simulate` end to end on an image directory, beside esim_py on the same files; print JSON figures.

    python -m benchmarks.perf.bench_simulate FRAMES_DIR --timestamps T.txt [--runs 3]
        [--tree DIR ...] [--esim-python PYTHON]

Each round runs every variant once, in turn (so a loaded machine's drift hits them alike): `dvsot
simulate FRAMES_DIR --timestamps T.txt -o OUT.h5 --quiet` as a whole process (start-up, decoding,
simulation, the written and read-back file), once per --tree (a checkout put first on PYTHONPATH; default:
the dvsot this Python imports), and esim_py (ESIM's C++ port from rpg_vid2e, contrast 0.2/0.2, eps 1e-3,
no refractory period: dvsot's defaults) when --esim-python names a Python that imports it (default: this
one, if it does). esim_py is timed as a process (start-up, import, generateFromFolder, no file written) and
as its generateFromFolder call alone. Printed per variant: the median frames/s over the rounds, their
range, and CPU milliseconds a frame (the child's user + system time); and each dvsot variant's ratio to
esim_py's frames/s, against the process and against the call.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

_ESIM = """
import sys, time
import esim_py
sim = esim_py.EventSimulator(0.2, 0.2, 0.0, 1e-3, True)
a = time.perf_counter()
ev = sim.generateFromFolder(sys.argv[1], sys.argv[2])
print(time.perf_counter() - a, len(ev))
"""


def _child_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def _timed(cmd: list[str], env: dict[str, str] | None = None, cwd: str | None = None) -> tuple[float, float, str]:
    """(wall s, CPU s, stdout) of one subprocess run; a failure raises with its stderr."""
    c0, a = _child_cpu(), time.perf_counter()
    done = subprocess.run(cmd, env=env, capture_output=True, text=True, cwd=cwd)
    wall, cpu = time.perf_counter() - a, _child_cpu() - c0
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(cmd[:4])} ... failed ({done.returncode}): {done.stderr.strip()[-400:]}")
    return wall, cpu, done.stdout


def _tree_env(tree: str) -> dict[str, str]:
    """This environment with the checkout `tree` (if any) first on PYTHONPATH."""
    env = dict(os.environ)
    if tree:
        env["PYTHONPATH"] = os.pathsep.join(p for p in (str(Path(tree).resolve()), env.get("PYTHONPATH")) if p)
    return env


def _imports_esim(python: str) -> bool:
    return subprocess.run([python, "-c", "import esim_py"], capture_output=True).returncode == 0


def _summary(frames: int, walls: list[float], cpus: list[float]) -> dict:
    med = statistics.median(walls)
    return {"frames_per_s": round(frames / med, 1), "frames_per_s_range": [round(frames / max(walls), 1),
                                                                            round(frames / min(walls), 1)],
            "cpu_ms_per_frame": round(1e3 * statistics.median(cpus) / frames, 2)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("frames", help="directory of images, sorted by name (as both simulators read it)")
    parser.add_argument("--timestamps", required=True, help="seconds, one per line, one per image")
    parser.add_argument("--runs", type=int, default=3, help="rounds; each runs every variant once")
    parser.add_argument("--tree", action="append", default=[], help="a dvsot checkout to time (repeatable)")
    parser.add_argument("--esim-python", help="a Python that imports esim_py (default: this one, if it does)")
    args = parser.parse_args()
    frames = sum(1 for p in Path(args.frames).iterdir() if p.suffix.lower() in {".png", ".jpg", ".tif", ".tiff"})
    esim_python = args.esim_python or sys.executable
    have_esim = _imports_esim(esim_python)
    trees = args.tree or [""]
    walls: dict[str, list[float]] = {}
    cpus: dict[str, list[float]] = {}
    events: dict[str, int] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(args.runs):
            if have_esim:
                wall, cpu, out = _timed([esim_python, "-c", _ESIM, args.frames, args.timestamps])
                call, n = out.split()
                for key, w in (("esim_py_process", wall), ("esim_py_call", float(call))):
                    walls.setdefault(key, []).append(w)
                    cpus.setdefault(key, []).append(cpu)
                events["esim_py"] = int(n)
            for k, tree in enumerate(trees):
                name = f"dvsot:{tree}" if tree else "dvsot"
                env = _tree_env(tree)
                # run from the temp directory: `python -m` puts the working directory first on sys.path, so
                # from inside a checkout its dvsot, not the tree's, would be timed
                wall, cpu, out = _timed([sys.executable, "-m", "dvsot.cli", "simulate", str(Path(args.frames).resolve()),
                                         "--timestamps", str(Path(args.timestamps).resolve()), "-o",
                                         f"{tmp}/out{k}.h5", "--quiet"], env, cwd=tmp)
                walls.setdefault(name, []).append(wall)
                cpus.setdefault(name, []).append(cpu)
                events[name] = json.loads(out.strip().splitlines()[-1])["events"]
    imported = {}  # which dvsot each variant ran: a tree that is not first on the path would time another one
    for tree in trees:
        with tempfile.TemporaryDirectory() as where:
            imported[f"dvsot:{tree}" if tree else "dvsot"] = subprocess.run(
                [sys.executable, "-c", "import dvsot; print(dvsot.__file__)"], env=_tree_env(tree), cwd=where,
                capture_output=True, text=True).stdout.strip()
    result = {"frames": frames, "input": args.frames, "runs": args.runs, "events": events, "imported": imported,
              "esim_py": esim_python if have_esim else f"not timed: {esim_python} does not import esim_py"}
    for name in walls:
        result[name] = _summary(frames, walls[name], cpus[name])
    if have_esim:
        for name in walls:
            if name.startswith("dvsot"):
                fps = result[name]["frames_per_s"]
                result[name]["x_esim_py_process"] = round(fps / result["esim_py_process"]["frames_per_s"], 2)
                result[name]["x_esim_py_call"] = round(fps / result["esim_py_call"]["frames_per_s"], 2)
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
