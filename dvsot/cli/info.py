"""Summarise a dataset file: resolution, duration, events, rate, events per object, segments, box coverage, parameters.

Examples:
  dvsot info out/quickstart.h5
  dvsot info out/quickstart.h5 --json
"""

from __future__ import annotations

import argparse


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Flags of `dvsot info`."""
    p.add_argument("file", nargs="+", help="dataset file(s) (.h5)")
    p.add_argument("--json", action="store_true", help="print JSON (one object per file, as a list if several)")


def summarise(path: str) -> dict:
    """The summary of one dataset file: dvsot.dataset.info.dataset_info (imported here on use: `dvsot --help` stays
    light)."""
    from dvsot.dataset.info import dataset_info

    return dataset_info(path)


def _text(info: dict) -> str:
    from benchmarks.evaluation.safe_names import one_line

    lines = [f"{info['file']}  ({one_line(info['name'])}{', ' + one_line(info['split']) if info['split'] else ''})",
             f"  resolution     {info['resolution'][0]}x{info['resolution'][1]}",
             f"  duration       {info['duration_s']:.3f} s",
             f"  events         {info['events']:,}  ({info['event_rate_per_s'] / 1e6:.3f} Mev/s"
             + (f", {100 * info['positive_fraction']:.1f}% positive" if info['positive_fraction'] is not None else "")
             + (f", {info['noise_events']:,} noise" if info.get("noise_events") else "") + ")",
             f"  segments       {info['segments']} x {info['segment_ms']:g} ms, "
             f"{info['segments_with_box']} with a box ({100 * info['box_coverage']:.1f}%)"]
    if "segments_absent" in info:
        median = info["visibility_median"]
        lines.append(
            f"  visibility     median {'-' if median is None else f'{median:.2f}'} of the target's pixels seen, "
            f"{info['segments_absent']} segments with the target absent"
        )
    if "segments_truncated" in info:
        kept = [what for key, what in (("per_object_truth", "every object's boxes"), ("mask_samples", "object masks"))
                if key in info]
        lines.append(f"  truncation     {info['segments_truncated']} segments with part of the target off the sensor"
                     + (f"; {' and '.join(kept)} per sample" if kept else ""))
    for row in info.get("objects", ()):
        lines.append(f"  {'objects' if row is info['objects'][0] else '':<15}{row['id']:>3} {one_line(row['name'])} "
                     f"({row['role']}): {row['events']:,} events, {100 * row['share']:.1f}%")
    if info.get("t_offset_us"):
        lines.append(f"  t_offset       {info['t_offset_us']} us (added to t for the recording's clock)")
    if info.get("ground_truth") == "annotations":
        lines.append(f"  annotations    {info['box_samples']} boxes, {info['segments_matched_to_annotation']} "
                     f"segments matched to one (only those are scored)")
    if "box_width_px" in info:
        w, h = info["box_width_px"], info["box_height_px"]
        lines.append(
            f"  box size       w {w[0]:.0f}/{w[1]:.0f}/{w[2]:.0f}  "
            f"h {h[0]:.0f}/{h[1]:.0f}/{h[2]:.0f} px (min/median/max)"
        )
    if "simulator" in info and isinstance(info["simulator"], dict):
        lines.append("  simulator      " + ", ".join(f"{k}={v}" for k, v in info["simulator"].items()))
    if "seed" in info:
        lines.append(f"  seed           {info['seed']}")
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    """Print the summary of each file."""
    import json

    infos = [summarise(f) for f in args.file]
    if args.json:
        print(json.dumps(infos[0] if len(infos) == 1 else infos, indent=2))
    else:
        print("\n".join(_text(i) for i in infos))
    return 0
