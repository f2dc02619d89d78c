"""Tasks on Dask: a LocalCluster (`local:N`) or a running cluster (`tcp://HOST:PORT`), results taken as they finish.

One loop serves every command that runs on a cluster (`dvsot generate`, `dvsot bench`, benchmarks.ablation):
`run_tasks` submits one task per call, takes each result as it completes (`as_completed`), records a failure
(the task raised, returned a failure, or its worker died) as one line and resubmits it, on a worker not yet
tried while there is one, up to `retries` times, while the other tasks go on.
"""

from __future__ import annotations

import logging
import os
import uuid
from dataclasses import dataclass
from typing import Any, Callable

from dvsot.errors import RunError, UserError, exception_line
from dvsot.validate import MAX_WORKERS


@dataclass(frozen=True)
class Failure:
    """A task that did not give a result: its one-line error and the worker it ran on (None if unknown)."""

    error: str
    worker: str | None = None


def parse_scheduler(spec: str, label: str = "scheduler") -> tuple[str, int | str]:
    """('local', N) for local:N, ('address', spec) for tcp://HOST:PORT (or tls://, ws://, wss://); UserError else.

    label: how the message names the setting (a command passes its flag)."""
    if spec.startswith("local:"):
        n = spec.removeprefix("local:")
        if not n.isdigit() or not 1 <= int(n) <= MAX_WORKERS:
            raise UserError(f"{label} local:N needs N, a number of worker processes in 1..{MAX_WORKERS} (the bound), "
                            f"got {spec!r}")
        return "local", int(n)
    scheme, _, rest = spec.partition("://")
    host, _, port = rest.rpartition(":")
    if scheme not in ("tcp", "tls", "ws", "wss") or not host or not port.isdigit():
        raise UserError(f"{label} must be local:N or tcp://HOST:PORT, got {spec!r}")
    if not 1 <= int(port) <= 65535:
        raise UserError(f"{label} {spec!r}: port {int(port)} is not a TCP port (1..65535)")
    return "address", spec


def worker_address() -> str:
    """The Dask worker this code runs in (its address), or this process's pid outside a worker."""
    try:
        from distributed import get_worker

        return get_worker().address
    except (ImportError, ValueError):
        return f"pid {os.getpid()}"


class Cluster:
    """`with Cluster(spec) as client`: a Client on a new LocalCluster of single-threaded worker processes
    (local:N, closed at the end) or on a running scheduler (tcp://HOST:PORT)."""

    def __init__(self, spec: str) -> None:
        self.spec = spec
        self.kind, self.arg = parse_scheduler(spec)
        self.cluster = self.client = None

    def __enter__(self):
        from distributed import Client, LocalCluster

        if self.kind == "local":
            try:
                self.cluster = LocalCluster(n_workers=self.arg, threads_per_worker=1, processes=True,
                                            dashboard_address=None,
                                            silence_logs=logging.CRITICAL)  # failures are reported, one line each
            except (RuntimeError, OSError, TimeoutError) as exc:
                raise RunError(f"scheduler local:{self.arg}: the worker processes did not start "
                               f"({exception_line(exc, 300)})") from None
            self.client = Client(self.cluster)
        else:
            try:
                self.client = Client(self.arg, timeout="20s")
            except (OSError, TimeoutError) as exc:
                raise UserError(f"scheduler {self.arg}: cannot reach the scheduler "
                                f"({exception_line(exc, 300)})") from None
        return self.client

    def __exit__(self, *exc) -> None:
        if self.client is not None:
            self.client.close()
        if self.cluster is not None:
            self.cluster.close()


def workers(client) -> list[str]:
    """Addresses of the workers the scheduler knows now."""
    return list(client.scheduler_info(n_workers=-1)["workers"])


def host_of(address: str) -> str:
    """The machine part of a worker address: the address without its port."""
    return address.rpartition(":")[0]


def host_workers(client) -> dict[str, int]:
    """{host: number of workers on it} (host_of each worker's address)."""
    counts: dict[str, int] = {}
    for address in workers(client):
        host = host_of(address)
        counts[host] = counts.get(host, 0) + 1
    return counts


def _guarded(fn: Callable, *args) -> Any:
    """fn(*args) in a worker; an exception comes back as a Failure (no traceback in the worker's log)."""
    try:
        return fn(*args)
    except Exception as exc:
        return Failure(exception_line(exc, 300), worker_address())


def _failure_of(result: Any) -> Failure | None:
    return result if isinstance(result, Failure) else None


def run_tasks(client, fn: Callable, calls: list[tuple], retries: int = 0,
              on_result: Callable[[int, Any], None] | None = None,
              on_failure: Callable[[int, Failure, bool], None] | None = None,
              failure_of: Callable[[Any], Failure | None] = _failure_of,
              stop_on_failure: bool = False, name: str = "task", where: str = "") -> list:
    """fn(*calls[k]) for every k, one Dask task each; results in call order, a Failure where a call finally failed.

    Results are taken as they finish: on_result(k, result) for a success, on_failure(k, failure, final) for a
    failed attempt (failure_of(result) says whether a returned result is one). A failed call is resubmitted,
    preferring a worker it has not run on, until it has failed retries + 1 times. stop_on_failure: the first
    failure cancels every other task and is raised as one RunError line (naming `where`, else the scheduler).
    """
    from distributed import as_completed

    results: list = [None] * len(calls)
    run = uuid.uuid4().hex[:8]  # keys unique across runs on one long-lived cluster
    tried: list[set] = [set() for _ in calls]
    pending: dict = {}
    done = as_completed()

    def submit(k: int, attempt: int) -> None:
        others = [w for w in workers(client) if w not in tried[k]] if tried[k] else []
        # a strict restriction to the untried workers (a loose one lands wherever is free first)
        fut = client.submit(_guarded, fn, *calls[k], pure=False, key=f"{name}-{run}-{k}-{attempt}",
                            workers=others or None)
        pending[fut.key] = (k, attempt, fut)
        done.add(fut)

    for k in range(len(calls)):
        submit(k, 1)
    for fut in done:
        k, attempt, _ = pending.pop(fut.key)
        try:
            result: Any = fut.result()
            failure = failure_of(result)
        except Exception as exc:  # the worker died (KilledWorker), the task could not be sent or unpickled, ...
            result = failure = Failure(exception_line(exc, 300))
        fut.release()
        results[k] = result
        if failure is None:
            if on_result is not None:
                on_result(k, result)
            continue
        if stop_on_failure:
            client.cancel([f for _, _, f in pending.values()])
            raise RunError(f"{name} {k + 1} of {len(calls)} failed on {where or client.scheduler.address}: "
                           f"{failure.error}")
        final = attempt > retries
        if on_failure is not None:
            on_failure(k, failure, final)
        if not final:
            if failure.worker:
                tried[k].add(failure.worker)
            submit(k, attempt + 1)
    return results


def map_tasks(scheduler: str, fn: Callable, calls: list[tuple],
              on_result: Callable[[int, Any], None] | None = None) -> list:
    """fn(*call) for every call on a new client of `scheduler` (local:N or tcp://HOST:PORT); results in call order.

    Results are taken as they finish (on_result(k, result) for each); a task that raised, or whose worker
    died, is one RunError line and the rest are cancelled.
    """
    with Cluster(scheduler) as client:
        return run_tasks(client, fn, calls, on_result=on_result, stop_on_failure=True, name="task", where=scheduler)
