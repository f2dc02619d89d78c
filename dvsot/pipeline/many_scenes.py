"""Render scenes: one path for one scene or many, here, on `local:N` worker processes or on a Dask cluster.

`generate_scenes` (what `dvsot generate` calls) and `generate_variants` check everything first (every scene
or drawn variant, every output path and the manifest's), then `generate_many` renders the tasks: one scene
per task through dvsot.runtime.dask_tasks.TaskRunner, each failure recorded in the manifest with its one-line
error and the scene resubmitted (on a cluster preferring another worker) up to `retries` times. A lone scene
rendered here (no scheduler, no resume) is the quick path: no cluster, no manifest file, its errors raised.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Mapping
from pathlib import Path

from dvsot.core.errors import UserError, label
from dvsot.pipeline.manifest import Manifest, scene_failure
from dvsot.pipeline.scene_sources import many_tasks
from dvsot.pipeline.scene_task import SceneTask, output_is_done, render_scene, render_task, warm_up_scene
from dvsot.runtime.dask_tasks import Failure, TaskRunner, parse_scheduler
from dvsot.runtime.outputs import output_dir, output_file, refuse_non_regular
from dvsot.runtime.warm_up import warm_workers

MANIFEST = "manifest.json"


def check_outputs(tasks: list[SceneTask], inputs: list[Path], out_dir: str | Path | None = None,
                  output: str | None = None, keep_frames: str | None = None, manifest: bool = True,
                  labels: Mapping[str, str] | None = None) -> Path | None:
    """Check every output path before any work: each task's dataset file and preview, kept frames, the manifest;
    make out_dir. output: one scene's file (then no manifest). The manifest's path, or None without one."""
    out = None
    if output:
        output_file(output, label("output", labels), inputs)
    else:
        out = output_dir(out_dir or "out", label("out_dir", labels))
    seen: dict = {}
    for t in tasks:
        o = Path(t.output)
        if o.is_dir() or o.exists():
            output_file(o, f"the output of {t.source}", inputs)
        if o.resolve() in seen:
            raise UserError(f"{t.source}: scene name gives the same output {o} as {seen[o.resolve()]}; rename one")
        seen[o.resolve()] = t.source
        gif = o.with_suffix(".gif")
        if t.preview and not gif.is_dir():
            refuse_non_regular(gif, label("preview", labels))  # a FIFO, socket or device named like the preview
        if t.preview and (gif.is_dir() or gif == o):
            raise UserError(f"{gif}: {label('preview', labels)} would write this path, " +
                            ("a directory" if gif.is_dir() else "the dataset file itself"))
    if keep_frames:
        from dvsot.pipeline.generate import check_keep_frames

        output_dir(keep_frames, label("keep_frames", labels))
        for t in tasks:
            check_keep_frames(t.keep_frames, label("keep_frames", labels))
    path = None
    if manifest and out is not None:
        path = out / MANIFEST
        if path.is_dir() or path.exists():
            output_file(path, "the manifest", inputs)
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
    return path


def generate_many(tasks: list[SceneTask], inputs: list[Path], out_dir: str | Path, scheduler: str | None = None,
                  retries: int = 1, resume: bool = False, report: Callable[[dict], None] | None = None,
                  labels: Mapping[str, str] | None = None, keep_frames: str | None = None) -> Manifest:
    """Check the outputs, then render every task (here, or on `scheduler`: local:N or tcp://HOST:PORT); the
    manifest of the run (<out_dir>/manifest.json). report(record) after every attempt.

    labels: how messages name the settings out_dir, preview, retries and scheduler (a command's flags)."""
    if retries < 0:
        raise UserError(f"{label('retries', labels)} must be >= 0, got {retries}")
    if scheduler is not None:
        parse_scheduler(scheduler, label("scheduler", labels))
    path = check_outputs(tasks, inputs, out_dir, None, keep_frames, True, labels)
    return run_scenes(tasks, path, scheduler, retries, resume, report)


def run_scenes(tasks: list[SceneTask], manifest_path: Path | None, scheduler: str | None = None, retries: int = 0,
               resume: bool = False, report: Callable[[dict], None] | None = None) -> Manifest:
    """Render every task (in this process when scheduler is None), recording each attempt; the manifest at the end.

    On a cluster the timing holds start_s (the client and any LocalCluster), warm_s (the workers' warm-up) and
    run_s (first submit to last result), in seconds.
    """
    manifest = Manifest(manifest_path, tasks)
    todo = []
    for i, task in enumerate(tasks):
        if resume and output_is_done(task):
            manifest.records[i].update(status="done", resumed=True)
        else:
            todo.append(i)
    manifest.write()
    report = report or (lambda rec: None)
    if not todo:  # nothing to render: no cluster started
        manifest.timing["run_s"] = 0.0
        manifest.write()
        return manifest
    t0 = time.perf_counter()
    with TaskRunner(scheduler) as runner:
        hosts = runner.hosts()
        if runner.client is not None:
            manifest.timing["start_s"] = round(time.perf_counter() - t0, 3)
            t0 = time.perf_counter()
            fixed = {t.overrides.get("render.threads") for t in tasks}  # threads set for every scene by an override
            threads = next(iter(fixed)) if len(fixed) == 1 else None
            warm_workers(runner.client, warm_up_scene, threads if isinstance(threads, int) else 0)
            manifest.timing["warm_s"] = round(time.perf_counter() - t0, 3)
            t0 = time.perf_counter()
            if not hosts:
                print(f"dvsot generate: no workers on {scheduler} yet; waiting for some", file=sys.stderr)

        def done(k: int, outcome: dict) -> None:
            report(manifest.record(todo[k], outcome, final=True))

        def failed(k: int, failure: Failure, final: bool) -> None:
            report(manifest.record(todo[k], failure, final))

        lease = manifest_path.parent if manifest_path is not None else Path(tasks[0].output).resolve().parent
        runner.run(render_task, [(tasks[i], hosts) for i in todo], retries, on_result=done, on_failure=failed,
                   failure_of=scene_failure, name="scene", lease_dir=lease)
    manifest.timing["run_s"] = round(time.perf_counter() - t0, 3)
    manifest.write()
    return manifest


def generate_scenes(paths: list[str], output: str | None = None, out_dir: str | None = None,
                    overrides: dict | None = None, preview: bool = False, scheduler: str | None = None,
                    keep_frames: str | None = None, variants: int | None = None, retries: int = 1,
                    resume: bool = False, quiet: bool = False, warn: Callable[[str], None] | None = None,
                    report: Callable[[dict], None] | None = None,
                    labels: Mapping[str, str] | None = None, masks: bool | None = None) -> Manifest:
    """Render scene files (or `variants` drawn from one template) into dataset files: `output` for one scene, else
    <out_dir>/<name>.h5 and <out_dir>/manifest.json; the run's manifest (each scene's summary in .summaries).
    masks: keep each file's object index masks (/masks/objects; None: generate's default, on).

    Every scene is loaded and every output path checked before anything is rendered; `warn` gets the scenes'
    visibility warnings (for variants, each task records its own). scheduler: None (this process), local:N or
    tcp://HOST:PORT. One scene here without resume renders directly, its errors raised, with no manifest file.
    """
    if retries < 0:
        raise UserError(f"{label('retries', labels)} must be >= 0, got {retries}")
    if scheduler is not None:
        parse_scheduler(scheduler, label("scheduler", labels))
    alone = len(paths) == 1 and variants is None and scheduler is None and not resume
    tasks, inputs = many_tasks(paths, out_dir or "out", variants, overrides, preview,
                               warn if variants is None else None, labels, keep_frames,
                               progress=not quiet and scheduler is None, output=output, masks=masks)
    if output and not alone:
        raise UserError(f"{label('output', labels)} names one output file, with no manifest: give "
                        f"{label('out_dir', labels)} for a run on a scheduler or a resumed run")
    path = check_outputs(tasks, inputs, out_dir, output, keep_frames, not alone, labels)
    if not alone:
        return run_scenes(tasks, path, scheduler, retries, resume, report)
    manifest = Manifest(None, tasks)  # the quick path: no task runner, no retry, errors as they are
    summary = render_scene(tasks[0])
    rec = manifest.record(0, summary, final=True)
    if report is not None:
        report(rec)
    return manifest


def generate_variants(template: str | Path, n: int, out_dir: str | Path, scheduler: str | None = None,
                      overrides: dict | None = None, preview: bool = False, retries: int = 1, resume: bool = False,
                      report: Callable[[dict], None] | None = None,
                      labels: Mapping[str, str] | None = None, masks: bool | None = None) -> Manifest:
    """Draw n variants of a scene template and render them into <out_dir>/<name>.h5 (here, or on `scheduler`:
    local:N or tcp://HOST:PORT); the run's manifest, also written to <out_dir>/manifest.json. masks: keep the
    object index masks (None: generate's default, on)."""
    from dvsot.core.bounds import MAX_VARIANTS, range_problem

    if isinstance(n, bool) or not isinstance(n, int):
        raise UserError(f"n (variants to draw) must be an integer, got {n!r}")
    problem = range_problem("n (variants to draw)", n, 1, MAX_VARIANTS)
    if problem:
        raise UserError(problem)
    return generate_scenes([str(template)], None, str(out_dir), overrides, preview, scheduler, None, n, retries,
                           resume, True, None, report, labels, masks)


__all__ = ["generate_scenes", "generate_variants", "generate_many", "run_scenes", "check_outputs", "MANIFEST"]
