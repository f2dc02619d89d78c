"""Scene file -> one labelled event sequence: sample times, renders, events and boxes, streamed into a dataset file."""

from __future__ import annotations

import json
import os
import re
import sys
import time
from pathlib import Path

import numpy as np

from dvsot import __version__
from dvsot.core.errors import UserError
from dvsot.dataset.boxes import box_from_mask, mask_visibility, object_rows, truncation_share
from dvsot.dataset.format import attrs_problem
from dvsot.events import EventSimulator
from dvsot.events.labels import TARGET_ID, LabelledFrame, object_table
from dvsot.pipeline.kept_frames import DIGEST_ATTR as KEPT_DIGEST_ATTR
from dvsot.pipeline.kept_frames import FrameDigest
from dvsot.pipeline.sequence import write_sequence
from dvsot.render.sample_times import frames_saved_vs_fixed, motion_bounded_times, with_extra_times
from dvsot.runtime import interrupts
from dvsot.runtime.outputs import run_outputs, writing
from dvsot.scene import SceneConfig
from dvsot.scene.shapes import mesh_for, sample_points
from dvsot.scene.trajectory import pose_and_scale, pose_matrix, project


def scene_projector(cfg: SceneConfig):
    """A function t (s) -> (N, 2) pixel positions of tracked points (objects' and the background's; NaN behind the
    camera)."""
    k = cfg.sensor.intrinsics()
    n = cfg.sampling.points_per_object
    moving = []
    for i, spec in enumerate([cfg.target] + list(cfg.objects)):
        pts = sample_points(mesh_for(spec.shape, spec.mesh), n, seed=i) * spec.size_m
        name = "target" if i == 0 else (spec.name or f"{spec.role}_{i - 1}")
        moving.append((spec.trajectory, pts, cfg.derived_seed("shake:" + name)))
    bg = cfg.background
    g = np.linspace(-0.5, 0.5, 15)
    gx, gy = np.meshgrid(g, g)
    if bg.kind == "plane":
        plane = pose_and_scale(type(cfg.camera)(keyframes=[{"t": 0, "location": bg.location,
                                                             "rotation_deg": bg.rotation_deg}]), 0.0)[0]
        local = np.stack([gx.ravel(), gy.ravel(), np.zeros(gx.size)], 1) * bg.size_m
        static = local @ plane[:3, :3].T + plane[:3, 3]
    else:  # environment: directions far away; only camera rotation moves them
        d = np.random.default_rng(0).normal(size=(300, 3))
        static = 1e4 * d / np.linalg.norm(d, axis=1, keepdims=True)
    cam_seed = cfg.derived_seed("camera_shake")

    def proj(t: float) -> np.ndarray:
        parts = [static]
        for traj, pts, seed in moving:
            m, s = pose_and_scale(traj, t, seed)
            parts.append((pts * s) @ m[:3, :3].T + m[:3, 3])
        cam = pose_matrix(cfg.camera, t, cam_seed)
        if bg.kind == "environment":
            parts[0] = static + cam[:3, 3]
        return project(np.vstack(parts), cam, k)

    return proj


_MARGIN_PX = 50.0  # motion this far outside the image is not seen; covers the pixel filter's reach


def sample_times(cfg: SceneConfig) -> np.ndarray:
    """Motion-bounded render times in seconds for a scene."""
    s, k = cfg.sampling, cfg.sensor.intrinsics()
    window = (-_MARGIN_PX, -_MARGIN_PX, k.width + _MARGIN_PX, k.height + _MARGIN_PX)
    times = motion_bounded_times(scene_projector(cfg), 0.0, cfg.duration_s, s.max_displacement_px, s.min_rate_hz,
                                 s.max_rate_hz, window)
    return with_extra_times(times, np.asarray(s.extra_times_ms, np.float64) / 1000.0)



def scene_object_table(cfg: SceneConfig) -> list[dict]:
    """The scene's object ids for the per-event labels: background 0, target 1, the scene file's objects from 2."""
    return object_table([(o.name or f"{o.role}_{i}", o.role) for i, o in enumerate(cfg.objects)],
                        target=cfg.target.name or "target")


# Whether `dvsot generate` keeps the object index pass (/masks/objects) unless told: on, since its measured cost on
# the quick-start scene at default settings is within 1.10x generate's time per sample and 1.3x the file's size
# (docs/results.md, "Ground-truth masks")
MASKS_BY_DEFAULT = True

