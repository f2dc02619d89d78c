"""A whole training run: settings checked, the model trained (tracked on validation sequences if asked), and its
checkpoint written with its provenance, unless the trained network is silent.

Every check runs before any training, each naming the parameter it refuses (`labels` renames them, as a
command names its flags): the settings against the model (benchmarks.training.registry), the data files,
validation apart from training, and the checkpoint's path (no input overwritten, its .json beside it).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping, Sequence
from typing import Any

from benchmarks.training.registry import configure, model_settings, resolve, trainer
from dvsot.core.bounds import MAX_THREADS, range_problem
from dvsot.core.errors import RunError, UserError, label

DEFAULT_DATA = ("data/dvsot21",)


def sctn_tracker(model, seed: int):
    """The benchmark tracker of an SCTN (or its twin): SCTNTracker, which fine-tunes a copy of the network."""
    from benchmarks.trackers.sctn import SCTNBenchTracker
    from sctn.tracker import SCTNTracker

    return SCTNBenchTracker.wrap(SCTNTracker(model, seed=seed))


def siamfc_tracker(model, seed: int):
    """The benchmark tracker of a SiamFC network, read as it is."""
    from benchmarks.trackers.siamfc.tracker import SiamFCTracker

    return SiamFCTracker.from_model(model)


def validation_scorer(model_kind: str, files: list, max_segments: int | None, seed: int) -> Callable[[Any], dict]:
    """model -> {"arscore", "accuracy_tracking", "robustness"} of the model's registered tracker on the validation
    sequences with the paper's protocol (re-initialisation)."""
    make = resolve(trainer(model_kind).tracker)

    def score(model) -> dict:
        from benchmarks.evaluation.metrics import pooled
        from benchmarks.evaluation.protocol import run_sequence
        from dvsot.dataset import Dataset

        ious = []
        for f in files:
            with Dataset(f) as ds:
                ious.append(run_sequence(make(model, seed), ds, model_kind, max_segments=max_segments).iou)
        s = pooled(ious)
        return {"arscore": s.arscore, "accuracy_tracking": s.accuracy, "robustness": s.robustness}
    return score


def training_config(model: str, settings: Mapping[str, Any], labels: Mapping[str, str] | None = None):
    """The config of `model` from settings (None = not given); UserError naming a setting it lacks or a bad value."""
    from sctn.training.loop import TrainConfigError

    full = model_settings(model, settings, labels)
    try:
        return configure(model, full, labels)
    except TrainConfigError as exc:  # every field set here is the setting of the same name
        raise UserError(f"{label(exc.field, labels)} {exc.problem}") from None


def train_model(model: str = "sctn", data: Sequence[str | os.PathLike] = DEFAULT_DATA,
                out_path: str | os.PathLike | None = None, *, split: str = "train",
                val_data: Sequence[str | os.PathLike] | None = None, val_arscore_segments: int | None = None,
                threads: int | None = None, progress: bool = True, labels: Mapping[str, str] | None = None,
                **settings: Any) -> dict:
    """Train `model` (a name of the training registry) on the `split` of the dataset files, directories or globs
    `data` ("any": every split) and write its checkpoint to out_path (default runs/<model>.pt) with its .json;
    returns the run's summary (checkpoint, steps, minutes, the last validation). `settings`: the model's training
    settings (None = the default). A silent trained network raises RunError and out_path keeps what it held."""
    import torch

    from dvsot.dataset import find_datasets
    from dvsot.runtime import interrupts
    from sctn.checkpoint import check_checkpoint_output, save_checkpoint
    from sctn.training.snn import provenance

    cfg = training_config(model, settings, labels)
    problem = threads is not None and range_problem(label("threads", labels), threads, 1, MAX_THREADS)
    if problem:
        raise UserError(problem)
    data = [str(d) for d in data]
    files = find_datasets(data, split=None if split == "any" else split, need_events=True)
    val_files = find_datasets([str(d) for d in val_data], split=None, need_events=True) if val_data else None
    both = set(map(str, val_files or [])) & set(map(str, files))
    if both:
        raise UserError(f"{', '.join(sorted(both))}: in both {label('data', labels)} and "
                        f"{label('val_data', labels)} (validation must be apart from training)")
    if settings.get("val_arscore_every") is not None and not val_files:
        raise UserError(f"{label('val_arscore_every', labels)} needs {label('val_data', labels)} "
                        "(the sequences to track)")
    if val_arscore_segments is not None and val_arscore_segments < 1:
        raise UserError(f"{label('val_arscore_segments', labels)} must be >= 1, got {val_arscore_segments}")
    out = check_checkpoint_output(out_path or f"runs/{model}.pt", label("out_path", labels),
                                  inputs=files + (val_files or []))
    if threads:
        torch.set_num_threads(threads)
    validation: dict = {}
    if val_files:
        validation["val_files"] = val_files
        if cfg.val_arscore_every is not None:
            validation["val_score"] = validation_scorer(model, val_files, val_arscore_segments, cfg.seed)
    try:
        net, history = resolve(trainer(model).train)(files, cfg, progress=progress, **validation)
    except UserError:  # already names its file (a UserError is a ValueError too)
        raise
    except ValueError as exc:
        raise UserError(f"{', '.join(data)}: {exc}") from None
    final = history["val"][-1] if history["val"] else {}
    if history.get("silent"):  # a dead network is no checkpoint: keep what out_path held
        rescue = trainer(model).rescue
        raise RunError(f"{out}: not written: the trained network is silent (target output {final['vmax_max']:g} "
                       f"at most on the {history['val_segments']} validation segments' samples); train again "
                       f"with another {label('seed', labels)}"
                       + (f" or {label(rescue[0], labels)} {rescue[1]}" if rescue else ""))
    with interrupts.last_step():  # once the checkpoint's renames begin the run has completed: a signal then is late
        save_checkpoint(out, net, provenance(files, cfg, history), kind=model)
    return {"checkpoint": str(out), "model": model, "steps": history["steps"],
            "minutes": round(history["minutes"], 2), "train_segments": history["train_segments"],
            "validation": history.get("validation"), "val": final, "nearly_silent": history.get("nearly_silent")}
