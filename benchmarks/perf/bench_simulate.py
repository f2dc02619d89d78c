"""Time `dvsot simulate` end to end on an image directory, beside esim_py on the same files; print JSON figures.

    python -m benchmarks.perf.bench_simulate FRAMES_DIR --timestamps T.txt [--runs 3]
        [--tree DIR ...] [--esim-python PYTHON] [--preset NAME ...] [--v2e-python PYTHON --v2e-src DIR]

Each round runs every variant once, in turn (so a loaded machine's drift hits them alike): `dvsot
simulate FRAMES_DIR --timestamps T.txt -o OUT.h5 --quiet` as a whole process (start-up, decoding,
simulation, the written and read-back file), once per --tree (a checkout put first on PYTHONPATH; default:
the dvsot this Python imports), and esim_py (ESIM's C++ port from rpg_vid2e, contrast 0.2/0.2, eps 1e-3,
no refractory period: dvsot's defaults) in the Python --esim-python names (an error, exit 2, if it does not
import esim_py; without the option: this one, if it does). esim_py is timed as a process (start-up,
import, generateFromFolder, no file written) and as its generateFromFolder call alone. Printed per variant: the median
frames/s over the rounds, their range, and CPU milliseconds a frame (the child's user + system time); and each dvsot
variant's ratio to esim_py's frames/s, against the process and against the call.

--preset (repeatable) runs every tree once per sensor preset (`dvsot simulate --preset NAME`; variant
`dvsot[NAME]`); without it, the default (ideal) model only. --v2e-python and --v2e-src time v2e's
EventEmulator (SensorsINI/v2e, in its own Python, its source first on the path) as a process on the same
images (read by OpenCV as 8-bit grey), once per preset with the parameters v2e shares with it
(thresholds, mismatch, cutoff, shot noise, leak rate and spread, refractory period; v2e has no latency,
readout limit or hot pixels); each dvsot variant's ratio to v2e's frames/s of its preset is printed. Both
options or neither; a v2e that does not import is an error (exit 2) before any round.
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


_V2E = """
import json, logging, sys, time
from pathlib import Path
import cv2
from v2ecore.emulator import EventEmulator
logging.disable(logging.WARNING)
files = sorted(p for p in Path(sys.argv[1]).iterdir() if p.suffix.lower() in {".png", ".jpg", ".tif", ".tiff"})
times = [float(v) for v in Path(sys.argv[2]).read_text().split()]
emu = EventEmulator(device="cpu", seed=1, output_folder=None, **json.loads(sys.argv[3]))
a, n = time.perf_counter(), 0
for f, t in zip(files, times):
    ev = emu.generate_events(cv2.imread(str(f), cv2.IMREAD_GRAYSCALE), t - times[0])
    n += 0 if ev is None else len(ev)
print(time.perf_counter() - a, n)
"""


def _v2e_kwargs(preset: str | None) -> dict:
    """v2e's EventEmulator parameters matching a dvsot preset's (the ones v2e has)."""
    from dvsot.events import EventParams

    p = EventParams(preset=preset or "ideal")
    return dict(pos_thres=p.cp, neg_thres=p.cn, sigma_thres=(p.sigma_cp + p.sigma_cn) / 2,
                cutoff_hz=p.lowpass_cutoff_hz if p.lowpass_order else 0.0, leak_rate_hz=p.leak_hz,
                shot_noise_rate_hz=p.shot_noise_hz, refractory_period_s=p.refractory_us * 1e-6,
                leak_jitter_fraction=0.1, noise_rate_cov_decades=p.leak_spread_decades)


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


def _v2e_import_error(python: str, src: str) -> str:
    """The last line of the error importing v2e's EventEmulator in `python` with `src` on its path ('' if none)."""
    with tempfile.TemporaryDirectory() as where:
        done = subprocess.run([python, "-c", "from v2ecore.emulator import EventEmulator"], capture_output=True,
                              text=True, cwd=where, env={**os.environ, "PYTHONPATH": str(Path(src).resolve())})
    return "" if done.returncode == 0 else (done.stderr.strip().splitlines() or [f"exit {done.returncode}"])[-1]


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
    parser.add_argument("--esim-python", help="a Python that imports esim_py (without it: this one, if it does)")
    parser.add_argument("--preset", action="append", default=[], help="a sensor preset to time (repeatable)")
    parser.add_argument("--v2e-python", help="a Python with v2e's requirements, to time v2e too")
    parser.add_argument("--v2e-src", help="v2e's source tree (holds v2ecore/), with --v2e-python")
    args = parser.parse_args()
    # checked before any round: a reference that cannot run would otherwise fail, or go untimed, after minutes
    if bool(args.v2e_python) != bool(args.v2e_src):
        parser.error("--v2e-python and --v2e-src go together")
    if args.v2e_python and (why := _v2e_import_error(args.v2e_python, args.v2e_src)):
        parser.error(f"{args.v2e_python} with --v2e-src {args.v2e_src} does not import v2ecore.emulator: {why}")
    presets = args.preset or [None]
    frames = sum(1 for p in Path(args.frames).iterdir() if p.suffix.lower() in {".png", ".jpg", ".tif", ".tiff"})
    esim_python = args.esim_python or sys.executable
    have_esim = _imports_esim(esim_python)
    if args.esim_python and not have_esim:
        parser.error(f"--esim-python {args.esim_python} does not import esim_py")
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
            for preset in presets if args.v2e_python else []:
                env = {**os.environ, "PYTHONPATH": str(Path(args.v2e_src).resolve())}
                wall, cpu, out = _timed([args.v2e_python, "-c", _V2E, str(Path(args.frames).resolve()),
                                         str(Path(args.timestamps).resolve()), json.dumps(_v2e_kwargs(preset))],
                                        env, cwd=tmp)
                name = f"v2e[{preset or 'ideal'}]"
                walls.setdefault(name, []).append(wall)
                cpus.setdefault(name, []).append(cpu)
                events[name] = int(out.split()[1])
            for k, (tree, preset) in enumerate((t, p) for t in trees for p in presets):
                name = (f"dvsot:{tree}" if tree else "dvsot") + (f"[{preset}]" if preset else "")
                env = _tree_env(tree)
                # run from the temp directory: `python -m` puts the working directory first on sys.path, so
                # from inside a checkout its dvsot, not the tree's, would be timed
                wall, cpu, out = _timed(
                    [
                        sys.executable,
                        "-m",
                        "dvsot.cli",
                        "simulate",
                        str(Path(args.frames).resolve()),
                        "--timestamps",
                        str(Path(args.timestamps).resolve()),
                        "-o",
                        f"{tmp}/out{k}.h5",
                        "--quiet",
                        *(["--preset", preset] if preset else []),
                    ],
                    env,
                    cwd=tmp,
                )
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
    for name in walls:
        preset = name.partition("[")[2].rstrip("]") or "ideal"
        if name.startswith("dvsot") and f"v2e[{preset}]" in result:
            result[name]["x_v2e"] = round(result[name]["frames_per_s"] / result[f"v2e[{preset}]"]["frames_per_s"], 2)
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
