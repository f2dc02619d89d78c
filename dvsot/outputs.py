"""Output paths checked before any work starts, so that a bad one fails at once (exit 2) and never after a run."""

from __future__ import annotations

import os
from contextlib import contextmanager
from pathlib import Path
from typing import Iterable, Iterator

from dvsot.errors import UserError


def output_file(path: str | Path, flag: str, inputs: Iterable[str | Path] = ()) -> Path:
    """`path` as a file a command may (re)write: its directory exists, it is no directory and no input."""
    p = Path(path)
    if p.is_dir():
        raise UserError(f"{p}: {flag} names a directory, not a file")
    if not p.parent.is_dir():
        raise UserError(f"{p}: {flag}: directory {p.parent} does not exist")
    if p.exists():
        for i in inputs:
            if Path(i).exists() and os.path.samefile(p, i):
                raise UserError(f"{p}: {flag} would overwrite an input file")
    return p


def output_dir(path: str | Path, flag: str) -> Path:
    """`path` as a directory a command may write into (made later, when there is output): not a file."""
    p = Path(path)
    if p.exists() and not p.is_dir():
        raise UserError(f"{p}: {flag} names a file, not a directory")
    for parent in p.parents:
        if parent.exists():
            if not parent.is_dir():
                raise UserError(f"{p}: {flag}: {parent} is a file, not a directory")
            break
    return p


@contextmanager
def replacing(path: str | Path) -> Iterator[Path]:
    """A temp path beside `path` (same suffix) to write; renamed onto `path` if the block succeeds, else removed."""
    p = Path(path)
    tmp = p.with_name(f".{p.stem}.tmp-{os.getpid()}{p.suffix}")
    try:
        yield tmp
        os.replace(tmp, p)
    finally:
        tmp.unlink(missing_ok=True)  # only left when the write or the rename failed
