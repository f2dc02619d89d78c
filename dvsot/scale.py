"""Many scenes, one task each: on this process, a Dask LocalCluster (`local:N`) or a running cluster (`tcp://HOST:PORT`).

Each scene is rendered by `render_task` in a worker process, one at a time per process (Blender is
process-global), with `render.threads` (when the scene leaves it at 0, all cores) set to the worker's
share of its machine's cores. Results are collected one by one: a failure is recorded in the manifest
with its one-line error and the scene is resubmitted, preferring another worker, up to `retries` times.
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

from dvsot.errors import UserError, exception_line
from dvsot.outputs import replacing

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


def parse_scheduler(spec: str) -> tuple[str, int | str]:
    """('local', N) for local:N, ('address', spec) for tcp://HOST:PORT (or tls://, ws://, wss://); UserError else."""
    if spec.startswith("local:"):
        n = spec.removeprefix("local:")
        if not n.isdigit() or not 1 <= int(n) <= 256:
            raise UserError(f"--scheduler local:N needs N, a number of worker processes in 1..256, got {spec!r}")
        return "local", int(n)
    scheme, _, rest = spec.partition("://")
    host, _, port = rest.rpartition(":")
    if scheme not in ("tcp", "tls", "ws", "wss") or not host or not port.isdigit():
        raise UserError(f"--scheduler must be local:N or tcp://HOST:PORT, got {spec!r}")
    return "address", spec


