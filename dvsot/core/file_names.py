"""A name from a file (free text: a sequence's name, a tracker's) made safe where it becomes a file name."""

from __future__ import annotations

import hashlib
import re

_SAFE = re.compile(r"[A-Za-z0-9_.-]+")
_MAX_STEM = 100  # characters of a file name made from a name (file systems allow 255 bytes)


def file_stem(name: str) -> str:
    """A file name (no directory, no leading dot) for `name`: the name itself if it is plain
    (letters, digits, _ . -), else the plain characters kept and a short hash of the name added,
    so distinct names stay distinct ("../../x" becomes "_.._x-<8 hex>")."""
    name = str(name)
    if _SAFE.fullmatch(name) and not name.startswith(".") and len(name) <= _MAX_STEM:
        return name
    plain = re.sub(r"[^A-Za-z0-9_.-]+", "_", name)[:_MAX_STEM - 9].lstrip(".") or "_"
    digest = hashlib.sha256(name.encode("utf-8", "surrogatepass")).hexdigest()[:8]
    return f"{plain}-{digest}"
