"""A dataset's name (free text from a file's attributes) made safe where it becomes a file name or a table cell."""

from __future__ import annotations

import hashlib
import re

_SAFE = re.compile(r"[A-Za-z0-9_.-]+")
_MAX_STEM = 100  # characters of a file name made from a name (file systems allow 255 bytes)
_CONTROL = re.compile(r"[\x00-\x1f\x7f-\x9f\u2028\u2029]")


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


def one_line(text: str) -> str:
    """Text with control characters (newlines, tabs, escapes) written as visible escapes such as \\n."""
    return _CONTROL.sub(lambda m: m.group().encode("unicode_escape").decode("ascii"), str(text))


def markdown_cell(text: str) -> str:
    """Text for a Markdown table cell: one line, with | and backslashes escaped."""
    return one_line(text).replace("\\", "\\\\").replace("|", "\\|")


_LATEX = {"\\": r"\textbackslash{}", "&": r"\&", "%": r"\%", "$": r"\$", "#": r"\#", "_": r"\_", "{": r"\{",
          "}": r"\}", "~": r"\textasciitilde{}", "^": r"\textasciicircum{}"}


def latex_text(text: str) -> str:
    """Text for LaTeX: one line, with every special character escaped."""
    return "".join(_LATEX.get(ch, ch) for ch in one_line(text))


def plot_text(text: str) -> str:
    """Text for a matplotlib title or legend: one line, $ escaped (no mathtext), no leading _ (legend skips those)."""
    out = one_line(text).replace("$", r"\$")
    return " " + out if out.startswith("_") else out
