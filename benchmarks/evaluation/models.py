"""The networks a benchmark run loads up front: SCTN's checkpoint (checked), and the energy table's ANN models."""

from __future__ import annotations

import os
from collections.abc import Sequence


def error_text(exc: BaseException) -> str:
    """One line for an exception from pydantic, torch or elsewhere (their messages span several lines)."""
    from pydantic import ValidationError

    if isinstance(exc, ValidationError):
        err = exc.errors()[0]
        loc = ".".join(str(p) for p in err["loc"])
        msg = "unknown field" if err["type"] == "extra_forbidden" else err["msg"]
        return f"field '{loc}': {msg}" if loc else msg
    lines = [ln.strip() for ln in str(exc).splitlines() if ln.strip()]
    if len(lines) > 1 and lines[0].endswith(":"):
        lines = lines[1:]  # torch: "Error(s) in loading state_dict for SCTN:" then the actual problem
    return f"{type(exc).__name__}: {lines[0] if lines else repr(exc)}"


def load_sctn_checkpoint(path: str | os.PathLike | None):
    """The SCTN model of a checkpoint (None: the shipped one), built with its state dict; any problem is a
    UserError naming the file."""
    from dvsot.core.errors import UserError
    from sctn.checkpoint import default_checkpoint_path, load_checkpoint

    try:
        return load_checkpoint(path)[0]
    except UserError:
        raise
    except Exception as exc:  # a loadable file whose config or tensors do not fit the network
        where = path if path is not None else default_checkpoint_path()
        detail = error_text(exc)
        if detail.startswith("field "):
            detail = "config " + detail  # NetworkConfig rejected the checkpoint's config
        raise UserError(f"{where}: not a usable SCTN checkpoint ({detail})") from None


def energy_ann_models(trackers: Sequence[str], options: dict[str, dict]) -> tuple[dict, tuple[str, ...]]:
    """The twin and SiamFC networks for the energy table's ANN rows: the run's checkpoints, else the shipped ones;
    a row without a checkpoint is left out with a note saying so."""
    from benchmarks.trackers.siamfc.model import default_siamfc_path, load_siamfc
    from sctn.ann import default_twin_path, load_twin

    models, notes = {}, []
    for key, name, load, shipped in (("twin", "sctn_ann", load_twin, default_twin_path),
                                     ("siamfc", "siamfc", load_siamfc, default_siamfc_path)):
        path = options.get(name, {}).get("checkpoint")
        if name in trackers or path is not None or shipped().is_file():
            models[key] = load(path)[0]
        else:
            notes.append(f"({name}: no checkpoint at {shipped()}, its row is left out)")
    return models, tuple(notes)