_FRAME = re.compile(r"^\d{6}\.npy$")


def check_keep_frames(path: str | Path, flag: str) -> Path:
    """A directory for kept frames: new, empty, or holding only frames (NNNNNN.npy) of an earlier run, replaced
    whole."""
    p = Path(path)
    if p.is_dir():
        other = sorted(n for n in os.listdir(p) if not _FRAME.match(n))
        if other:
            raise UserError(f"{p}: {flag} holds files that are not kept frames ({', '.join(other[:3])}"
                            f"{', ...' if len(other) > 3 else ''}); its content is replaced whole, so give a "
                            "new or empty directory")
    return p


def run_manifest(out_path: str | Path) -> Path:
    """Where a run with more outputs than the dataset file writes its manifest: .<name>.run.json beside it."""
    p = Path(out_path)
    return p.with_name(f".{p.name}.run.json")


def _status(show: bool, text: str) -> None:
    """One progress line on stderr (where the bar goes), when progress is shown."""
    if show:
        print(text, file=sys.stderr, flush=True)


def generate(cfg: SceneConfig, out_path: str | Path, scene_text: str = "", progress: bool = True,
             keep_frames: str | Path | None = None, preview: bool = False, labels: bool = True,
             masks: bool | None = None) -> dict:
    """Render the scene at motion-bounded times, simulate events and boxes, write the dataset file; a summary.

    labels: each event carries the id of the object that made it (/events/object, dvsot.events.labels),
    from the render's object-index pass; with them the file also holds every object's boxes, pixel counts,
    visibility and truncation per sample (/objects/..., dvsot.dataset.boxes.object_rows).
    masks: also keep that pass itself, one object index image per sample (/masks/objects); None: MASKS_BY_DEFAULT.
    The target's truncation (/boxes/truncation) is always written.

    preview: also write <out_path>.gif (event frames with the box); the file, its preview and kept frames
    are renamed into place together, or none of them (dvsot.runtime.outputs).
    """
    masks = MASKS_BY_DEFAULT if masks is None else bool(masks)
    if masks and not labels:
        raise UserError(f"{out_path}: masks are the object index pass the labels come from: they need labels")
    with run_outputs(run_manifest(out_path) if preview or keep_frames else None) as run:
        summary = _generate(cfg, out_path, scene_text, progress, keep_frames, labels, masks)
        if preview:
            from dvsot.dataset.preview import PREVIEW_SEGMENTS, write_preview

            gif = Path(out_path).with_suffix(".gif")
            write_preview(run.staged(out_path), gif, max_segments=PREVIEW_SEGMENTS)
            summary["preview"] = str(gif)
    return summary


