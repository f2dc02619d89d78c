"""Temp names unique across hosts, commit journals, and the clean-up of what dead local processes left behind.

A staged output is `.<name>.tmp~<host>~<pid>~<token><suffix>` beside its target (same file system, so
the rename is atomic; the suffix kept for writers that choose a format by it). A run that commits
several outputs first writes a journal `.<name>.commit~<host>~<pid>~<token>.json` naming every
(staged, final) pair; its presence means "all staged files are complete, the renames are under way".
The next run in that directory (any process on the same host, once that pid is dead) completes the
renames from the journal, then deletes the dead process's other temps.

A run whose tasks commit in other processes (dvsot.runtime.dask_tasks) holds a lease `.run.lease~<host>~<pid>~<token>`
in its output directory: byte 0 locked by the parent while the run is live, byte 1 shared by each worker
while it commits. Stopping the run takes byte 1 exclusively (waiting out commits under way) and removes
the file, so no worker commits after the parent has said the run stopped; a dead parent's lock is gone.
"""

from __future__ import annotations

import errno
import json
import os
import re
import secrets
import shutil
import socket
import stat
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

try:
    import fcntl
except ImportError:  # not POSIX: leases are checked by their file alone
    fcntl = None

_HOST = re.sub(r"[^A-Za-z0-9.-]", "-", socket.gethostname() or "host")[:64] or "host"
_NAME = re.compile(
    r"^\.(?P<base>.+)\.(?P<kind>tmp|commit|old|lease)~(?P<host>[^~/]+)~(?P<pid>\d+)~(?P<token>[0-9a-f]{8})"
    r"(?P<suffix>(?:\.[^.~/]*)*)$"
)  # a writer's own temp of a staged file (faery's <name>.write) too
_LEGACY = re.compile(
    r"^\.(?P<base>.+)\.tmp-(?P<pid>\d+)(?P<suffix>\.[^.~]*)?$"
)  # the temp names of earlier dvsot versions


def host() -> str:
    """This machine's name as used in temp names (characters other than letters, digits, '.', '-' replaced)."""
    return _HOST


def new_token() -> str:
    """Eight random hex digits: a run's token (with host and pid it makes temp names unique across a cluster)."""
    return secrets.token_hex(4)


def temp_name(final: Path, kind: str = "tmp", token: str | None = None, suffix: str | None = None) -> Path:
    """The hidden sibling of `final` of this kind (tmp, commit, old, lease) for this host, process and token."""
    suffix = final.suffix if suffix is None else suffix
    return final.with_name(f".{final.name}.{kind}~{_HOST}~{os.getpid()}~{token or new_token()}{suffix}")


def pid_alive(pid: int) -> bool:
    """Whether a process of this pid exists on this machine (a pid owned by another user counts as alive)."""
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _dead_local(name: str) -> tuple[str, int, str] | None:
    """(kind, pid, token) of a dvsot temp name left by a dead process of this host, else None."""
    m = _NAME.match(name)
    if m:
        if m["host"] != _HOST or pid_alive(int(m["pid"])):
            return None
        return m["kind"], int(m["pid"]), m["token"]
    m = _LEGACY.match(name)  # pid only: taken to be this host's, as dvsot then wrote no host into names
    if m and not pid_alive(int(m["pid"])):
        return "tmp", int(m["pid"]), ""
    return None


def _remove(p: Path) -> None:
    """Remove a staged file or directory, and the temps a writer made of it (`<name>.<anything>`, as faery's .write)."""
    if p.is_dir() and not p.is_symlink():
        shutil.rmtree(p, ignore_errors=True)
    else:
        p.unlink(missing_ok=True)
    try:
        companions = [n for n in os.listdir(p.parent) if n.startswith(p.name + ".")]
    except OSError:
        return
    for n in companions:
        (p.parent / n).unlink(missing_ok=True)


