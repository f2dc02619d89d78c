"""One scene as a task: what it holds, rendering it (in a worker process or here), and whether its output is done.

A task renders with `render.threads` (when the scene leaves it at 0, all cores) set to the worker's share of
its machine's cores (dvsot.runtime.cpu_shares); every worker of a cluster first renders a 16x12 scene
(`warm_up_scene`, run once per process by dvsot.runtime.warm_up), so a scene's task time is its own.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field
from pathlib import Path

from dvsot.core.errors import exception_line
from dvsot.runtime.cpu_shares import threads_for_this_worker
from dvsot.runtime.dask_tasks import worker_address
from dvsot.runtime.warm_up import RENDER_LOCK, real_bpy_first


@dataclass(frozen=True)
class SceneTask:
    """One scene to render: its concrete scene text, where to write it and what the manifest says of it."""

    name: str
    text: str                      # the concrete scene file (YAML)
    source: str                    # for messages: the scene or template file
    base_dir: str                  # absolute; relative mesh and texture paths resolve against it
    output: str                    # the .h5 path (absolute, but for a single scene's -o as given)
    overrides: dict = field(default_factory=dict)
    preview: bool = False
    record: dict = field(default_factory=dict)  # manifest fields known up front (variant, seed, drawn)
    keep_frames: str | None = None  # directory for the rendered luma frames (.npy), on the worker's machine
    progress: bool = False         # a progress bar on stderr (a task rendered in this process)
    masks: bool | None = None      # keep the object index masks (/masks/objects); None: generate's default


def render_scene(task: SceneTask, host_workers: dict[str, int] | None = None) -> dict:
    """Render one scene into its dataset file (its errors raised); its summary, with task_s and cpu_s in seconds."""
    t_task, cpu_task = time.perf_counter(), time.process_time()
    with RENDER_LOCK:
        real_bpy_first()
        from dvsot.pipeline.generate import generate
        from dvsot.scene import parse_scene
        from dvsot.scene.checks import visibility_warnings

        cfg = parse_scene(task.text, task.source, Path(task.base_dir), dict(task.overrides))
        if cfg.render.threads == 0 and host_workers is not None:
            cfg.render.threads = threads_for_this_worker(host_workers)
        warnings = visibility_warnings(cfg)  # here, not at the head: each costs a scene's projections
        # the dataset file and its preview are renamed into place together, or neither (dvsot.pipeline.generate)
        summary = generate(cfg, task.output, task.text, progress=task.progress, keep_frames=task.keep_frames,
                           preview=task.preview, masks=task.masks)
        summary["task_s"] = round(time.perf_counter() - t_task, 3)  # with imports, scene check, waiting on the lock
        # CPU seconds of the whole process (every render thread) during the task: what the scene cost whatever
        # else ran on the machine
        summary["cpu_s"] = round(time.process_time() - cpu_task, 3)
        summary["render_threads"] = cfg.render.threads
        if hasattr(os, "sched_getaffinity"):
            summary["cpus"] = sorted(os.sched_getaffinity(0))  # the worker's share (warm_up), or every CPU
        summary["warnings"] = warnings
    return summary


def render_task(task: SceneTask, host_workers: dict[str, int] | None = None) -> dict:
    """render_scene in a worker: its summary with "worker", or {"error": one line, "worker"} on any failure."""
    worker = worker_address()
    try:
        summary = render_scene(task, host_workers)
    except Exception as exc:  # returned, not raised: the head records it and retries (no traceback in worker logs)
        return {"error": exception_line(exc, 300), "worker": worker}
    summary["worker"] = worker
    return summary


WARM_UP_SCENE = """name: warm_up
duration_s: 0.01
sensor: {width: 16, height: 12, focal_mm: 35}
camera: {keyframes: [{t: 0, location: [0, -10, 0], look_at: [0, 0, 0]}]}
target:
  shape: cube
  size_m: 1.5
  trajectory: {interpolation: linear, keyframes: [{t: 0, location: [-1, 0, 0]}, {t: 0.01, location: [1, 0, 0]}]}
background: {material: {texture: {type: noise, scale: 10}}}
sampling: {min_rate_hz: 200}
"""


def warm_up_scene(tmp: Path, threads: int) -> None:
    """Render a 16x12 scene into tmp with `threads` render threads (0: all cores): the bpy import, Cycles' first
    render, h5py and the event kernels' load (numba's cache), paid once per worker process (dvsot.runtime.warm_up)."""
    from dvsot.pipeline.generate import generate
    from dvsot.scene import parse_scene
    from dvsot.scene.checks import visibility_warnings

    cfg = parse_scene(WARM_UP_SCENE, "warm-up scene", Path(tmp))
    cfg.render.threads = threads
    visibility_warnings(cfg)
    generate(cfg, Path(tmp) / "warm_up.h5", WARM_UP_SCENE, progress=False)


def output_is_done(task: SceneTask) -> bool:
    """Whether the task's output exists, reads back whole and holds this very scene, with masks or without them as the
    task asks (for resume)."""
    from dvsot.dataset import Dataset
    from dvsot.pipeline.generate import MASKS_BY_DEFAULT

    if not Path(task.output).is_file():
        return False
    try:
        with Dataset(task.output) as ds:
            ds.verify()
            masks = MASKS_BY_DEFAULT if task.masks is None else task.masks
            return ds.attrs.get("scene_yaml") == task.text and ds.has_masks == masks
    except Exception:  # any damage means: render it again
        return False
