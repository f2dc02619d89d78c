"""Many scenes, one task each: on this process, a Dask LocalCluster (`local:N`) or a running cluster (`tcp://HOST:PORT`).

Each scene is rendered by `render_task` in a worker process, one at a time per process (Blender is
process-global), with `render.threads` (when the scene leaves it at 0, all cores) set to the worker's
share of its machine's cores; with several workers on a machine each process is bound to its share
(warm_up), since Blender's idle threads would otherwise spin on the others' CPUs. Every worker first
renders a 16x12 scene (`warm_up`: the bpy import, Cycles' first render, the event kernels), so a scene's
task time is its own. Results are collected one by one
(dvsot.runtime.dask_tasks.run_tasks): a failure is recorded in the manifest with its one-line error and the scene is
resubmitted, preferring another worker, up to `retries` times.
The manifest (JSON: one record per scene with variant, seed, file, drawn values, status, attempts) is
rewritten atomically after every result.
"""

from __future__ import annotations

import json
import os
import sys
import threading
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Callable

from dvsot.runtime.dask_tasks import (Cluster, Failure, host_of, host_workers, map_tasks, parse_scheduler, run_tasks,
                           worker_address)
from dvsot.core.errors import exception_line
from dvsot.runtime.outputs import replacing

__all__ = ["SceneTask", "Manifest", "render_task", "warm_up", "run_scenes", "output_is_done", "summary_line",
           "record_dict", "map_tasks", "parse_scheduler"]  # the last two: dvsot.runtime.dask_tasks's, kept here

_RENDER_LOCK = threading.Lock()  # one Blender scene per process, whatever the worker's thread count


@dataclass(frozen=True)
class SceneTask:
    """One scene to render: its concrete scene text, where to write it and what the manifest says of it."""

    name: str
    text: str                      # the concrete scene file (YAML)
    source: str                    # for messages: the scene or template file
    base_dir: str                  # absolute; relative mesh and texture paths resolve against it
    output: str                    # absolute .h5 path
    overrides: dict = field(default_factory=dict)
    preview: bool = False
    record: dict = field(default_factory=dict)  # manifest fields known up front (variant, seed, drawn)


_BOUND: list[int] = []  # the CPUs warm_up bound this worker process to (empty: not bound)


def _this_host() -> str | None:
    """The machine part of this Dask worker's address, or None outside a worker."""
    try:
        from distributed import get_worker

        return host_of(get_worker().address)
    except (ImportError, ValueError):
        return None