def write_json(path: Path, data: dict, token: str) -> None:
    """Write JSON to path atomically (its own staged temp, flushed to disk, then a rename)."""
    tmp = temp_name(path, token=token)
    try:
        with open(tmp, "w") as f:
            json.dump(data, f, indent=2)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def replace_dir(staged: Path, final: Path, old: Path) -> None:
    """Put the directory `staged` at `final`, moving a directory already there to `old` first (re-runnable)."""
    if staged.exists():
        if final.exists() and not old.exists():
            os.replace(final, old)
        os.replace(staged, final)
    _remove(old)


def is_temp(name: str) -> bool:
    """Whether a file name is one of dvsot's temps (staged files, journals, old directories, leases), any process's."""
    return bool(_NAME.match(name) or _LEGACY.match(name))


def _remove_gone(final: Path, root: Path) -> None:
    """Remove a previous run's file, then the directories it leaves empty up to (not including) root."""
    if final.is_dir() and not final.is_symlink():
        shutil.rmtree(final, ignore_errors=True)
    else:
        final.unlink(missing_ok=True)
    d = final.parent
    while d != root and root in d.parents:
        try:
            os.rmdir(d)
        except OSError:
            return
        d = d.parent


def journal_problem(journal: Path, data: dict) -> str | None:
    """Why a journal's entries are not one run's staged outputs that can complete (a staged name of another run or
    directory, something other than a regular file staged, a directory where a file goes), else None."""
    m = _NAME.match(journal.name)
    token = m["token"] if m else None
    for e in data["entries"]:
        final = Path(e["final"])
        if e["kind"] == "gone":
            continue
        staged = Path(e["staged"])
        n = _NAME.match(staged.name)
        if n is None or n["token"] != token or n["kind"] != "tmp" or staged.parent != final.parent:
            return f"{staged}: not a staged output of the run of {journal.name}"
        if e["kind"] == "file":
            if os.path.lexists(staged) and not stat.S_ISREG(os.lstat(staged).st_mode):
                return f"{staged}: staged for {final.name}, but not a regular file"
            if os.path.isdir(final) and not os.path.islink(final):
                return f"{final}: a directory where the run's file goes"
            if not os.path.lexists(staged) and not os.path.isfile(final):
                return f"{final}: neither staged nor in place"
        elif e["kind"] == "dir" and os.path.lexists(staged) and not os.path.isdir(staged):
            return f"{staged}: staged for the directory {final.name}, but not a directory"
    return None


def discard_journal(journal: Path, data: dict) -> None:
    """Drop a journal that cannot complete: its own staged files not yet renamed and its pointers go, no manifest
    (a staged name of another run, live perhaps, is left alone)."""
    m = _NAME.match(journal.name)
    for e in data.get("entries", []):
        n = _NAME.match(Path(e["staged"]).name) if e.get("staged") and e.get("kind") in ("file", "dir") else None
        if m and n and n["token"] == m["token"] and n["pid"] == m["pid"] and n["kind"] == "tmp":
            _remove(Path(e["staged"]))
    for pointer in data.get("pointers", []):
        Path(pointer).unlink(missing_ok=True)
    journal.unlink(missing_ok=True)


def apply_journal(journal: Path) -> None:
    """Complete the renames a journal names (each one done at most once), the removals of a previous run's files,
    then the manifest, then drop the journal. A journal whose entries are not its run's regular staged files (or
    whose file would replace a directory) is never completed: it is discarded, and ValueError says why."""
    data = json.loads(journal.read_text())
    problem = journal_problem(journal, data)
    if problem:
        discard_journal(journal, data)
        raise ValueError(f"{journal.name}: not completed: {problem}")
    for e in data["entries"]:
        final = Path(e["final"])
        if e["kind"] == "gone":
            _remove_gone(final, Path(e["old"]))
            continue
        staged = Path(e["staged"])
        if e["kind"] == "dir":
            replace_dir(staged, final, Path(e["old"]))
        elif staged.exists():
            os.replace(staged, final)
    for pointer in data.get("pointers", []):
        Path(pointer).unlink(missing_ok=True)
    if data.get("manifest"):
        os.replace(journal, data["manifest"])  # the manifest is the journal, complete: the run's last step
    else:
        journal.unlink(missing_ok=True)


