"""Scenes to render as checked tasks: scene files, or variants drawn from a template.

Everything is read and validated here, before any task runs: every variant drawn and validated (its file,
line and field named on an error), each scene's preview size. Messages name settings by their parameter
names; a command passes {name: flag} as `labels` to have its flags named instead (dvsot.core.errors.label).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path

from dvsot.core.errors import UserError, label
from dvsot.dataset.preview import check_preview_size
from dvsot.pipeline.scene_task import SceneTask
from dvsot.scene import SceneConfig, asset_paths, load_scene, read_scene_text, read_yaml
from dvsot.scene.templates import draw_variants, is_template, read_template, validate_variant


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
                            "draw scenes from it (generate_variants; `dvsot generate --variants N`)") from None
        raise


def _warn(cfg: SceneConfig, source: str, warn: Callable[[str], None] | None) -> None:
    if warn is not None:
        from dvsot.scene.checks import visibility_warnings

        for w in visibility_warnings(cfg):
            warn(f"{source}: {w}")


def _check(cfg: SceneConfig, source: str, overrides: dict, preview: bool, labels: Mapping[str, str] | None) -> None:
    if "sensor.width" in overrides and cfg.sensor.fx is not None:
        raise UserError(f"{source}: {label('resolution', labels)} cannot rescale a lens given as fx/cx/cy")
    if preview:
        check_preview_size(source, cfg, label("preview", labels))


def _keep(keep_frames: str | None, name: str, several: bool) -> str | None:
    """Where a scene keeps its frames: keep_frames itself for one scene, <keep_frames>/<name> for several."""
    if not keep_frames:
        return None
    return str(Path(keep_frames) / name) if several else str(keep_frames)


def variant_tasks(template: str | Path, count: int, out_dir: str | Path, overrides: dict | None = None,
                  preview: bool = False, warn: Callable[[str], None] | None = None,
                  labels: Mapping[str, str] | None = None, keep_frames: str | None = None,
                  progress: bool = False, masks: bool | None = None) -> tuple[list[SceneTask], list[Path]]:
    """Draw and validate `count` variants of a template; (tasks, input files) with outputs <out_dir>/<name>.h5.
    masks: keep the object index masks (None: generate's default)."""
    if count < 1:
        raise UserError(f"count (variants to draw) must be >= 1, got {count}")
    tpl = read_template(template)
    out = Path(out_dir).absolute()  # not resolved: a bad out_dir (a link loop) is named by check_outputs
    overrides = dict(overrides or {})
    tasks, inputs = [], [Path(template)]
    for v in draw_variants(tpl, count):
        source = f"{template} (variant {v.index})"
        cfg = validate_variant(tpl, v, dict(overrides), note=f"(variant {v.index})")
        _warn(cfg, source, warn)
        _check(cfg, source, overrides, preview, labels)
        inputs += asset_paths(cfg)
        tasks.append(SceneTask(name=v.name, text=v.text(Path(template).name), source=source,
                               base_dir=str(tpl.base_dir), output=str(out / f"{v.name}.h5"), overrides=overrides,
                               preview=preview, record={"variant": v.index, "seed": v.seed, "drawn": v.drawn},
                               keep_frames=_keep(keep_frames, v.name, count > 1), progress=progress,
                               masks=masks))
    return tasks, inputs


def scene_tasks(paths: list[str], out_dir: str | Path, overrides: dict | None = None,
                preview: bool = False, warn: Callable[[str], None] | None = None,
                labels: Mapping[str, str] | None = None, keep_frames: str | None = None,
                progress: bool = False, output: str | None = None,
                masks: bool | None = None) -> tuple[list[SceneTask], list[Path]]:
    """Validate scene files; (tasks, input files) with outputs <out_dir>/<scene name>.h5 (one scene: `output`);
    masks: keep the object index masks (None: generate's default)."""
    if output and len(paths) > 1:
        raise UserError(f"{label('output', labels)} names one output file; use {label('out_dir', labels)} "
                        "for several scenes")
    out = Path(out_dir).absolute()  # not resolved: a bad out_dir (a link loop) is named by check_outputs
    overrides = dict(overrides or {})
    configs = [load_plain_scene(p, dict(overrides)) for p in paths]  # all bad input before anything else
    tasks, inputs = [], []
    for p, cfg in zip(paths, configs):
        _warn(cfg, str(p), warn)
        _check(cfg, str(p), overrides, preview, labels)
        inputs += [Path(p), *asset_paths(cfg)]
        tasks.append(SceneTask(name=cfg.name, text=read_scene_text(p), source=str(p),
                               base_dir=str(Path(p).parent.resolve()),
                               output=str(output) if output else str(out / f"{cfg.name}.h5"), overrides=overrides,
                               preview=preview, record={"seed": cfg.seed},
                               keep_frames=_keep(keep_frames, cfg.name, len(paths) > 1), progress=progress,
                               masks=masks))
    return tasks, inputs


def many_tasks(paths: list[str], out_dir: str | Path, variants: int | None = None, overrides: dict | None = None,
               preview: bool = False, warn: Callable[[str], None] | None = None,
               labels: Mapping[str, str] | None = None, keep_frames: str | None = None,
               progress: bool = False, output: str | None = None,
               masks: bool | None = None) -> tuple[list[SceneTask], list[Path]]:
    """`variants` drawn from one template (variant_tasks), or else each scene file a task (scene_tasks)."""
    if variants is not None:
        if len(paths) != 1:
            raise UserError(f"{label('variants', labels)} draws from one template file, got {len(paths)}")
        if output:
            raise UserError(f"{label('output', labels)} names one output file; use {label('out_dir', labels)} "
                            f"for {label('variants', labels)}")
        return variant_tasks(paths[0], variants, out_dir, overrides, preview, warn, labels, keep_frames, progress,
                             masks)
    return scene_tasks(paths, out_dir, overrides, preview, warn, labels, keep_frames, progress, output, masks)
