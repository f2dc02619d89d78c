"""Tasks on Dask: a LocalCluster (`local:N`) or a running cluster (`tcp://HOST:PORT`), results taken as they finish.

One loop serves every command that runs on a cluster (`dvsot generate`, `dvsot bench`, benchmarks.experiments.ablation):
`run_tasks` submits one task per call, takes each result as it completes (`as_completed`), records a failure
(the task raised, returned a failure, or its worker died) as one line and resubmits it, on a worker not yet
tried while there is one, up to `retries` times, while the other tasks go on.

`TaskRunner(None)` runs the same calls in this process, in order, under the same failure and retry rules
(`run_here`), so a command has one path whether or not it has a cluster.

`local:N` runs N worker processes of this process (dvsot.runtime.local_workers: they die with it and stop quietly);
`generate --jobs N` and `bench --jobs N` are `local:N`. A run whose tasks write files holds a lease in its
output directory (dvsot.runtime.staging.RunLease): when the run stops here (an interrupt, an error), the lease is
revoked before anything is reported, so no task of it commits afterwards, and its queued tasks are cancelled.
"""

from __future__ import annotations

import logging
import os
import uuid
import weakref
from collections.abc import Callable
from contextlib import ExitStack
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from dvsot.core.bounds import MAX_WORKERS
from dvsot.core.errors import RunError, UserError, exception_line


@dataclass(frozen=True)
class Failure:
    """A task that did not give a result: its one-line error and the worker it ran on (None if unknown)."""

    error: str
    worker: str | None = None
    kind: str | None = None  # "user" (bad input, dvsot.core.errors.UserError), "run" (RunError), "interrupted", None
    message: str | None = None  # a UserError's or RunError's own message, raised again as such here


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


_LOCAL: weakref.WeakSet = weakref.WeakSet()  # clients of local:N clusters: their workers share this machine


def lease_home(client, lease_dir: str | os.PathLike) -> Path:
    """Where a run's lease goes: this machine's temp directory for local:N (a killed run leaves nothing in the
    output directory), else `lease_dir`, which every worker sees at the same path."""
    if client in _LOCAL:
        import tempfile

        from dvsot.runtime.staging import clean_stale

        home = Path(tempfile.gettempdir()) / "dvsot-runs"
        home.mkdir(mode=0o700, exist_ok=True)
        clean_stale(home)  # leases of killed runs
        return home
    return Path(lease_dir)


class Cluster:
    """`with Cluster(spec) as client`: a Client on a new local scheduler with N single-threaded worker processes
    of this process (local:N, all ended at the end) or on a running scheduler (tcp://HOST:PORT)."""

    def __init__(self, spec: str, start_timeout_s: float = 120.0) -> None:
        self.spec = spec
        self.kind, self.arg = parse_scheduler(spec)
        self.start_timeout_s = start_timeout_s
        self.cluster = self.client = None
        self.procs: list = []

    def __enter__(self):
        from distributed import Client

        if self.kind == "local":
            try:
                self._start_local()
            except BaseException as exc:
                self.__exit__(None, None, None)
                if isinstance(exc, (RuntimeError, OSError, TimeoutError)):
                    raise RunError(f"scheduler local:{self.arg}: the worker processes did not start "
                                   f"({exception_line(exc, 300)})") from None
                raise
        else:
            try:
                self.client = Client(self.arg, timeout="20s")
            except (OSError, TimeoutError) as exc:
                raise UserError(f"scheduler {self.arg}: cannot reach the scheduler "
                                 f"({exception_line(exc, 300)})") from None
        return self.client

    def _start_local(self) -> None:
        from distributed import Client, LocalCluster

        from dvsot.runtime import local_workers

        local_workers.quiet_logs()
        # the scheduler here, no workers of its own: they are this process's children (dvsot.runtime.local_workers)
        self.cluster = LocalCluster(n_workers=0, processes=True, host="127.0.0.1", scheduler_port=0,
                                    dashboard_address=None, silence_logs=logging.CRITICAL,
                                    # its HTTP server (health, metrics) on a free port: 8787 may be another's
                                    scheduler_kwargs={"dashboard_address": "127.0.0.1:0"})
        self.client = Client(self.cluster)
        _LOCAL.add(self.client)
        self.procs = local_workers.start(self.cluster.scheduler_address, self.arg)
        try:
            self.client.wait_for_workers(self.arg, timeout=self.start_timeout_s)
        except TimeoutError:
            dead = [p.returncode for p in self.procs if p.poll() is not None]
            raise RuntimeError(f"{len(workers(self.client))} of {self.arg} joined in {self.start_timeout_s:g} s"
                               + (f"; {len(dead)} exited (status {dead[0]})" if dead else "")) from None

    def __exit__(self, *exc) -> None:
        from dvsot.runtime import local_workers

        try:
            if self.client is not None:
                self.client.close()
        finally:
            local_workers.stop(self.procs)  # each running task unwinds (temps removed) before its process exits
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


