"""A dataset's name (free text from a file's attributes) made safe where it becomes a file name or a table cell."""

from __future__ import annotations

import re

from dvsot.core.file_names import file_stem  # the rule dvsot export's toolkit layouts name sequences by

__all__ = ["file_stem", "one_line", "markdown_cell", "latex_text", "plot_text"]

_CONTROL = re.compile(r"[\x00-\x1f\x7f-\x9f\u2028\u2029]")


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
