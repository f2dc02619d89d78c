"""Scene files -> one dataset file each: every scene and output path checked first, then rendered here or on local:N.

Messages name the settings by their parameter names (output, out_dir, preview, keep_frames, resolution);
a command passes {name: flag} as `labels` to have its flags named instead (dvsot.errors.label).
"""

from __future__ import annotations

from pathlib import Path
from typing import Callable, Mapping

from dvsot.errors import UserError, label


def generate_one(scene_path: str, out_path: str, overrides: dict, preview: bool, quiet: bool,
                 keep_frames: str | None, labels: Mapping[str, str] | None = None) -> dict:
    """Worker: load, render, simulate and write one scene (own process when parallel); its summary."""
    from dvsot.scene import load_scene, read_scene_text
    from dvsot.pipeline.generate import generate

    cfg = load_scene(scene_path, overrides)
    if "sensor.width" in overrides and cfg.sensor.fx is not None:
        raise UserError(f"{scene_path}: {label('resolution', labels)} cannot rescale a lens given as fx/cx/cy")
    return generate(cfg, out_path, read_scene_text(scene_path), progress=not quiet, keep_frames=keep_frames,
                    preview=preview)


def keep_dirs(keep: str | None, configs: list) -> list:
    """Where each scene keeps its frames: `keep` itself for one scene, <keep>/<name> for several."""
    if not keep:
        return [None] * len(configs)
    return [keep] if len(configs) == 1 else [str(Path(keep) / c.name) for c in configs]


def scene_outputs(paths: list[str], configs: list, output: str | None = None, out_dir: str | None = None,
                  preview: bool = False, keep_frames: str | None = None,
                  labels: Mapping[str, str] | None = None) -> list[Path]:
    """The dataset file of each scene, every output path checked (and out_dir made) before rendering."""
    from dvsot.dataset.preview import check_preview_size
    from dvsot.scene import asset_paths
    from dvsot.runtime.outputs import output_dir, output_file

    inputs = paths + [a for c in configs for a in asset_paths(c)]  # scene files, meshes, image textures
    if output:
        outs = [output_file(output, label("output", labels), inputs)]
    else:
        out = output_dir(out_dir or "out", label("out_dir", labels))
        outs = [out / f"{c.name}.h5" for c in configs]
    seen: dict = {}
    for o, p, c in zip(outs, paths, configs):
        if o.is_dir() or o.exists():
            output_file(o, f"the output of {p}", inputs)
        if o.resolve() in seen:
            raise UserError(f"{p}: scene name gives the same output {o} as {seen[o.resolve()]}; rename one")
        seen[o.resolve()] = p
        gif = o.with_suffix(".gif")
        if preview:
            check_preview_size(p, c, label("preview", labels))
        if preview and not gif.is_dir():
            from dvsot.runtime.outputs import refuse_non_regular

            refuse_non_regular(gif, label("preview", labels))  # a FIFO, socket or device named like the preview
        if preview and (gif.is_dir() or gif == o):
            raise UserError(f"{gif}: {label('preview', labels)} would write this path, " +
                            ("a directory" if gif.is_dir() else "the dataset file itself"))
    if keep_frames:
        from dvsot.pipeline.generate import check_keep_frames

        output_dir(keep_frames, label("keep_frames", labels))
        for k in keep_dirs(keep_frames, configs):
            check_keep_frames(k, label("keep_frames", labels))
    if not output:
        out.mkdir(parents=True, exist_ok=True)
    return outs


def visibility_warnings(paths: list[str], configs: list) -> list[str]:
    """One line per scene whose target is never in view, or always fills the frame (it is still rendered)."""
    from dvsot.scene.checks import visibility_warnings as scene_warnings

    return [f"{path}: {w}" for path, cfg in zip(paths, configs) for w in scene_warnings(cfg)]


def generate_scenes(paths: list[str], output: str | None = None, out_dir: str | None = None,
                    overrides: dict | None = None, preview: bool = False, jobs: int = 1,
                    keep_frames: str | None = None, quiet: bool = False,
                    warn: Callable[[str], None] | None = None,
                    labels: Mapping[str, str] | None = None) -> list[dict]:
    """Render scene files into dataset files (output for one, else <out_dir>/<name>.h5); one summary each.

    Every scene is loaded and every output path checked before anything is rendered; `warn` gets the
    visibility warnings. jobs > 1 renders scenes in local worker processes (dvsot.runtime.dask_tasks).
    """
    from dvsot.pipeline.many_scenes import load_plain_scene

    overrides = dict(overrides or {})
    configs = [load_plain_scene(p, overrides) for p in paths]  # all bad input is reported before any rendering
    if warn is not None:
        for line in visibility_warnings(paths, configs):
            warn(line)
    if output and len(paths) > 1:
        raise UserError(f"{label('output', labels)} names one output file; use {label('out_dir', labels)} "
                        "for several scenes")
    outs = scene_outputs(paths, configs, output, out_dir, preview, keep_frames, labels)
    tasks = [(p, str(o), overrides, preview, quiet or len(paths) > 1 and jobs > 1, k, labels)
             for p, o, k in zip(paths, outs, keep_dirs(keep_frames, configs))]
    if jobs == 1 or len(tasks) == 1:
        return [generate_one(*t) for t in tasks]
    # local:N; its workers die with this process and commit nothing once it stops (dvsot.runtime.dask_tasks)
    from dvsot.runtime.dask_tasks import map_tasks

    return map_tasks(f"local:{min(jobs, len(tasks))}", generate_one, tasks, lease_dir=Path(outs[0]).resolve().parent)