def _guarded(lease: str | None, fn: Callable, *args) -> Any:
    """fn(*args) in a worker, under its run's lease if it has one (dvsot.runtime.staging.LeaseGuard); an exception, an
    interrupt included, comes back as a Failure (no traceback in the worker's log)."""
    from dvsot.core.errors import RunError
    from dvsot.runtime import interrupts, local_workers
    from dvsot.runtime.staging import LeaseGuard

    guard = LeaseGuard(lease) if lease is not None else None
    local_workers.task_started()
    try:
        with interrupts.guarded(guard):
            interrupts.check()  # a run stopped before this task began: nothing to do
            return fn(*args)
    except interrupts.Interrupted as exc:
        return Failure(f"interrupted ({exc.why})", worker_address(), "interrupted")
    except Exception as exc:
        kind = "user" if isinstance(exc, UserError) else "run" if isinstance(exc, RunError) else None
        return Failure(exception_line(exc, 300), worker_address(), kind, str(exc) if kind else None)
    finally:
        if guard is not None:
            guard.close()
        local_workers.task_ended()


def _failure_of(result: Any) -> Failure | None:
    return result if isinstance(result, Failure) else None


def run_tasks(client, fn: Callable, calls: list[tuple], retries: int = 0,
              on_result: Callable[[int, Any], None] | None = None,
              on_failure: Callable[[int, Failure, bool], None] | None = None,
              failure_of: Callable[[Any], Failure | None] = _failure_of,
              stop_on_failure: bool = False, name: str = "task", where: str = "",
              lease_dir: str | os.PathLike | None = None) -> list:
    """fn(*calls[k]) for every k, one Dask task each; results in call order, a Failure where a call finally failed.

    Results are taken as they finish: on_result(k, result) for a success, on_failure(k, failure, final) for a
    failed attempt (failure_of(result) says whether a returned result is one). A failed call is resubmitted,
    preferring a worker it has not run on, until it has failed retries + 1 times. stop_on_failure: the first
    failure cancels every other task and is raised as one line (naming `where`, else the scheduler): the task's
    own UserError or RunError, else a RunError.
    lease_dir: the directory the tasks write into (the same path on every worker): the run's lease goes there
    (on local:N, in this machine's temp directory), and once this call ends, by an exception (an interrupt included) or
    not, no task of it commits anything.
    """
    from dvsot.runtime.staging import RunLease

    lease = RunLease(lease_home(client, lease_dir)) if lease_dir is not None else None
    pending: dict = {}
    try:
        return _run_tasks(client, fn, calls, retries, on_result, on_failure, failure_of, stop_on_failure, name,
                          where, str(lease.path) if lease else None, pending)
    finally:
        from dvsot.runtime import interrupts

        with interrupts.deferred():  # a second Ctrl-C waits: the lease must go, whatever comes next
            if lease is not None:
                lease.revoke()
            if pending:
                try:
                    client.cancel([f for _, _, f in pending.values()], force=True)
                except Exception:  # a scheduler already gone: its workers stop with it
                    pass


