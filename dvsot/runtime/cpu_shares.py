"""Worker processes' shares of their machine's CPUs: which CPUs a worker gets, binding it to them, its thread count.

Why bind: Blender's task scheduler (oneTBB) starts a thread per CPU it may use and keeps them spinning in
sched_yield between tasks, so a worker rendering on one thread also keeps its other CPUs busy, and workers
on one machine slow each other down: bound to its share, each competes only with itself.
"""

from __future__ import annotations

import os

BOUND: list[int] = []  # the CPUs this worker process is bound to (empty: not bound)


def this_host() -> str | None:
    """The machine part of this Dask worker's address, or None outside a worker."""
    from dvsot.runtime.dask_tasks import host_of

    try:
        from distributed import get_worker

        return host_of(get_worker().address)
    except (ImportError, ValueError):
        return None


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


def pin_to_share(host_workers: dict[str, int], slot: int) -> list[int] | None:
    """Bind this worker process to its share of its machine's CPUs (slot among the workers there); the CPUs or None.

    Call it before a library starts its threads (bpy): threads started later inherit the binding.
    """
    host = this_host()
    if host is None or not hasattr(os, "sched_setaffinity") or not os.path.isdir("/proc/self/task"):
        return None
    cpus = cpu_share(sorted(os.sched_getaffinity(0)), slot, host_workers.get(host, 1))
    if cpus is None:
        return None
    pin_process(cpus)
    BOUND[:] = sorted(cpus)
    return list(BOUND)


def threads_for_this_worker(host_workers: dict[str, int]) -> int:
    """Threads for a worker process: its bound CPUs, else this machine's cores shared among its workers."""
    if BOUND:
        return len(BOUND)
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    host = this_host()
    return cores if host is None else max(1, cores // max(1, host_workers.get(host, 1)))
