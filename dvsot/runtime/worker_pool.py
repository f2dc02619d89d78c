"""Worker processes that die with their parent: a spawn process pool for `generate --jobs` and `bench --jobs`.

Each worker asks the kernel for SIGTERM when its parent dies (Linux prctl PR_SET_PDEATHSIG), handles
SIGINT/SIGTERM like the command line does (its outputs are aborted, never renamed into place) and
then exits at once. The parent, on any exception (an interrupt included), cancels what is queued and
stops the workers before it returns.
"""

from __future__ import annotations

import ctypes
import os
import signal
import sys
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from multiprocessing import get_context
from typing import Any, Callable, Iterable

from dvsot.runtime import interrupts
from dvsot.errors import RunError

_PR_SET_PDEATHSIG = 1
_in_task = [False]


def _die_with_parent(parent: int) -> None:
    """Ask Linux to send SIGTERM when the parent dies; exit now if it already has."""
    if sys.platform.startswith("linux"):
        try:
            ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGTERM, 0, 0, 0)
        except (OSError, AttributeError):
            pass  # no prctl: parent_gone() below and before every commit still applies
    if os.getppid() != parent:
        os._exit(128 + signal.SIGTERM)


def _worker_signal(signum: int, frame) -> None:
    if not _in_task[0]:
        os._exit(128 + signum)  # idle: nothing to clean up
    interrupts._handler(signum, frame)  # raise Interrupted (or record it inside a Blender render)


def _init_worker(parent: int) -> None:
    interrupts.set_parent(parent)
    _die_with_parent(parent)
    for s in interrupts.SIGNALS:
        signal.signal(s, _worker_signal)


def _guarded(fn: Callable, *args: Any) -> Any:
    """Run one task; an interrupt unwinds it (its temps removed), then the worker exits without a word."""
    _in_task[0] = True
    try:
        interrupts.check()
        return fn(*args)
    except interrupts.Interrupted as exc:
        os._exit(exc.exit_status)
    finally:
        _in_task[0] = False


class WorkerPool:
    """A spawn ProcessPoolExecutor whose workers die with the parent; on an exception the workers are stopped."""

    def __init__(self, workers: int) -> None:
        self._pool = ProcessPoolExecutor(workers, mp_context=get_context("spawn"), initializer=_init_worker,
                                         initargs=(os.getpid(),))

    def submit(self, fn: Callable, *args: Any) -> Future:
        """Queue fn(*args) (both picklable) for a worker."""
        return self._pool.submit(_guarded, fn, *args)

    def map(self, fn: Callable, *iterables: Iterable) -> list:
        """fn over the iterables in the workers; results in order. A dead worker is one RunError line."""
        futures = [self.submit(fn, *a) for a in zip(*iterables)]
        return [result(f) for f in futures]

    def stop(self) -> None:
        """Cancel queued tasks and end every worker (SIGTERM, then SIGKILL after 10 s)."""
        procs = list((getattr(self._pool, "_processes", None) or {}).values())
        self._pool.shutdown(wait=False, cancel_futures=True)
        for p in procs:
            if p.is_alive():
                p.terminate()
        for p in procs:
            p.join(10)
            if p.is_alive():
                p.kill()
                p.join(1)

    def __enter__(self) -> "WorkerPool":
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            self._pool.shutdown(wait=True)
        else:
            self.stop()


def result(future: Future) -> Any:
    """A task's result; a worker that died (killed, out of memory) is one RunError line."""
    try:
        return future.result()
    except BrokenProcessPool:
        interrupts.check()  # the parent's own interrupt explains it, if there was one
        raise RunError("a worker process died before finishing its task (killed, or out of memory?)") from None