def _generate(cfg: SceneConfig, out_path: str | Path, scene_text: str, progress: bool,
              keep_frames: str | Path | None, labels: bool = True, masks: bool = False) -> dict:
    # a signal raised inside bpy's import leaves Blender half set up and the process dies of SIGSEGV at exit;
    # record it during the import and raise it after, like a signal during a render
    with interrupts.deferred():
        from dvsot.render.blender import BlenderScene, blender_version

    start = time.perf_counter()
    # a long scene spends minutes here and in the scene build before its bar appears: say what is going on
    _status(progress, f"{cfg.name}: planning render times for {cfg.duration_s:g} s of scene "
                      f"(no point moving more than {cfg.sampling.max_displacement_px:g} px between frames)")
    times = sample_times(cfg)
    _status(progress, f"{cfg.name}: {len(times)} frames to render; building the Blender scene")
    t_us = np.rint(times * 1e6).astype(np.int64)
    W, H = cfg.sensor.width, cfg.sensor.height
    params = cfg.events
    from dvsot.events.memory import check_memory

    check_memory(params, W, H, float(np.diff(t_us).max()) if len(t_us) > 1 else 0.0, cfg.name, render=True)
    sim = EventSimulator(W, H, params, cfg.derived_seed("events"))
    attrs = {"name": cfg.name, "split": cfg.split, "scene_yaml": scene_text,
             "scene_resolved": json.loads(cfg.model_dump_json()), "simulator": params.model_dump(),
             "seed": cfg.seed, "event_seed": cfg.derived_seed("events"), "generator": "dvsot generate",
             "challenges": cfg.challenges,
             "versions": {"dvsot": __version__, "blender": blender_version(), "numpy": np.__version__}}
    problem = attrs_problem(attrs)
    if problem:  # before the Blender scene is built
        raise UserError(f"{out_path}: {problem}")
    render_s = 0.0
    truth_s = 0.0  # boxes, visibility, truncation and every object's rows, after the render
    first_s = 0.0  # the first render also builds Cycles' BVH and shaders (kept after it: persistent data)
    # Cycles swallows a KeyboardInterrupt raised inside its callbacks (and renders on), so SIGINT/SIGTERM
    # are only recorded while Blender runs and raised between frames; the outputs are then never renamed.
    with run_outputs(run_manifest(out_path) if keep_frames else None) as run, interrupts.deferred():
        keep = None
        kept = FrameDigest()  # recorded in the file: tools given these frames check they belong to it
        if keep_frames:
            check_keep_frames(keep_frames, "keep_frames")
            keep = run.stage_dir(keep_frames)  # replaces the directory whole at the commit: runs never mix
        with BlenderScene(cfg) as scene:
            interrupts.check()
            amodal, visible, visibility, truncation = [], [], [], []
            table = scene_object_table(cfg)
            ids = np.array([row["id"] for row in table])
            rows: list[dict] = []  # every object's ground truth per sample (with labels)

            def renders():
                """Luma of each sample in turn; its boxes are kept for the file."""
                nonlocal render_s, first_s, truth_s
                for i, t in enumerate(times):
                    r0 = time.perf_counter()
                    luma, full, seen, objects, coverage = scene.render_truth(float(t))
                    render_s += time.perf_counter() - r0
                    interrupts.check()  # a signal during the render: stop here
                    if i == 0:
                        first_s = render_s
                    if keep:
                        with writing(keep_frames):  # a full disk: one line naming --keep-frames
                            np.save(keep / f"{i:06d}.npy", luma)
                        kept.update(luma)
                    g0 = time.perf_counter()
                    amodal.append(box_from_mask(full))
                    visible.append(box_from_mask(seen))
                    visibility.append(mask_visibility(full, seen))
                    _, on, whole = coverage[TARGET_ID]
                    truncation.append(truncation_share(on, whole))
                    if labels:
                        coverage[TARGET_ID] = (full, on, whole)  # the target's amodal mask as /boxes/xywh has it
                        rows.append(object_rows(objects, ids, coverage))
                    truth_s += time.perf_counter() - g0
                    yield LabelledFrame(luma, objects) if labels else luma

            def boxes() -> dict:
                out = {"t_us": t_us, "xywh": amodal, "xywh_visible": visible, "visibility": visibility,
                       "truncation": truncation}
                if rows:
                    out["objects"] = {name: np.stack([r[name] for r in rows]) for name in rows[0]}
                return out

            _, counts = write_sequence(out_path, renders(), t_us, sim, attrs, int(round(cfg.segment_ms * 1000)),
                                       source=cfg.name, boxes=boxes, progress=progress,
                                       bar_after_error=False,  # the error line alone, no bar redrawn under it
                                       objects=table if labels else None, masks=masks,
                                       final_attrs=lambda: {KEPT_DIGEST_ATTR: kept.hexdigest()} if keep else {})
            n_events, n_pos = counts.events, counts.positive
    wall = time.perf_counter() - start
    saved = frames_saved_vs_fixed(times, 1000.0)
    return {"output": str(out_path), "name": cfg.name, "resolution": f"{W}x{H}", "duration_s": cfg.duration_s,
            "frames": len(times), "frames_at_fixed_1kHz": saved["fixed_frames"],
            "frames_saved_vs_1kHz": round(saved["saved_fraction"], 3),
            "events": n_events, "positive_fraction": round(n_pos / n_events, 4) if n_events else None,
            "s_per_frame": round(render_s / len(times), 4),
            "s_per_frame_after_first": round((render_s - first_s) / (len(times) - 1), 4) if len(times) > 1 else None,
            "first_frame_s": round(first_s, 3), "truth_s_per_frame": round(truth_s / len(times), 4),
            "masks": masks, "frames_per_simulated_s": round(len(times) / cfg.duration_s, 1),
            "wall_s": round(wall, 2)}
