"""A package's public names imported on first use, and a module that can be called as its main function.

The packages `dvsot`, `sctn` and `benchmarks` name their public API in one table each; importing the
package imports none of it, so `import dvsot` and `dvsot --help` stay free of torch and bpy.
"""

from __future__ import annotations

import importlib
import sys
import types
from typing import Any, Callable


def lazy_attributes(package: str, table: dict[str, str]) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """`__getattr__` and `__dir__` for a package whose public names {name: module} load on first access."""

    def __getattr__(name: str) -> Any:
        if name not in table:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        module = importlib.import_module(table[name])
        # a name shared with its own submodule (sctn.train) is the submodule, made callable below
        return module if module.__name__ == f"{package}.{name}" else getattr(module, name)

    def __dir__() -> list[str]:
        return sorted(set(vars(sys.modules[package])) | set(table))

    return __getattr__, __dir__


def callable_module(module_name: str, function: str) -> None:
    """Let the module be called as its function `function` (looked up at each call, so a patch applies).

    Why: a package attribute named like one of its submodules is replaced by the submodule whenever that
    is first imported, so `sctn.train` cannot reliably be the function; it is the module, callable.
    """
    module = sys.modules[module_name]

    class CallableModule(types.ModuleType):
        def __call__(self, *args: Any, **kwargs: Any) -> Any:
            return getattr(self, function)(*args, **kwargs)

    CallableModule.__call__.__doc__ = f"{module_name}.{function}: " + (getattr(module, function).__doc__ or "")
    module.__class__ = CallableModule
