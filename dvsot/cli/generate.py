"""Render scene files into labelled event sequences (one HDF5 dataset file per scene).

Examples:
  dvsot generate blender_scenes/quickstart.yaml -o out/quickstart.h5 --preview
  dvsot generate blender_scenes/*.yaml --out-dir data/dvsot21 --jobs 2
  dvsot generate blender_scenes/city_cat.yaml -o /tmp/cc.h5 --duration 0.3 --resolution 320x240
  dvsot generate blender_scenes/random_dvsot21.yaml --variants 5 --dry-run
  dvsot generate blender_scenes/random_dvsot21.yaml --variants 500 --out-dir data/random --scheduler local:2
  dvsot generate blender_scenes/random_dvsot21.yaml --variants 500 --out-dir /shared/random --scheduler tcp://head:8786
"""

from __future__ import annotations

import argparse


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Flags of `dvsot generate`."""
    p.add_argument("scenes", nargs="+", help="scene files (.yaml) or globs")
    p.add_argument("-o", "--output", help="output file (only with one scene)")
    p.add_argument("--out-dir", help="output directory: <name>.h5 per scene (default: next to -o, or out/)")
    p.add_argument("--preview", action="store_true", help="also write <output>.gif: event frames with the box")
    p.add_argument("--duration", type=float, help="override duration_s (seconds), for quick runs")
    p.add_argument("--resolution", help="override the sensor size, WxH (the lens's field of view is kept)")
    p.add_argument("--jobs", type=int, default=1, help="scenes rendered in parallel processes (default 1)")
    p.add_argument("--keep-frames", help="directory to keep rendered luma frames (.npy) in")
    p.add_argument("--quiet", action="store_true", help="no progress bar; JSON summary")
    many = p.add_argument_group("many scenes (a template's variants, a cluster; writes <out-dir>/manifest.json)")
    many.add_argument("--variants", type=int, help="draw N scenes from one template file (its distributions)")
    many.add_argument("--dry-run", action="store_true", help="print the drawn scenes (checked), render nothing")
    many.add_argument("--scheduler", help="local:N (a LocalCluster of N worker processes) or tcp://HOST:PORT")
    many.add_argument("--retries", type=int, default=1, help="times a failed scene is resubmitted (default 1)")
    many.add_argument("--resume", action="store_true", help="skip scenes whose output exists, verifies and holds them")


def _overrides(args: argparse.Namespace) -> dict:
    from dvsot.errors import UserError

    out = {}
    if args.duration is not None:
        if args.duration <= 0:
            raise UserError(f"--duration must be positive, got {args.duration}")
        out["duration_s"] = args.duration
    if args.resolution:
        try:
            w, h = (int(v) for v in args.resolution.lower().split("x"))
        except ValueError:
            raise UserError(f"--resolution must look like 640x480, got {args.resolution!r}") from None
        out["sensor.width"], out["sensor.height"] = w, h
    return out


def generate_one(scene_path: str, out_path: str, overrides: dict, preview: bool, quiet: bool,
                 keep_frames: str | None) -> dict:
    """Worker: load, render, simulate and write one scene (own process when parallel)."""
    from dvsot.scene import load_scene, read_scene_text
    from dvsot.pipeline.generate import generate

    cfg = load_scene(scene_path, overrides)
    if "sensor.width" in overrides and cfg.sensor.fx is not None:
        from dvsot.errors import UserError

        raise UserError(f"{scene_path}: --resolution cannot rescale a lens given as fx/cx/cy")
    return generate(cfg, out_path, read_scene_text(scene_path), progress=not quiet, keep_frames=keep_frames,
                    preview=preview)


def _check_preview_size(path: str, cfg) -> None:
    """UserError before rendering if the --preview of a scene would hold more frames in memory than allowed."""
    from dvsot.dataset.preview import check_preview_size

    check_preview_size(path, cfg, "--preview")


def _outputs(args: argparse.Namespace, paths: list[str], configs: list) -> list:
    """The dataset file of each scene, every output path checked (and --out-dir made) before rendering."""

    from dvsot.scene import asset_paths
    from dvsot.errors import UserError
    from dvsot.runtime.outputs import output_dir, output_file

    inputs = paths + [a for c in configs for a in asset_paths(c)]  # scene files, meshes, image textures
    if args.output:
        outs = [output_file(args.output, "-o", inputs)]
    else:
        out_dir = output_dir(args.out_dir or "out", "--out-dir")
        outs = [out_dir / f"{c.name}.h5" for c in configs]
    seen: dict = {}
    for o, p, c in zip(outs, paths, configs):
        if o.is_dir() or o.exists():
            output_file(o, f"the output of {p}", inputs)
        if o.resolve() in seen:
            raise UserError(f"{p}: scene name gives the same output {o} as {seen[o.resolve()]}; rename one")
        seen[o.resolve()] = p
        gif = o.with_suffix(".gif")
        if args.preview:
            _check_preview_size(p, c)
        if args.preview and (gif.is_dir() or gif == o):
            raise UserError(f"{gif}: --preview would write this path, " + ("a directory" if gif.is_dir() else
                                                                            "the dataset file itself"))
    if args.keep_frames:
        from dvsot.pipeline.generate import check_keep_frames

        output_dir(args.keep_frames, "--keep-frames")
        for k in _keep_dirs(args.keep_frames, configs):
            check_keep_frames(k, "--keep-frames")
    if not args.output:
        out_dir.mkdir(parents=True, exist_ok=True)
    return outs


def _warn_nonsense(paths: list[str], configs: list) -> None:
    """One stderr line per scene whose target is never in view, or always fills the frame (still rendered)."""
    import sys

    from dvsot.scene.checks import visibility_warnings

    for path, cfg in zip(paths, configs):
        for warning in visibility_warnings(cfg):
            print(f"dvsot generate: warning: {path}: {warning}", file=sys.stderr)


def _keep_dirs(keep: str | None, configs: list) -> list:
    """Where each scene keeps its frames: --keep-frames itself for one scene, <it>/<name> for several."""
    from pathlib import Path

    if not keep:
        return [None] * len(configs)
    return [keep] if len(configs) == 1 else [str(Path(keep) / c.name) for c in configs]


def run(args: argparse.Namespace) -> int:
    """Validate every scene first (nothing is rendered if one is bad), then render them."""
    import glob
    import json

    from pathlib import Path

    from dvsot.errors import UserError

    paths: list[str] = []
    for spec in args.scenes:
        found = sorted(glob.glob(spec)) if any(c in spec for c in "*?[") else [spec]
        if not found:
            raise UserError(f"{spec}: no scene files match")
        paths += found
    from dvsot import limits as validate

    if args.output and args.out_dir:
        raise UserError("-o names the output file and --out-dir a directory for <name>.h5 files: give one of them")
    for problem in (validate.range_problem("--jobs", args.jobs, 1, validate.MAX_WORKERS),
                    args.variants is not None and validate.range_problem("--variants", args.variants, 1,
                                                                          validate.MAX_VARIANTS)):
        if problem:  # before any scene is read or drawn
            raise UserError(problem)
    overrides = _overrides(args)
    if args.variants is not None or args.scheduler or args.dry_run or args.resume:
        return _many(args, paths, overrides)
    from dvsot.pipeline.many_scenes import load_plain_scene

    configs = [load_plain_scene(p, overrides) for p in paths]  # all bad input is reported before any rendering
    _warn_nonsense(paths, configs)
    if args.output and len(paths) > 1:
        raise UserError("-o names one output file; use --out-dir for several scenes")
    outs = _outputs(args, paths, configs)
    jobs = [(p, str(o), overrides, args.preview, args.quiet or len(paths) > 1 and args.jobs > 1, k)
            for p, o, k in zip(paths, outs, _keep_dirs(args.keep_frames, configs))]
    if args.jobs == 1 or len(jobs) == 1:
        summaries = [generate_one(*j) for j in jobs]
    else:  # local:N; its workers die with this process and commit nothing once it stops (dvsot.runtime.dask_tasks)
        from dvsot.runtime.dask_tasks import map_tasks

        summaries = map_tasks(f"local:{min(args.jobs, len(jobs))}", generate_one, jobs,
                              lease_dir=Path(outs[0]).resolve().parent)
    for s in summaries:
        if args.quiet:
            print(json.dumps(s))
        else:
            print("\n".join(f"{k:>24}: {v}" for k, v in s.items()))
    return 0


# how dvsot.pipeline.many_scenes's messages name its settings here
_LABELS = {"out_dir": "--out-dir", "preview": "--preview", "retries": "--retries", "scheduler": "--scheduler"}


def _many(args: argparse.Namespace, paths: list[str], overrides: dict) -> int:
    """A template's variants or several scenes, each its own task (dvsot.pipeline.many_scenes); exit 1 if any finally failed."""
    import json
    import sys

    from dvsot.pipeline.many_scenes import generate_many, scene_tasks, variant_tasks
    from dvsot.errors import UserError
    from dvsot.pipeline.scene_runner import summary_line

    if args.output or args.keep_frames:
        raise UserError("--variants, --scheduler, --dry-run and --resume write <name>.h5 files and a manifest into "
                        "--out-dir; -o and --keep-frames do not apply")

    def warn(text: str) -> None:
        print(f"dvsot generate: warning: {text}", file=sys.stderr)

    if args.variants is not None:
        if len(paths) != 1:
            raise UserError(f"--variants draws from one template file, got {len(paths)}")
        # a dry run checks each drawn scene's view here; a render run in each task (warnings in the manifest)
        tasks, inputs = variant_tasks(paths[0], args.variants, args.out_dir or "out", overrides, args.preview,
                                      warn if args.dry_run else None, _LABELS)
    else:
        tasks, inputs = scene_tasks(paths, args.out_dir or "out", overrides, args.preview, warn, _LABELS)
    if args.dry_run:
        for t in tasks:
            print(f"# ---- {t.name}: {t.output}\n{t.text}")
        return 0
    scheduler = args.scheduler or (f"local:{args.jobs}" if args.jobs > 1 else None)

    def report(rec: dict) -> None:
        if args.quiet:
            if rec["status"] != "retrying":
                print(json.dumps(rec), flush=True)
        else:
            tried = rec["attempts"][-1]
            where = f" on {tried['worker']}" if tried.get("worker") else ""
            print(f"{rec['name']}: {rec['status']}{where}" + (f": {rec['error']}" if rec["error"] else ""),
                  file=sys.stderr, flush=True)
        if rec.get("warnings") and rec.get("variant") is not None:
            for w in rec["warnings"]:
                warn(f"{rec['name']}: {w}")

    manifest = generate_many(tasks, inputs, args.out_dir or "out", scheduler, args.retries, args.resume, report,
                             _LABELS)
    print(summary_line(manifest), file=sys.stderr)
    return 1 if any(r["status"] == "failed" for r in manifest.records) else 0
