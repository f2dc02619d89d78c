"""Temp names unique across hosts, commit journals, and the clean-up of what dead local processes left behind.

A staged output is `.<name>.tmp~<host>~<pid>~<token><suffix>` beside its target (same file system, so
the rename is atomic; the suffix kept for writers that choose a format by it). A run that commits
several outputs first writes a journal `.<name>.commit~<host>~<pid>~<token>.json` naming every
(staged, final) pair; its presence means "all staged files are complete, the renames are under way".
The next run in that directory (any process on the same host, once that pid is dead) completes the
renames from the journal, then deletes the dead process's other temps.
"""

from __future__ import annotations

import json
import os
import re
import secrets
import shutil
import socket
from pathlib import Path

_HOST = re.sub(r"[^A-Za-z0-9.-]", "-", socket.gethostname() or "host")[:64] or "host"
_NAME = re.compile(r"^\.(?P<base>.+)\.(?P<kind>tmp|commit|old)~(?P<host>[^~/]+)~(?P<pid>\d+)~(?P<token>[0-9a-f]{8})"
                   r"(?P<suffix>\.[^.~]*)?$")
_LEGACY = re.compile(r"^\.(?P<base>.+)\.tmp-(?P<pid>\d+)(?P<suffix>\.[^.~]*)?$")  # the temp names of earlier dvsot versions


def host() -> str:
    """This machine's name as used in temp names (characters other than letters, digits, '.', '-' replaced)."""
    return _HOST


def new_token() -> str:
    """Eight random hex digits: a run's token (with host and pid it makes temp names unique across a cluster)."""
    return secrets.token_hex(4)


def temp_name(final: Path, kind: str = "tmp", token: str | None = None, suffix: str | None = None) -> Path:
    """The hidden sibling of `final` of this kind (tmp, commit, old) for this host, process and token."""
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
    if p.is_dir() and not p.is_symlink():
        shutil.rmtree(p, ignore_errors=True)
    else:
        p.unlink(missing_ok=True)


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


def apply_journal(journal: Path) -> None:
    """Complete the renames a journal names (each one done at most once), then the manifest, then drop the journal."""
    data = json.loads(journal.read_text())
    for e in data["entries"]:
        staged, final = Path(e["staged"]), Path(e["final"])
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