def _threads_for_this_worker(host_workers: dict[str, int]) -> int:
    """Render threads for a worker process: this machine's cores shared among the workers on it."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    try:
        from distributed import get_worker

        host = get_worker().address.rpartition(":")[0]
    except (ImportError, ValueError):
        return cores
    return max(1, cores // max(1, host_workers.get(host, 1)))


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
    t_task = time.perf_counter()
    worker = _worker_address()
    try:
        with _RENDER_LOCK:
            _real_bpy_first()
            from dvsot.config import parse_scene
            from dvsot.generate import generate

            cfg = parse_scene(task.text, task.source, Path(task.base_dir), dict(task.overrides))
            if cfg.render.threads == 0 and host_workers is not None:
                cfg.render.threads = _threads_for_this_worker(host_workers)
            from dvsot.scene_checks import visibility_warnings

            warnings = visibility_warnings(cfg)  # here, not at the head: ~0.1 s a scene
            from dvsot.generate import run_manifest
            from dvsot.outputs import run_outputs

            # the dataset file and its preview are renamed into place together, or neither (dvsot.outputs)
            with run_outputs(run_manifest(task.output) if task.preview else None) as run:
                summary = generate(cfg, task.output, task.text, progress=False)
                if task.preview:
                    from dvsot.preview import PREVIEW_SEGMENTS, write_preview

                    gif = Path(task.output).with_suffix(".gif")
                    write_preview(run.staged(task.output), gif, max_segments=PREVIEW_SEGMENTS)
                    summary["preview"] = str(gif)
            summary["task_s"] = round(time.perf_counter() - t_task, 3)  # with imports, scene check, waiting on the lock
            summary["render_threads"] = cfg.render.threads
            summary["warnings"] = warnings
    except Exception as exc:  # returned, not raised: the head records it and retries (no traceback in worker logs)
        return {"error": exception_line(exc, 300), "worker": worker}
    summary["worker"] = worker
    return summary


def _worker_address() -> str:
    try:
        from distributed import get_worker

        return get_worker().address
    except (ImportError, ValueError):
        return f"pid {os.getpid()}"


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
        self.timing: dict = {}  # seconds: cluster start, submit -> last result
        self.records = [{"name": t.name, **t.record, "file": str(Path(t.output)), "status": "pending",
                         "attempts": [], "error": None} for t in tasks]

    def write(self) -> None:
        with replacing(self.path) as tmp:
            tmp.write_text(json.dumps({"format": "dvsot-manifest", "version": 1, "timing": self.timing,
                                       "scenes": self.records}, indent=1)
                           + "\n")


def run_scenes(tasks: list[SceneTask], manifest_path: Path, scheduler: str | None = None, retries: int = 0,
               resume: bool = False, report: Callable[[dict], None] | None = None) -> Manifest:
    """Render every task (this process when scheduler is None), recording each result; the manifest at the end."""
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
        kind, arg = parse_scheduler(scheduler)
        with _client(kind, arg) as client:
            manifest.timing["start_s"] = round(time.perf_counter() - t0, 3)
            t0 = time.perf_counter()
            _run_dask(client, tasks, todo, manifest, retries, report)
    manifest.timing["run_s"] = round(time.perf_counter() - t0, 3)
    manifest.write()
    return manifest


def _ok(outcome: dict | BaseException) -> bool:
    return isinstance(outcome, dict) and "error" not in outcome


def _record(manifest: Manifest, i: int, outcome: dict | BaseException, final: bool) -> dict:
    rec = manifest.records[i]
    if _ok(outcome):
        rec["attempts"].append({"worker": outcome.get("worker"), "error": None, "wall_s": outcome.get("wall_s"),
                                "task_s": outcome.get("task_s"), "render_threads": outcome.get("render_threads")})
        rec.update(status="done", error=None, events=outcome.get("events"), frames=outcome.get("frames"),
                   warnings=outcome.get("warnings") or [])
    else:
        err = outcome["error"] if isinstance(outcome, dict) else exception_line(outcome, 300)
        worker = outcome["worker"] if isinstance(outcome, dict) else None
        rec["attempts"].append({"worker": worker, "error": err})
        rec.update(status="failed" if final else "retrying", error=err)
    manifest.write()
    return rec


def _run_here(tasks, todo, manifest, retries, report) -> None:
    for i in todo:
        for attempt in range(retries + 1):
            outcome = render_task(tasks[i])
            rec = _record(manifest, i, outcome, final=_ok(outcome) or attempt == retries)
            report(rec)
            if rec["status"] == "done":
                break


class _client:
    """A distributed Client on a new LocalCluster of single-threaded worker processes, or on a running scheduler."""

    def __init__(self, kind: str, arg: int | str) -> None:
        self.kind, self.arg, self.cluster, self.client = kind, arg, None, None

    def __enter__(self):
        import logging

        from distributed import Client, LocalCluster

        if self.kind == "local":
            try:
                self.cluster = LocalCluster(n_workers=self.arg, threads_per_worker=1, processes=True,
                                            dashboard_address=None,
                                            silence_logs=logging.CRITICAL)  # failures reach the manifest, one line each
            except (RuntimeError, OSError, TimeoutError) as exc:
                from dvsot.errors import RunError

                raise RunError(f"--scheduler local:{self.arg}: the worker processes did not start "
                               f"({exception_line(exc, 300)})") from None
            self.client = Client(self.cluster)
        else:
            try:
                self.client = Client(self.arg, timeout="20s")
            except (OSError, TimeoutError) as exc:
                raise UserError(f"--scheduler {self.arg}: cannot reach the scheduler ({exception_line(exc, 300)})") from None
        return self.client

    def __exit__(self, *exc) -> None:
        if self.client is not None:
            self.client.close()
        if self.cluster is not None:
            self.cluster.close()


def _host_workers(client) -> dict[str, int]:
    counts: dict[str, int] = {}
    for address in client.scheduler_info(n_workers=-1)["workers"]:
        host = address.rpartition(":")[0]
        counts[host] = counts.get(host, 0) + 1
    return counts


def _run_dask(client, tasks, todo, manifest, retries, report) -> None:
    from distributed import as_completed

    hosts = _host_workers(client)
    if not hosts:
        print(f"dvsot generate: no workers on {client.scheduler.address} yet; waiting for some", file=sys.stderr)
    pending: dict = {}
    done = as_completed()
    for i in todo:
        fut = client.submit(render_task, tasks[i], hosts, pure=False, key=f"scene-{tasks[i].name}-1")
        pending[fut.key] = (i, 1)
        done.add(fut)
    for fut in done:
        i, attempt = pending.pop(fut.key)
        try:
            outcome: Any = fut.result()
        except Exception as exc:  # the worker died (KilledWorker), the task could not be sent or run, ...
            outcome = exc
        final = _ok(outcome) or attempt > retries
        rec = _record(manifest, i, outcome, final)
        report(rec)
        fut.release()
        if not final:
            tried = {a["worker"] for a in rec["attempts"]}
            others = [w for w in client.scheduler_info(n_workers=-1)["workers"] if w not in tried]
            # on another worker while there is one (a strict restriction: a loose one lands wherever is free first)
            again = client.submit(render_task, tasks[i], _host_workers(client) or hosts, pure=False,
                                  key=f"scene-{tasks[i].name}-{attempt + 1}", workers=others or None)
            pending[again.key] = (i, attempt + 1)
            done.add(again)


def map_tasks(scheduler: str, fn: Callable, calls: list[tuple],
              on_result: Callable[[int, Any], None] | None = None) -> list:
    """fn(*call) for every call, one Dask task each (local:N or tcp://HOST:PORT); results in call order.

    Results are taken as they finish (on_result(k, result) for each); a task that raised, or whose worker
    died, is one RunError line and the rest are cancelled.
    """
    from distributed import as_completed

    from dvsot.errors import RunError

    kind, arg = parse_scheduler(scheduler)
    results: list = [None] * len(calls)
    with _client(kind, arg) as client:
        futures = {client.submit(fn, *call, pure=False): k for k, call in enumerate(calls)}
        for fut in as_completed(futures):
            k = futures[fut]
            try:
                results[k] = fut.result()
            except Exception as exc:  # a crash of the task itself, a dead worker, a lost connection
                client.cancel(list(futures))
                raise RunError(f"task {k + 1} of {len(calls)} failed on {scheduler}: {exception_line(exc, 300)}") from None
            if on_result is not None:
                on_result(k, results[k])
    return results


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
