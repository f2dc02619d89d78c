"""SIGINT and SIGTERM as one exception (`Interrupted`), raised where it is safe: at once, or deferred past a block.

Blender's Python callbacks swallow exceptions: a KeyboardInterrupt raised inside a Cycles render is
printed and the render carries on. Inside `deferred()` the handler only records the signal; `check()`
(called between frames) and the block's end raise it. A worker process also treats the death of its
parent as an interrupt (`set_parent`), and a task of a run whose parent has stopped it (`guarded`: the run's
lease, dvsot.runtime.staging.RunLease) as one too, so that `check()` and every commit refuse to go on.

Committed: once a command's commit (dvsot.runtime.outputs) starts renaming its outputs in the main process, those
outputs are in place; a signal from then on is recorded as late (`late()`) and interrupts nothing, until the command
goes on with other work (`check()`, or a new output staged: `resume()`), where it stops the run as any signal does.
Inside `going_on()` (a command's tasks being run and waited for) a commit is the run's progress (a manifest rewritten
after each task), not its end: a signal there stops the run at once.
A second signal after a commit is raised at once. The command line reports a late signal and exits 0. In the
`dvsot` process itself (`at_startup`), a signal before the command line's handlers are in place ends the process
with one line, and one after the command has finished (interpreter exit, Blender's clean-up) is only recorded.
"""

from __future__ import annotations

import os
import signal
import sys
import threading
from collections.abc import Iterator
from contextlib import AbstractContextManager, contextmanager, nullcontext
from contextvars import ContextVar
from typing import Protocol

SIGNALS = (signal.SIGINT, signal.SIGTERM)


class Interrupted(KeyboardInterrupt):
    """The run was stopped by a signal; `exit_status` is 128 + its number (130 for SIGINT, 143 for SIGTERM)."""

    def __init__(self, signum: int, why: str | None = None) -> None:
        self.signum = int(signum)
        self.why = why or signal.Signals(self.signum).name
        super().__init__(self.why)

    @property
    def exit_status(self) -> int:
        return 128 + self.signum


def interruption(exc: BaseException) -> KeyboardInterrupt | None:
    """The interrupt behind an exception, if any: itself, or one its causes and contexts chain back to.

    A signal handled while compiled code calls back into Python (numba's dispatcher unpickling a constant)
    comes out of that call as a SystemError whose cause is the Interrupted: still an interrupt.
    """
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return exc
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return None


_state = {"depth": 0, "pending": None, "parent": None, "raised": None, "seen": None, "last": False,
          "finished": False, "late": None, "installed": False, "going_on": 0}


def _handler(signum: int, frame) -> None:
    if _state["finished"] and (not _state["late"] or _state["depth"]):  # a commit's renames have begun: late
        _state["late"] = _state["late"] or signum
        return
    if _state["finished"]:  # a second signal after the commit (its renames done): the user wants the process to stop
        _state["finished"] = False
        _state["late"] = None
    _state["seen"] = _state["seen"] or signum
    if _state["depth"]:
        _state["pending"] = _state["pending"] or signum  # the first one wins; raised at check() or the block's end
        return
    # kept too: raised inside a weakref callback or a __del__, the exception is printed and dropped, and the
    # run would go on to replace its outputs; check() (before every commit) raises it again
    _state["raised"] = _state["raised"] or signum
    raise Interrupted(signum)


def install() -> list:
    """Make SIGINT and SIGTERM raise `Interrupted` (main thread only); the previous handlers, for `restore`."""
    if threading.current_thread() is not threading.main_thread():
        return []
    _reset()  # a new run: an earlier one's interrupt was its own
    saved = [(s, signal.getsignal(s)) for s in SIGNALS]
    for s in SIGNALS:
        signal.signal(s, _handler)
    saved.append(("unraisable", sys.unraisablehook))
    sys.unraisablehook = _unraisable
    _state["installed"] = True
    return saved


def _reset() -> None:
    _state.update(raised=None, seen=None, last=False, finished=False, late=None, installed=False)


def seen() -> int | None:
    """The first signal this run received and raised (whatever exception it turned into on its way), else None."""
    return _state["seen"]


def stopped_status(caught: BaseException, prog: str) -> int | None:
    """The exit status of a run that `caught` ended because of a signal, its one line printed on stderr; None when
    `caught` is an exception of the run's own (the caller re-raises it)."""
    exc = interruption(caught)
    if exc is None and seen():
        # a signal inside a library (an extension module's import, a callback) that came out as that library's own
        # error, its cause dropped (pyo3's PanicException, "numpy failed to import"): still the signal's
        exc = Interrupted(seen())
    if exc is None:
        return None
    why = exc.why if isinstance(exc, Interrupted) else "SIGINT"
    print(f"{prog}: interrupted ({why})", file=sys.stderr)
    return exc.exit_status if isinstance(exc, Interrupted) else 130


@contextmanager
def last_step() -> Iterator[None]:
    """The block is the command's last step: once its final commit starts renaming (`finish`), the run has completed,
    and a signal from then on is reported as late (`late()`) instead of interrupting it."""
    _state["last"] = True
    try:
        yield
    finally:
        _state["last"] = False


def finish() -> None:
    """Called as a commit starts its renames: in a command's main thread (not a task's), its outputs are committed."""
    own = _state["installed"] and threading.current_thread() is threading.main_thread() and _guard.get() is None
    if (_state["last"] or own) and not _state["going_on"]:
        _state["finished"] = True


def committed() -> bool:
    """Whether the last thing the command did was to commit its outputs (a signal now is late)."""
    return _state["finished"]


def resume() -> None:
    """The command goes on after a commit (new outputs staged, a next step): a late signal stops it here."""
    if _state["finished"] and not _state["last"]:
        _state["finished"] = False
        signum, _state["late"] = _state["late"], None
        if signum:
            raise Interrupted(signum)


