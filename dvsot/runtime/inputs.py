"""Input files read by path: each one a regular file, checked before it is opened (opening a FIFO blocks)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import IO

from dvsot.core.bounds import file_kind_problem
from dvsot.core.errors import UserError


def regular_input(path: str | os.PathLike, what: str | None = None, missing_ok: bool = False) -> Path | None:
    """`path` if it is a regular file (through its symlinks); UserError naming it (and `what`) otherwise.

    `missing_ok`: a path that does not exist gives None (an optional side file); any other kind is still refused.
    """
    problem = file_kind_problem(path)
    if problem is None:
        return Path(path)
    if missing_ok and problem == "no such file":
        return None
    label = f" ({what})" if what else ""
    raise UserError(f"{path}{label}: {problem}, not a regular file to read")


def open_input(path: str | os.PathLike, mode: str = "rb", what: str | None = None, **kwargs) -> IO:
    """`open(path, mode)` for reading, once `regular_input` has passed it (no wait on a FIFO, no device read)."""
    if any(c in mode for c in "wax+"):
        raise ValueError(f"open_input reads only, got mode {mode!r}")
    return open(regular_input(path, what), mode, **kwargs)


def read_text(path: str | os.PathLike, what: str | None = None, missing_ok: bool = False) -> str | None:
    """The text of a regular file (UTF-8); None for a missing one when `missing_ok`."""
    p = regular_input(path, what, missing_ok)
    if p is None:
        return None
    with open(p, encoding="utf-8") as f:
        return f.read()