def clean_stale(directory: str | os.PathLike) -> list[Path]:
    """In `directory`: finish the commits of dead local processes, then remove their temps; the paths removed."""
    d = Path(directory)
    try:
        names = os.listdir(d)
    except OSError:
        return []
    dead = {n: k for n in names if (k := _dead_local(n))}
    for name, (kind, _, _) in dead.items():
        if kind == "commit":
            try:
                data = json.loads((d / name).read_text())
                if "journal" in data:  # a pointer to the run's journal in another directory
                    journal = Path(data["journal"])
                    if journal.exists():
                        apply_journal(journal)
                    (d / name).unlink(missing_ok=True)
                else:
                    apply_journal(d / name)
            except (OSError, ValueError, KeyError, TypeError):
                pass  # unreadable (cut short while it was written): its run never started renaming
    removed = []
    for name, (kind, _, _) in dead.items():
        p = d / name
        if kind != "commit" and os.path.lexists(p):
            _remove(p)
            removed.append(p)
    return removed


def _lock(fd: int, how: int, byte: int) -> None:
    """Lock one byte of fd (POSIX record lock, released when the process closes the file or dies)."""
    fcntl.lockf(fd, how, 1, byte)


class RunLease:
    """The parent's side of a run's lease in `directory`: live from creation until `revoke()`."""

    def __init__(self, directory: str | os.PathLike) -> None:
        self.path = temp_name(Path(directory) / "run", "lease", suffix="")
        self._fd: int | None = os.open(self.path, os.O_CREAT | os.O_EXCL | os.O_RDWR, 0o644)
        try:
            os.write(self._fd, b"\0\0")
            if fcntl is not None:
                _lock(self._fd, fcntl.LOCK_EX, 0)
        except BaseException:
            self.revoke()
            raise

    def revoke(self) -> None:
        """End the run: wait for commits under way, then remove the lease; no worker commits for it afterwards."""
        if self._fd is None:
            return
        try:
            if fcntl is not None:
                try:
                    _lock(self._fd, fcntl.LOCK_EX, 1)
                except OSError:
                    pass  # no locks on this file system: the file's removal alone stops the workers
            os.unlink(self.path)
        except FileNotFoundError:
            pass
        finally:
            fd, self._fd = self._fd, None
            os.close(fd)  # releases both locks


class LeaseGuard:
    """A worker's side of a run's lease (an `interrupts.Guard`): the run is live while the lease file stands and
    its parent holds it."""

    def __init__(self, path: str | os.PathLike) -> None:
        self.path = Path(path)
        self._fd: int | None = None
        self._ino: int | None = None
        try:
            self._fd = os.open(self.path, os.O_RDWR)
            self._ino = os.fstat(self._fd).st_ino
        except OSError:
            self._fd = None

    def close(self) -> None:
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None

    def problem(self) -> str | None:
        """None while the run is live; else why it is not (stopped by its parent, or the parent died)."""
        if self._fd is None:
            return "its run was stopped (no lease)"
        try:
            if os.stat(self.path).st_ino != self._ino:
                return "its run was stopped"
        except OSError:
            return "its run was stopped"
        m = _NAME.match(self.path.name)
        if m and m["host"] == _HOST and int(m["pid"]) == os.getpid():
            return None  # the run's own process (its record locks never conflict with themselves): the file decides
        if fcntl is not None:
            try:
                _lock(self._fd, fcntl.LOCK_SH | fcntl.LOCK_NB, 0)
            except OSError as exc:
                if exc.errno in (errno.EAGAIN, errno.EACCES):
                    return None  # the parent holds it: live
                return None  # no locks on this file system: the file decides
            _lock(self._fd, fcntl.LOCK_UN, 0)
            return "its parent process died"
        return None

    @contextmanager
    def committing(self) -> Iterator[None]:
        """Hold byte 1 shared while renaming; the run's `revoke()` waits for it."""
        if self._fd is not None and fcntl is not None:
            try:
                _lock(self._fd, fcntl.LOCK_SH, 1)
            except OSError:
                pass
        try:
            yield
        finally:
            if self._fd is not None and fcntl is not None:
                try:
                    _lock(self._fd, fcntl.LOCK_UN, 1)
                except OSError:
                    pass
