"""Many scenes in one run: a template's variants or scene files as checked tasks, rendered by dvsot.pipeline.scene_runner.

Everything is checked before any task is submitted: every variant drawn and validated (its file, line and
field named on an error), every output path and the manifest's.
"""

from __future__ import annotations

from pathlib import Path
from typing import Callable, Mapping

from dvsot.scene import SceneConfig, asset_paths, load_scene, read_scene_text, read_yaml
from dvsot.core.errors import UserError, label
from dvsot.runtime.outputs import output_dir, output_file
from dvsot.dataset.preview import check_preview_size
from dvsot.pipeline.scene_runner import Manifest, SceneTask, run_scenes
from dvsot.scene.templates import draw_variants, is_template, read_template, validate_variant

MANIFEST = "manifest.json"


def load_plain_scene(path: str | Path, overrides: dict | None = None) -> SceneConfig:
    """load_scene, with a template (distributions, counts, random walks) named as such: it needs drawing."""
    try:
        return load_scene(path, overrides)
    except UserError:
        try:
            data, _ = read_yaml(read_scene_text(path), str(path))
        except UserError:
            data = None
        if is_template(data):
            raise UserError(f"{path}: a scene template (it holds distributions, counted items or random walks): "
                            "draw scenes from it (variant_tasks; `dvsot generate --variants N`)") from None
        raise


def _warn(cfg: SceneConfig, source: str, warn: Callable[[str], None] | None) -> None:
    if warn is not None:
        from dvsot.scene.checks import visibility_warnings

        for w in visibility_warnings(cfg):
            warn(f"{source}: {w}")


def variant_tasks(template: str | Path, count: int, out_dir: str | Path, overrides: dict | None = None,
                  preview: bool = False, warn: Callable[[str], None] | None = None,
                  labels: Mapping[str, str] | None = None) -> tuple[list[SceneTask], list[Path]]:
    """Draw and validate `count` variants of a template; (tasks, input files) with outputs <out_dir>/<name>.h5."""
    if count < 1:
        raise UserError(f"count (variants to draw) must be >= 1, got {count}")
    tpl = read_template(template)
    out = Path(out_dir).resolve()
    tasks, inputs = [], [Path(template)]
    for v in draw_variants(tpl, count):
        cfg = validate_variant(tpl, v, dict(overrides or {}), note=f"(variant {v.index})")
        _warn(cfg, f"{template} (variant {v.index})", warn)
        if preview:
            check_preview_size(f"{template} (variant {v.index})", cfg, label("preview", labels))
        inputs += asset_paths(cfg)
        tasks.append(SceneTask(name=v.name, text=v.text(Path(template).name), source=f"{template} (variant {v.index})",
                               base_dir=str(tpl.base_dir), output=str(out / f"{v.name}.h5"),
                               overrides=dict(overrides or {}), preview=preview,
                               record={"variant": v.index, "seed": v.seed, "drawn": v.drawn}))
    return tasks, inputs


def scene_tasks(paths: list[str], out_dir: str | Path, overrides: dict | None = None,
                preview: bool = False, warn: Callable[[str], None] | None = None,
                labels: Mapping[str, str] | None = None) -> tuple[list[SceneTask], list[Path]]:
    """Validate scene files; (tasks, input files) with outputs <out_dir>/<scene name>.h5."""
    out = Path(out_dir).resolve()
    tasks, inputs = [], []
    for p in paths:
        cfg = load_plain_scene(p, dict(overrides or {}))
        _warn(cfg, str(p), warn)
        if preview:
            check_preview_size(str(p), cfg, label("preview", labels))
        inputs += [Path(p), *asset_paths(cfg)]
        tasks.append(SceneTask(name=cfg.name, text=read_scene_text(p), source=str(p),
                               base_dir=str(Path(p).parent.resolve()), output=str(out / f"{cfg.name}.h5"),
                               overrides=dict(overrides or {}), preview=preview, record={"seed": cfg.seed}))
    return tasks, inputs


def many_tasks(paths: list[str], out_dir: str | Path, variants: int | None = None, overrides: dict | None = None,
               preview: bool = False, warn: Callable[[str], None] | None = None,
               labels: Mapping[str, str] | None = None) -> tuple[list[SceneTask], list[Path]]:
    """`variants` drawn from one template (variant_tasks), or else each scene file a task (scene_tasks)."""
    if variants is not None:
        if len(paths) != 1:
            raise UserError(f"{label('variants', labels)} draws from one template file, got {len(paths)}")
        return variant_tasks(paths[0], variants, out_dir, overrides, preview, warn, labels)
    return scene_tasks(paths, out_dir, overrides, preview, warn, labels)


def check_outputs(tasks: list[SceneTask], out_dir: str | Path, inputs: list[Path],
                  labels: Mapping[str, str] | None = None) -> Path:
    """Check every output path (and the manifest's) before any work; make out_dir; the manifest's path."""
    out = output_dir(out_dir, label("out_dir", labels))
    seen: dict = {}
    for t in tasks:
        o = Path(t.output)
        if o.is_dir() or o.exists():
            output_file(o, f"the output of {t.source}", inputs)
        if o in seen:
            raise UserError(f"{t.source}: scene name gives the same output {o} as {seen[o]}; rename one")
        seen[o] = t.source
        gif = o.with_suffix(".gif")
        if t.preview and gif.is_dir():
            raise UserError(f"{gif}: {label('preview', labels)} would write this path, a directory")
    manifest = out / MANIFEST
    if manifest.is_dir() or manifest.exists():
        output_file(manifest, "the manifest", inputs)
    out.mkdir(parents=True, exist_ok=True)
    return manifest


def generate_many(tasks: list[SceneTask], inputs: list[Path], out_dir: str | Path, scheduler: str | None = None,
                  retries: int = 1, resume: bool = False,
                  report: Callable[[dict], None] | None = None,
                  labels: Mapping[str, str] | None = None) -> Manifest:
    """Check the outputs, then render every task (here, or on `scheduler`); the manifest of the run.

    labels: how messages name the settings out_dir, preview, retries and scheduler (a command's flags)."""
    if retries < 0:
        raise UserError(f"{label('retries', labels)} must be >= 0, got {retries}")
    if scheduler is not None:
        from dvsot.pipeline.scene_runner import parse_scheduler

        parse_scheduler(scheduler, label("scheduler", labels))
    manifest = check_outputs(tasks, out_dir, inputs, labels)
    return run_scenes(tasks, manifest, scheduler, retries, resume, report)