def _threads_for_this_worker(host_workers: dict[str, int]) -> int:
    """Render threads for a worker process: its bound CPUs, else this machine's cores shared among its workers."""
    if _BOUND:
        return len(_BOUND)
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    host = _this_host()
    return cores if host is None else max(1, cores // max(1, host_workers.get(host, 1)))


def cpu_share(cpus: list[int], slot: int, workers_here: int) -> set[int] | None:
    """The CPUs of worker `slot` of `workers_here` on a machine with these CPUs: an equal share, or None when
    the worker has them all (one worker) or there are fewer CPUs than workers."""
    share = len(cpus) // max(1, workers_here)
    if workers_here <= 1 or share < 1 or not 0 <= slot < workers_here:
        return None
    return set(sorted(cpus)[slot * share:(slot + 1) * share])


def pin_process(cpus: set[int]) -> None:
    """Bind every thread of this process (and so the threads they start) to these CPUs (Linux)."""
    for tid in os.listdir("/proc/self/task"):
        try:
            os.sched_setaffinity(int(tid), cpus)
        except OSError:  # a thread that has just ended
            pass


def _pin_to_share(host_workers: dict[str, int], slot: int) -> list[int] | None:
    """Bind this worker process to its share of its machine's CPUs (slot among the workers there); the CPUs or None.

    Why: Blender's task scheduler (oneTBB) starts a thread per CPU it may use and keeps them spinning in
    sched_yield between tasks, so a worker rendering on one thread also keeps its other CPUs busy, and
    workers on one machine slow each other down: bound to its share, each competes only with itself.
    """
    host = _this_host()
    if host is None or not hasattr(os, "sched_setaffinity") or not os.path.isdir("/proc/self/task"):
        return None
    cpus = cpu_share(sorted(os.sched_getaffinity(0)), slot, host_workers.get(host, 1))
    if cpus is None:
        return None
    pin_process(cpus)
    _BOUND[:] = sorted(cpus)
    return list(_BOUND)


def _real_bpy_first() -> None:
    """Drop Blender's script folders from sys.path before bpy is imported here.

    A worker spawned by a process that had imported bpy inherits its sys.path, with bpy's script folders
    in front; one holds a `bpy` package of Blender's scripts that hides the real module (ModuleNotFoundError:
    _bpy). Importing bpy puts them back.
    """
    if "bpy" in sys.modules:
        return
    import site

    roots = tuple(os.path.join(d, "bpy") + os.sep for d in site.getsitepackages() + [site.getusersitepackages()])
    sys.path[:] = [p for p in sys.path if not p.startswith(roots)]


def render_task(task: SceneTask, host_workers: dict[str, int] | None = None) -> dict:
    """Render one scene into its dataset file (in a worker): its summary, or {"error": one line} on any failure."""
    t_task, cpu_task = time.perf_counter(), time.process_time()
    worker = worker_address()
    try:
        with _RENDER_LOCK:
            _real_bpy_first()
            from dvsot.scene import parse_scene
            from dvsot.pipeline.generate import generate

            cfg = parse_scene(task.text, task.source, Path(task.base_dir), dict(task.overrides))
            if cfg.render.threads == 0 and host_workers is not None:
                cfg.render.threads = _threads_for_this_worker(host_workers)
            from dvsot.scene.checks import visibility_warnings

            warnings = visibility_warnings(cfg)  # here, not at the head: each costs a scene's projections
            # the dataset file and its preview are renamed into place together, or neither (dvsot.pipeline.generate)
            summary = generate(cfg, task.output, task.text, progress=False, preview=task.preview)
            summary["task_s"] = round(time.perf_counter() - t_task, 3)  # with imports, scene check, waiting on the lock
            # CPU seconds of the whole worker process (every render thread) during the task: what the scene cost
            # whatever else ran on the machine
            summary["cpu_s"] = round(time.process_time() - cpu_task, 3)
            summary["render_threads"] = cfg.render.threads
            if hasattr(os, "sched_getaffinity"):
                summary["cpus"] = sorted(os.sched_getaffinity(0))  # the worker's share (warm_up), or every CPU
            summary["warnings"] = warnings
    except Exception as exc:  # returned, not raised: the head records it and retries (no traceback in worker logs)
        return {"error": exception_line(exc, 300), "worker": worker}
    summary["worker"] = worker
    return summary


_WARM = False  # this process has rendered the warm-up scene
_WARM_SCENE = """name: warm_up
duration_s: 0.01
sensor: {width: 16, height: 12, focal_mm: 35}
camera: {keyframes: [{t: 0, location: [0, -10, 0], look_at: [0, 0, 0]}]}
target:
  shape: cube
  size_m: 1.5
  trajectory: {interpolation: linear, keyframes: [{t: 0, location: [-1, 0, 0]}, {t: 0.01, location: [1, 0, 0]}]}
background: {material: {texture: {type: noise, scale: 10}}}
sampling: {min_rate_hz: 200}
"""


def warm_up(host_workers: dict[str, int] | None = None, threads: int = 0, slot: int | None = None) -> dict:
    """Pay a worker process's one-time costs on a 16x12 scene: {"warm_s": seconds, "worker", "cpus"} or {"error",
    "worker"}. With `slot` (its index among the workers on its machine) the process is first bound to its share
    of the machine's CPUs ("cpus"; None: not bound, it has them all).

    The bpy import, Cycles' first render, h5py and the event kernels' load (numba's cache) cost seconds once per
    process; a run pays them before its first submit, so each scene's task_s and cpu_s are its own. The scene
    renders with the threads the worker's scenes will use (`threads`, else its share of the machine's cores).
    """
    import tempfile

    global _WARM
    if _WARM:
        return {"warm_s": 0.0, "worker": worker_address()}
    t0 = time.perf_counter()
    cpus = None
    try:
        with _RENDER_LOCK, tempfile.TemporaryDirectory(prefix="dvsot-warm-up-") as tmp:
            if slot is not None and host_workers:
                cpus = _pin_to_share(host_workers, slot)  # before bpy starts its threads
            _real_bpy_first()
            from dvsot.scene import parse_scene
            from dvsot.pipeline.generate import generate
            from dvsot.scene.checks import visibility_warnings

            cfg = parse_scene(_WARM_SCENE, "warm-up scene", Path(tmp))
            cfg.render.threads = threads or (_threads_for_this_worker(host_workers) if host_workers else 0)
            visibility_warnings(cfg)
            generate(cfg, Path(tmp) / "warm_up.h5", _WARM_SCENE, progress=False)
    except Exception as exc:  # a worker that cannot render says so in each scene's own error
        return {"error": exception_line(exc, 300), "worker": worker_address()}
    _WARM = True
    return {"warm_s": round(time.perf_counter() - t0, 3), "worker": worker_address(), "cpus": cpus}


def warm_workers(client, threads: int = 0, timeout_s: float = 300.0) -> list[dict]:
    """warm_up() once on every worker the scheduler knows now (pinned to each), waiting at most timeout_s.

    threads: the render threads the scenes will set (0: each worker's share of its machine's cores). Workers
    that join later pay these costs in their first scene.
    """
    import uuid

    from distributed import wait

    hosts, run = host_workers(client), uuid.uuid4().hex[:8]
    addresses = sorted(client.scheduler_info(n_workers=-1)["workers"])
    slots = {w: sum(1 for v in addresses[:k] if host_of(v) == host_of(w))
             for k, w in enumerate(addresses)}  # each worker's index among those on its machine
    futures = [client.submit(warm_up, hosts, threads, slots[w], pure=False, key=f"warm-up-{run}-{k}", workers=[w],
                             allow_other_workers=False)
               for k, w in enumerate(addresses)]
    try:
        wait(futures, timeout=timeout_s)
    except TimeoutError:
        pass  # a slow worker goes on warming; its scenes wait for it
    out = [f.result() if f.status == "finished" else {"error": f"warm-up {f.status}"} for f in futures]
    for f in futures:
        f.release()
    return out


def output_is_done(task: SceneTask) -> bool:
    """Whether the task's output exists, reads back whole and holds this very scene (for --resume)."""
    from dvsot.dataset import Dataset

    if not Path(task.output).is_file():
        return False
    try:
        with Dataset(task.output) as ds:
            ds.verify()
            return ds.attrs.get("scene_yaml") == task.text
    except Exception:  # any damage means: render it again
        return False


class Manifest:
    """The run's manifest: one record per scene, rewritten whole (temp file + rename) on every change."""

    def __init__(self, path: Path, tasks: list[SceneTask]) -> None:
        self.path = path
        self.timing: dict = {}  # seconds: cluster start, workers' warm-up, submit -> last result
        self.records = [{"name": t.name, **t.record, "file": str(Path(t.output)), "status": "pending",
                         "attempts": [], "error": None} for t in tasks]

    def write(self) -> None:
        with replacing(self.path) as tmp:
            tmp.write_text(json.dumps({"format": "dvsot-manifest", "version": 1, "timing": self.timing,
                                       "scenes": self.records}, indent=1)
                           + "\n")


def run_scenes(tasks: list[SceneTask], manifest_path: Path, scheduler: str | None = None, retries: int = 0,
               resume: bool = False, report: Callable[[dict], None] | None = None) -> Manifest:
    """Render every task (this process when scheduler is None), recording each result; the manifest at the end.

    On a cluster the timing holds start_s (the client and any LocalCluster), warm_s (warm_workers) and run_s
    (first submit to last result).
    """
    manifest = Manifest(manifest_path, tasks)
    todo = []
    for i, task in enumerate(tasks):
        if resume and output_is_done(task):
            manifest.records[i]["status"] = "done"
            manifest.records[i]["resumed"] = True
        else:
            todo.append(i)
    manifest.write()
    report = report or (lambda rec: None)
    t0 = time.perf_counter()
    if todo and scheduler is None:
        _run_here(tasks, todo, manifest, retries, report)
    elif todo:
        with Cluster(scheduler) as client:
            manifest.timing["start_s"] = round(time.perf_counter() - t0, 3)
            t0 = time.perf_counter()
            fixed = {t.overrides.get("render.threads") for t in tasks}  # threads set for every scene by --set
            warm_workers(client, fixed.pop() if len(fixed) == 1 and isinstance(next(iter(fixed)), int) else 0)
            manifest.timing["warm_s"] = round(time.perf_counter() - t0, 3)
            t0 = time.perf_counter()
            _run_dask(client, tasks, todo, manifest, retries, report)
    manifest.timing["run_s"] = round(time.perf_counter() - t0, 3)
    manifest.write()
    return manifest


def _ok(outcome: dict | Failure) -> bool:
    return isinstance(outcome, dict) and "error" not in outcome


def _record(manifest: Manifest, i: int, outcome: dict | Failure, final: bool) -> dict:
    rec = manifest.records[i]
    if _ok(outcome):
        rec["attempts"].append({"worker": outcome.get("worker"), "error": None, "wall_s": outcome.get("wall_s"),
                                "task_s": outcome.get("task_s"), "cpu_s": outcome.get("cpu_s"),
                                "render_threads": outcome.get("render_threads"), "cpus": outcome.get("cpus")})
        rec.update(status="done", error=None, events=outcome.get("events"), frames=outcome.get("frames"),
                   warnings=outcome.get("warnings") or [])
    else:
        failure = _failure(outcome)
        rec["attempts"].append({"worker": failure.worker, "error": failure.error})
        rec.update(status="failed" if final else "retrying", error=failure.error)
    manifest.write()
    return rec


def _failure(outcome: Any) -> Failure | None:
    """render_task's {"error": ...} (or a Failure from dvsot.runtime.dask_tasks) as a Failure; None for a summary."""
    if isinstance(outcome, Failure):
        return outcome
    if isinstance(outcome, dict) and "error" in outcome:
        return Failure(outcome["error"], outcome.get("worker"))
    return None if isinstance(outcome, dict) else Failure(f"unexpected task result {type(outcome).__name__}")


def _run_here(tasks, todo, manifest, retries, report) -> None:
    for i in todo:
        for attempt in range(retries + 1):
            outcome = render_task(tasks[i])
            rec = _record(manifest, i, outcome, final=_ok(outcome) or attempt == retries)
            report(rec)
            if rec["status"] == "done":
                break


def _run_dask(client, tasks, todo, manifest, retries, report) -> None:
    hosts = host_workers(client)
    if not hosts:
        print(f"dvsot generate: no workers on {client.scheduler.address} yet; waiting for some", file=sys.stderr)

    def done(k: int, outcome: dict) -> None:
        report(_record(manifest, todo[k], outcome, final=True))

    def failed(k: int, failure: Failure, final: bool) -> None:
        report(_record(manifest, todo[k], failure, final))

    run_tasks(client, render_task, [(tasks[i], hosts) for i in todo], retries, on_result=done, on_failure=failed,
              failure_of=_failure, name="scene", lease_dir=manifest.path.parent)


def summary_line(manifest: Manifest) -> str:
    """One line: how many scenes were rendered, skipped (resumed) and failed."""
    recs = manifest.records
    resumed = sum(1 for r in recs if r.get("resumed"))
    done = sum(1 for r in recs if r["status"] == "done") - resumed
    failed = [r["name"] for r in recs if r["status"] == "failed"]
    text = f"{done} rendered, {resumed} already done, {len(failed)} failed"
    return text + (f" ({', '.join(failed[:10])}{' ...' if len(failed) > 10 else ''})" if failed else "") + \
        f"; manifest {manifest.path}"


def record_dict(task: SceneTask) -> dict:
    """The task as a plain dict (for --dry-run and logs)."""
    return asdict(task)