def _run_tasks(client, fn, calls, retries, on_result, on_failure, failure_of, stop_on_failure, name, where, lease,
               pending) -> list:
    from distributed import as_completed

    results: list = [None] * len(calls)
    run = uuid.uuid4().hex[:8]  # keys unique across runs on one long-lived cluster
    tried: list[set] = [set() for _ in calls]
    done = as_completed()

    def submit(k: int, attempt: int) -> None:
        others = [w for w in workers(client) if w not in tried[k]] if tried[k] else []
        # a strict restriction to the untried workers (a loose one lands wherever is free first)
        fut = client.submit(_guarded, lease, fn, *calls[k], pure=False, key=f"{name}-{run}-{k}-{attempt}",
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
            if failure.kind == "user":
                raise UserError(failure.message or failure.error)
            raise RunError(failure.message if failure.kind == "run" and failure.message else
                           f"{name} {k + 1} of {len(calls)} failed on {where or client.scheduler.address}: "
                           f"{failure.error}")
        final = attempt > retries
        if on_failure is not None:
            on_failure(k, failure, final)
        if not final:
            if failure.worker:
                tried[k].add(failure.worker)
            submit(k, attempt + 1)
    return results


def run_here(fn: Callable, calls: list[tuple], retries: int = 0,
             on_result: Callable[[int, Any], None] | None = None,
             on_failure: Callable[[int, Failure, bool], None] | None = None,
             failure_of: Callable[[Any], Failure | None] = _failure_of,
             stop_on_failure: bool = False, name: str = "task", **_: Any) -> list:
    """fn(*calls[k]) for every k in this process, in order, under run_tasks' rules; results in call order.

    A failed call (it raised an Exception, or failure_of says its result is one) is tried again here until it
    has failed retries + 1 times; an interrupt is not a failure and ends the run. stop_on_failure: the first
    failure is raised (the call's own UserError or RunError, else a RunError of one line). run_tasks' `where` and
    `lease_dir` do not apply: this process's own interrupt stops its writes.
    """
    results: list = []
    for k, call in enumerate(calls):
        for attempt in range(1, retries + 2):
            try:
                result = fn(*call)
                failure = failure_of(result)
            except Exception as exc:  # as _guarded does in a worker: one line, not a traceback
                if stop_on_failure and isinstance(exc, (UserError, RunError)):
                    raise
                kind = "user" if isinstance(exc, UserError) else "run" if isinstance(exc, RunError) else None
                result = failure = Failure(exception_line(exc, 300), worker_address(), kind,
                                           str(exc) if kind else None)
            if failure is None:
                if on_result is not None:
                    on_result(k, result)
                break
            if stop_on_failure:
                if failure.kind == "user":
                    raise UserError(failure.message or failure.error)
                raise RunError(failure.message if failure.kind == "run" and failure.message else
                               f"{name} {k + 1} of {len(calls)} failed here: {failure.error}")
            final = attempt > retries
            if on_failure is not None:
                on_failure(k, failure, final)
            if final:
                break
        results.append(result)
    return results


class TaskRunner:
    """`with TaskRunner(scheduler) as runner`: runner.run(fn, calls, ...) runs calls as tasks on a cluster
    (local:N or tcp://HOST:PORT, run_tasks) or, with scheduler None, in this process (run_here), under the same
    failure, retry and result rules; runner.client is the cluster's client (None here)."""

    def __init__(self, scheduler: str | None) -> None:
        self.scheduler = scheduler
        self.cluster = Cluster(scheduler) if scheduler is not None else None
        self.client = None
        self._stack: ExitStack | None = None

    def __enter__(self) -> TaskRunner:
        from dvsot.runtime import interrupts

        with ExitStack() as stack:
            # the manifest written before the run (and after each task) is its progress, not the command's end: a
            # signal while the cluster starts or the tasks run stops the run, and its lease, at once
            stack.enter_context(interrupts.going_on())
            if self.cluster is not None:
                self.client = stack.enter_context(self.cluster)
            self._stack = stack.pop_all()
        return self

    def __exit__(self, *exc) -> None:
        stack, self._stack = self._stack, None
        if stack is not None:
            stack.__exit__(*exc)

    def hosts(self) -> dict[str, int] | None:
        """{host: number of workers on it} on a cluster (host_workers), None in this process."""
        return host_workers(self.client) if self.client is not None else None

    def run(self, fn: Callable, calls: list[tuple], retries: int = 0, **kw: Any) -> list:
        """fn(*call) for every call (run_tasks' keywords: on_result, on_failure, failure_of, stop_on_failure,
        name, where, lease_dir); results in call order, a Failure where a call finally failed."""
        if self.client is None:
            return run_here(fn, calls, retries, **kw)
        return run_tasks(self.client, fn, calls, retries, **kw)


def map_tasks(scheduler: str | None, fn: Callable, calls: list[tuple],
              on_result: Callable[[int, Any], None] | None = None,
              lease_dir: str | os.PathLike | None = None) -> list:
    """fn(*call) for every call on a new client of `scheduler` (local:N or tcp://HOST:PORT; None: in this process,
    in order); results in call order.

    Results are taken as they finish (on_result(k, result) for each); a task that raised, or whose worker
    died, is one line (its UserError or RunError as such, else a RunError) and the rest are cancelled.
    lease_dir: where the tasks write, if they do (run_tasks).
    """
    with TaskRunner(scheduler) as runner:
        return runner.run(fn, calls, on_result=on_result, stop_on_failure=True, name="task",
                          where=scheduler or "", lease_dir=lease_dir)
