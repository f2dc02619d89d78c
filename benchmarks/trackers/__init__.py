"""Tracker registry: built-in trackers by name (imported lazily) and user trackers added with `register`.

Add your own tracker in a few lines (see docs/benchmarks.md):

    from benchmarks.trackers import register
    from benchmarks.trackers.base import Tracker

    @register("centre")
    class CentreOfEvents(Tracker):
        def init(self, segment, box_xywh, width, height):
            self.box = box_xywh.copy()
        def update(self, segment):
            if len(segment.events):
                self.box[:2] = [segment.events.x.mean() - self.box[2] / 2, segment.events.y.mean() - self.box[3] / 2]
            return self.box.copy()

then `dvsot bench --tracker-module mypackage.mymodule --tracker centre`.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable

from dvsot.core.errors import UserError

# Built-ins are imported on first use, so listing trackers does not import torch or OpenCV.
BUILTIN: dict[str, str] = {
    "sctn": "benchmarks.trackers.sctn",
    "sctn_ann": "benchmarks.trackers.sctn_ann",
    "siamfc": "benchmarks.trackers.siamfc.tracker",
    "goturn": "benchmarks.trackers.goturn.tracker",
    "siamrpn": "benchmarks.trackers.siamrpn.tracker",
    "siammask": "benchmarks.trackers.siammask.tracker",
    "ocean": "benchmarks.trackers.ocean.tracker",
    "automatch": "benchmarks.trackers.automatch.tracker",
    "rct": "benchmarks.trackers.rct",
    "csrt": "benchmarks.trackers.frame_based",
    "kcf": "benchmarks.trackers.frame_based",
    "mil": "benchmarks.trackers.frame_based",
}
_REGISTRY: dict[str, type] = {}


def register(name: str) -> Callable[[type], type]:
    """Class decorator: make a Tracker subclass available under `name`."""

    def decorate(cls: type) -> type:
        _REGISTRY[name] = cls
        if getattr(cls, "name", None) in (None, "tracker"):
            cls.name = name
        return cls

    return decorate


def available_trackers() -> list[str]:
    """Names of the built-in and registered trackers."""
    return sorted(set(BUILTIN) | set(_REGISTRY))


def tracker_class(name: str) -> type:
    """The class registered under `name`; an unknown name raises UserError listing the known ones."""
    if name not in _REGISTRY and name in BUILTIN:
        importlib.import_module(BUILTIN[name])
    if name not in _REGISTRY:
        raise UserError(f"unknown tracker '{name}' (known: {', '.join(available_trackers())})")
    return _REGISTRY[name]


def get_tracker(name: str, **options) -> Tracker:  # noqa: F821 - imported lazily
    """A new instance of the tracker registered under `name`."""
    return tracker_class(name)(**options)


def load_tracker_module(module: str, label: str = "tracker module") -> None:
    """Import a user module whose trackers register themselves; a missing module raises UserError (naming it as
    `label` and the module)."""
    if not module or not all(part.isidentifier() for part in module.split(".")):  # "..x", "a/b.py", "a..b"
        raise UserError(f"{label} {module}: not a module name (dotted Python identifiers, e.g. mypkg.trackers)")
    try:
        importlib.import_module(module)
    except ModuleNotFoundError as exc:
        raise UserError(f"{label} {module}: cannot import ({exc})") from None
