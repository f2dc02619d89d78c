"""The exception types the command line turns into one line (bad input: exit status 2, a failed run: exit 1), and
the one formatter of any exception as one line."""

from __future__ import annotations

from collections.abc import Mapping


class UserError(ValueError):
    """Bad input from the user (a file, a field, a value): the message is one line naming what and where.

    A ValueError, so that library callers catching bad values catch it too.
    """

    def __init__(self, message: str) -> None:
        super().__init__(" ".join(str(message).split()))


class RunError(Exception):
    """A run that could not finish (a full disk, a dead worker): one line naming the output or the cause; exit 1."""

    def __init__(self, message: str) -> None:
        super().__init__(" ".join(str(message).split()))


def label(name: str, labels: Mapping[str, str] | None = None) -> str:
    """How a library message names its setting `name`: the caller's label for it (a command's flag), else the name.

    Library messages name settings by their parameter names; a command passes {name: flag} to have its
    flags named instead.
    """
    return (labels or {}).get(name, name)


def exception_line(exc: BaseException, limit: int | None = None, kind: bool = True) -> str:
    """An exception as one line: 'Type: message' with white space folded (torch and pydantic messages span several
    lines), the message cut to `limit` characters; without `kind` the message alone; the type when it has none."""
    text = " ".join(str(exc).split())[:limit]
    if not text:
        return type(exc).__name__
    return f"{type(exc).__name__}: {text}" if kind else text
