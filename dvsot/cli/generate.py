"""Render scene files into labelled event sequences (one HDF5 dataset file per scene).

Examples:
  dvsot generate blender_scenes/quickstart.yaml -o out/quickstart.h5 --preview
  dvsot generate blender_scenes/*.yaml --out-dir data/dvsot21 --jobs 2
  dvsot generate blender_scenes/city_cat.yaml -o /tmp/cc.h5 --duration 0.3 --resolution 320x240
  dvsot generate blender_scenes/templates/dvsot21_random.yaml --variants 5 --dry-run
  dvsot generate blender_scenes/templates/dvsot21_random.yaml --variants 500 --out-dir data/random --scheduler local:2
  dvsot generate blender_scenes/templates/dvsot21_random.yaml --variants 500 --out-dir /shared/random \\
      --scheduler tcp://head:8786
"""

from __future__ import annotations

import argparse
import sys

from dvsot.core.errors import UserError


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Flags of `dvsot generate`."""
    p.add_argument("scenes", nargs="+", help="scene files (.yaml) or globs")
    p.add_argument("-o", "--output", help="output file (only with one scene)")
    p.add_argument("--out-dir", help="output directory: <name>.h5 per scene (default: next to -o, or out/)")
    p.add_argument("--preview", action="store_true", help="also write <output>.gif: event frames with the box")
    p.add_argument("--duration", type=float, help="override duration_s (seconds), for quick runs")
    p.add_argument("--resolution", help="override the sensor size, WxH (the lens's field of view is kept)")
    p.add_argument("--jobs", type=int, default=1, help="scenes rendered in parallel processes: local:N (default 1)")
    p.add_argument("--keep-frames", help="directory to keep rendered luma frames (.npy) in")
    p.add_argument("--masks", action=argparse.BooleanOptionalAction, default=None,
                   help="keep the object index masks per sample (/masks/objects; default), or not (--no-masks)")
    p.add_argument("--quiet", action="store_true", help="no progress bar; JSON summary")
    many = p.add_argument_group("many scenes (several scene files, a template's variants, a cluster; writes "
                                "<out-dir>/manifest.json)")
    many.add_argument("--variants", type=int, help="draw N scenes from one template file (its distributions)")
    many.add_argument("--dry-run", action="store_true", help="print the drawn scenes (checked), render nothing")
    many.add_argument("--scheduler", help="local:N (N worker processes here) or tcp://HOST:PORT")
    many.add_argument("--retries", type=int, default=1, help="times a failed scene is resubmitted (default 1)")
    many.add_argument("--resume", action="store_true", help="skip scenes whose output exists, verifies and holds them")


def _overrides(args: argparse.Namespace) -> dict:
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


# how dvsot.pipeline's messages name their settings here
_LABELS = {"output": "-o", "out_dir": "--out-dir", "preview": "--preview", "keep_frames": "--keep-frames",
           "resolution": "--resolution", "variants": "--variants", "retries": "--retries", "scheduler": "--scheduler"}


def _warn(text: str) -> None:
    print(f"dvsot generate: warning: {text}", file=sys.stderr)


def run(args: argparse.Namespace) -> int:
    """Validate every scene first (nothing is rendered if one is bad), then render them; 1 if a scene failed."""
    import glob
    import json

    from dvsot.core import bounds
    from dvsot.pipeline.manifest import summary_line
    from dvsot.pipeline.many_scenes import generate_scenes, many_tasks

    paths: list[str] = []
    for spec in args.scenes:
        found = sorted(glob.glob(spec)) if any(c in spec for c in "*?[") else [spec]
        if not found:
            raise UserError(f"{spec}: no scene files match")
        paths += found
    if args.output and args.out_dir:
        raise UserError("-o names the output file and --out-dir a directory for <name>.h5 files: give one of them")
    for problem in (bounds.range_problem("--jobs", args.jobs, 1, bounds.MAX_WORKERS),
                    args.variants is not None and bounds.range_problem("--variants", args.variants, 1,
                                                                        bounds.MAX_VARIANTS)):
        if problem:  # before any scene is read or drawn
            raise UserError(problem)
    if args.dry_run:  # each drawn scene checked, its view included, and printed
        tasks, _ = many_tasks(paths, args.out_dir or "out", args.variants, _overrides(args), args.preview, _warn,
                              _LABELS, output=args.output)
        print("".join(f"# ---- {t.name}: {t.output}\n{t.text}\n" for t in tasks), end="")
        return 0
    scenes = args.variants or len(paths)
    scheduler = args.scheduler or (f"local:{min(args.jobs, scenes)}" if args.jobs > 1 and scenes > 1 else None)
    # else one scene rendered here: its summary, no manifest (dvsot.pipeline.many_scenes.generate_scenes)
    written = scheduler is not None or args.resume or len(paths) > 1 or args.variants is not None

    def report(rec: dict) -> None:
        if written and args.quiet and rec["status"] != "retrying":
            print(json.dumps(rec), flush=True)
        elif written and not args.quiet:
            tried = rec["attempts"][-1]
            where = f" on {tried['worker']}" if tried.get("worker") else ""
            print(f"{rec['name']}: {rec['status']}{where}" + (f": {rec['error']}" if rec["error"] else ""),
                  file=sys.stderr, flush=True)
        if rec.get("variant") is not None:
            for w in rec.get("warnings") or []:
                _warn(f"{rec['name']}: {w}")

    manifest = generate_scenes(paths, args.output, args.out_dir, _overrides(args), args.preview, scheduler,
                               args.keep_frames, args.variants, args.retries, args.resume, args.quiet,
                               _warn, report, _LABELS, args.masks)
    if manifest.path is not None:
        print(summary_line(manifest), file=sys.stderr)
    else:
        summary = manifest.summaries[0]
        print(json.dumps(summary) if args.quiet else "\n".join(f"{k:>24}: {v}" for k, v in summary.items()))
    return 1 if manifest.failed() else 0
