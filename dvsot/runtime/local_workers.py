"""The worker processes of `local:N`: Dask workers started by this process, that die with it and stop quietly.

Each worker is a child of the process that runs the scheduler (started from its main thread, so the kernel
ends it with SIGTERM when that process dies: Linux prctl PR_SET_PDEATHSIG). A worker ignores SIGINT (a
Ctrl-C reaches the whole process group; the parent stops the run) and takes SIGTERM as an interrupt of its
running task: `dvsot.runtime.interrupts.check()` raises in the task at its next step, its temps are removed, and the
process exits (128 + 15) once no task runs. It prints nothing: a task's failure comes back as its result.

Run as `python -m dvsot.runtime.local_workers SCHEDULER_ADDRESS PARENT_PID NAME`.
"""

from __future__ import annotations

import asyncio
import ctypes
import logging
import os
import signal
import subprocess
import sys
import threading
import time

_PR_SET_PDEATHSIG = 1
_active = [0]  # tasks running in this worker process (dvsot.runtime.dask_tasks counts them)


def die_with_parent(parent: int) -> None:
    """Ask Linux to send SIGTERM when the parent dies; exit now if it already has."""
    if sys.platform.startswith("linux"):
        try:
            ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGTERM, 0, 0, 0)
        except (OSError, AttributeError):
            pass  # no prctl: interrupts.parent_gone() at each step and before every commit still applies
    if os.getppid() != parent:
        os._exit(128 + signal.SIGTERM)


def quiet_logs() -> None:
    """Dask's own log lines off in this process: a local run reports each failure itself, as one line.

    Set on the loggers, not only on their handlers for the cluster's lifetime (LocalCluster's `silence_logs`):
    the event loop thread outlives the cluster, and a comm that closes as the run stops logs its traceback late.
    """
    for logger in ("distributed", "tornado", "asyncio"):
        logging.getLogger(logger).setLevel(logging.CRITICAL)


def task_started() -> None:
    """A task begins in this process."""
    _active[0] += 1


def task_ended() -> None:
    """A task has ended (returned or unwound) in this process."""
    _active[0] -= 1


def _exit_when_idle(signum: int) -> None:
    """Exit once no task runs (each unwinds at its next step), at the latest after 30 s."""
    end = time.monotonic() + 30.0
    while _active[0] > 0 and time.monotonic() < end:
        time.sleep(0.02)
    os._exit(128 + signum)


def _on_sigterm(signum: int, frame) -> None:
    from dvsot.runtime import interrupts

    interrupts.note(signum)  # the running task raises it at its next check(), in its own thread
    threading.Thread(target=_exit_when_idle, args=(signum,), daemon=True).start()


async def _serve(address: str, name: str) -> None:
    from distributed import Worker

    async with Worker(address, nthreads=1, name=name, memory_limit=0, death_timeout=60) as worker:
        await worker.finished()


def main(argv: list[str] | None = None) -> int:
    """A worker process's life: bound to its parent, then a Dask worker until its scheduler or parent goes."""
    address, parent, name = (argv if argv is not None else sys.argv[1:])[:3]
    from dvsot.runtime import interrupts

    die_with_parent(int(parent))
    interrupts.set_parent(int(parent))
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, _on_sigterm)
    quiet_logs()
    try:
        asyncio.run(_serve(address, name))
    except Exception:
        return 1
    return 0


def start(address: str, count: int) -> list[subprocess.Popen]:
    """Start `count` worker processes for the scheduler at `address` (call from the main thread)."""
    env = dict(os.environ)
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    env["PYTHONPATH"] = os.pathsep.join([root, *filter(None, [env.get("PYTHONPATH")])])  # this dvsot, also from a tree
    import dask.config

    env["DASK_INTERNAL_INHERIT_CONFIG"] = dask.config.serialize(dask.config.global_config)  # as a Nanny passes it
    return [
        subprocess.Popen(
            [sys.executable, "-m", "dvsot.runtime.local_workers", address, str(os.getpid()), f"local-{k}"],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            env=env,
        )
        for k in range(count)
    ]


def stop(procs: list[subprocess.Popen], timeout_s: float = 30.0) -> None:
    """End the worker processes: SIGTERM (each running task unwinds, its temps removed), SIGKILL after timeout_s."""
    for p in procs:
        if p.poll() is None:
            p.send_signal(signal.SIGTERM)
    end = time.monotonic() + timeout_s
    for p in procs:
        try:
            p.wait(max(0.0, end - time.monotonic()))
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()


if __name__ == "__main__":
    from dvsot.runtime.local_workers import main as _main  # the module's own state (_active), not a copy under __main__

    sys.exit(_main())
