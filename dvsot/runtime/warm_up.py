"""A worker process's one-time costs paid before its first task, so that each task's time is its own.

The caller passes the work that pays them (for scenes: a 16x12 render, which imports bpy, runs Cycles'
first render and loads h5py and the event kernels); this module runs it once per process, first binding
the process to its share of the machine's CPUs (dvsot.runtime.cpu_shares), and once on every worker of a
cluster (warm_workers). One Blender scene runs per process at a time: RENDER_LOCK.
"""

from __future__ import annotations

import os
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path

from dvsot.core.errors import exception_line
from dvsot.runtime.cpu_shares import pin_to_share, threads_for_this_worker
from dvsot.runtime.dask_tasks import host_of, host_workers, worker_address

RENDER_LOCK = threading.Lock()  # one Blender scene per process, whatever the worker's thread count
_WARM: list[bool] = [False]  # this process has done its warm-up work


def real_bpy_first() -> None:
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


def warm_up(work: Callable[[Path, int], None], host_workers: dict[str, int] | None = None, threads: int = 0,
            slot: int | None = None) -> dict:
    """work(temp_dir, threads) once in this process: {"warm_s": seconds, "worker", "cpus"} or {"error", "worker"}.

    With `slot` (its index among the workers on its machine) the process is first bound to its share of the
    machine's CPUs ("cpus"; None: not bound, it has them all). threads: what the worker's tasks will use (0: its
    share of the machine's cores).
    """
    if _WARM[0]:
        return {"warm_s": 0.0, "worker": worker_address()}
    t0 = time.perf_counter()
    cpus = None
    try:
        with RENDER_LOCK, tempfile.TemporaryDirectory(prefix="dvsot-warm-up-") as tmp:
            if slot is not None and host_workers:
                cpus = pin_to_share(host_workers, slot)  # before bpy starts its threads
            real_bpy_first()
            work(Path(tmp), threads or (threads_for_this_worker(host_workers) if host_workers else 0))
    except Exception as exc:  # a worker that cannot warm up says so in each task's own error
        return {"error": exception_line(exc, 300), "worker": worker_address()}
    _WARM[0] = True
    return {"warm_s": round(time.perf_counter() - t0, 3), "worker": worker_address(), "cpus": cpus}


def warm_workers(client, work: Callable[[Path, int], None], threads: int = 0,
                 timeout_s: float = 300.0) -> list[dict]:
    """warm_up(work) once on every worker the scheduler knows now (each bound to its share), waiting at most
    timeout_s (seconds); one result per worker. Workers that join later pay these costs in their first task."""
    import uuid

    from distributed import wait

    hosts, run = host_workers(client), uuid.uuid4().hex[:8]
    addresses = sorted(client.scheduler_info(n_workers=-1)["workers"])
    slots = {w: sum(1 for v in addresses[:k] if host_of(v) == host_of(w))
             for k, w in enumerate(addresses)}  # each worker's index among those on its machine
    futures = [client.submit(warm_up, work, hosts, threads, slots[w], pure=False, key=f"warm-up-{run}-{k}",
                             workers=[w], allow_other_workers=False)
               for k, w in enumerate(addresses)]
    try:
        wait(futures, timeout=timeout_s)
    except TimeoutError:
        pass  # a slow worker goes on warming; its tasks wait for it
    out = [f.result() if f.status == "finished" else {"error": f"warm-up {f.status}"} for f in futures]
    for f in futures:
        f.release()
    return out