@contextmanager
def going_on() -> Iterator[None]:
    """The block is more work after a commit (tasks started, run and waited for): a late signal stops it at entry,
    and a commit inside it (the run's progress) never counts as the command's last, so a signal stops the block."""
    resume()
    _state["going_on"] += 1
    try:
        yield
    finally:
        _state["going_on"] -= 1


def late() -> int | None:
    """A signal that arrived after the command's last commit had begun renaming (the run completed), else None."""
    return _state["late"]


def _startup_handler(signum: int, frame) -> None:
    os.write(2, f"dvsot: interrupted ({signal.Signals(signum).name})\n".encode())
    os._exit(128 + signum)  # nothing has started: no output to clean up, no traceback of a half-done import


def _ignore_at_teardown() -> None:
    """The last exit handler: the interpreter's finalisation puts SIG_DFL back for every signal with a Python handler,
    and native clean-up (Blender's) runs after it; an ignored signal stays ignored, so the decided status stands."""
    if _state.get("after"):
        for s in SIGNALS:
            signal.signal(s, signal.SIG_IGN)


def at_startup() -> None:
    """In the `dvsot` process, before its imports: a signal ends it with one line until `install()` takes over."""
    if threading.current_thread() is threading.main_thread():
        import atexit

        for s in SIGNALS:
            signal.signal(s, _startup_handler)
        _state["command"] = True
        atexit.register(_ignore_at_teardown)  # registered first, so run last


def is_command() -> bool:
    """Whether this process is the `dvsot` command (`at_startup` ran), not a library user or a test."""
    return bool(_state.get("command"))


def after_command(prog: str, status: int) -> None:
    """In the `dvsot` process once its command has returned `status`: a signal while the interpreter exits (Blender's
    clean-up) changes nothing: after a success it is noted in one line, otherwise only recorded; the status stands."""

    def handler(signum: int, frame) -> None:
        if status == 0:
            os.write(2, f"{prog}: done; {signal.Signals(signum).name} arrived after its outputs were written\n"
                     .encode())

    if threading.current_thread() is threading.main_thread():
        for s in SIGNALS:
            signal.signal(s, handler)
        sys.unraisablehook = lambda info: None
        _state["after"] = True


def quiet_exit() -> None:
    """After a run was reported interrupted: what libraries' clean-up raises as the process ends (a half-written
    video writer's __del__, an atexit callback) is the interrupt's consequence, not printed."""
    sys.unraisablehook = lambda info: None


def _unraisable(info) -> None:
    """sys.unraisablehook: an Interrupted dropped in a callback is kept for check(), not printed; others as before."""
    if isinstance(info.exc_value, Interrupted):
        return
    sys.__unraisablehook__(info)


def restore(saved: list) -> None:
    """Put back the handlers `install` replaced."""
    for s, h in saved:
        if s == "unraisable":
            sys.unraisablehook = h
        else:
            signal.signal(s, h if h is not None else signal.SIG_DFL)
    _reset()


def set_parent(pid: int) -> None:
    """In a worker: the parent's pid; once the worker is re-parented, `check()` raises."""
    _state["parent"] = int(pid)


def parent_gone() -> bool:
    """Whether this is a worker whose parent has died."""
    return _state["parent"] is not None and os.getppid() != _state["parent"]


def note(signum: int) -> None:
    """Record a signal for the next `check()` without raising (a handler that must not unwind its own thread)."""
    _state["raised"] = _state["raised"] or int(signum)


class Guard(Protocol):
    """What a task checks before each step and around each commit: whether its run still wants it."""

    def problem(self) -> str | None: ...

    def committing(self) -> AbstractContextManager[None]: ...


_guard: ContextVar[Guard | None] = ContextVar("dvsot_run_guard", default=None)


@contextmanager
def guarded(guard: Guard | None) -> Iterator[None]:
    """Inside the block (one task), `check()` also raises once `guard` reports a problem (its run was stopped)."""
    token = _guard.set(guard)
    try:
        yield
    finally:
        _guard.reset(token)


def committing() -> AbstractContextManager[None]:
    """Around a commit's renames: the guard of this task's run held (its parent cannot stop the run meanwhile)."""
    guard = _guard.get()
    return guard.committing() if guard is not None else nullcontext()


def check() -> None:
    """Raise `Interrupted` if a signal arrived during a deferred block or was raised and swallowed, this
    worker's parent died, or the run of this task was stopped; after a commit, the work goes on (`resume`)."""
    _check_recorded()
    resume()


def _check_recorded() -> None:
    pending = _state["pending"] or _state["raised"]
    if pending:
        _state["pending"] = _state["raised"] = None
        raise Interrupted(pending)
    if parent_gone():
        raise Interrupted(signal.SIGTERM, "parent process died")
    guard = _guard.get()
    if guard is not None:
        why = guard.problem()
        if why is not None:
            raise Interrupted(signal.SIGTERM, why)


@contextmanager
def deferred() -> Iterator[None]:
    """Within the block, SIGINT/SIGTERM are recorded, not raised; raised by `check()` or when the block ends."""
    main = threading.current_thread() is threading.main_thread()
    saved = [signal.getsignal(s) for s in SIGNALS] if main and _state["depth"] == 0 else None
    if saved is not None:
        for s in SIGNALS:
            signal.signal(s, _handler)
    _state["depth"] += 1
    try:
        yield
    finally:
        _state["depth"] -= 1
        if saved is not None:
            for s, h in zip(SIGNALS, saved):
                signal.signal(s, h)
        if _state["depth"] == 0:
            _check_recorded()  # raises the recorded signal (over any exception it caused inside the block)
