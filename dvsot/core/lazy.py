"""A package's public names imported on first use.

The packages `dvsot`, `sctn` and `benchmarks` name their public API in one table each; importing the
package imports none of it, so `import dvsot` and `dvsot --help` stay free of torch and bpy.
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable
from typing import Any


def lazy_attributes(package: str, table: dict[str, str]) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """`__getattr__` and `__dir__` for a package whose public names {name: module} load on first access."""

    def __getattr__(name: str) -> Any:
        if name not in table:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        # looked up at each access, not cached, so that a patch of the module's name applies
        return getattr(importlib.import_module(table[name]), name)

    def __dir__() -> list[str]:
        return sorted(set(vars(sys.modules[package])) | set(table))

    return __getattr__, __dir__

