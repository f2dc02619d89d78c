"""Helpers for tests that drive dvsot as a user does: the command line, files in a directory, its processes."""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path


def dvsot(*args) -> list[str]:
    """The argv of `dvsot ARGS` run by this interpreter."""
    return [sys.executable, "-m", "dvsot.cli", *map(str, args)]


def names(d: Path) -> list[str]:
    """The sorted file names in directory d, hidden ones too."""
    return sorted(p.name for p in d.iterdir())


def wait_for(cond, timeout: float = 300.0, step: float = 0.005) -> None:
    """Poll cond until it holds (generous: a loaded machine builds Blender scenes slowly)."""
    end = time.monotonic() + timeout
    while not cond():
        if time.monotonic() > end:
            raise AssertionError("timed out waiting")
        time.sleep(step)


def _stat(pid: int | str) -> list[str]:
    """The fields of /proc/PID/stat after the command name (state first), or [] once it is gone."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except (OSError, IndexError):
        return []


def alive(pid: int) -> bool:
    """A process that exists and is not a zombie."""
    fields = _stat(pid)
    return bool(fields) and fields[0] != "Z"


def children(pid: int) -> list[int]:
    """Every live child of pid, whichever of its threads started it (a task's `children` file lists only its own;
    a Dask scheduler's loop thread starts processes too)."""
    kids = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            fields = _stat(entry.name)
            if len(fields) > 1 and fields[0] != "Z" and int(fields[1]) == pid:
                kids.append(int(entry.name))
    return sorted(kids)


def group_alive(pgid: int) -> bool:
    """Whether any process of process group pgid is left."""
    try:
        os.killpg(pgid, 0)
    except ProcessLookupError:
        return False
    return True
