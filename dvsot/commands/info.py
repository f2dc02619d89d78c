"""Summarise a dataset file: resolution, duration, events, rate, segments, box coverage, parameters.

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
    """A dict summary of one dataset file (times in seconds, sizes in pixels)."""
    import numpy as np

    from dvsot.dataset import Dataset

    with Dataset(path) as ds:
        n_pos, n_noise, has_signal = 0, 0, False
        # chunked (files may hold hundreds of millions of events), and every chunk is checked on the way:
        # info is where a damaged file should show up, so it reads all of it
        for batch in ds.chunks():
            n_pos += int(np.count_nonzero(batch.p))
            if batch.signal is not None:
                has_signal = True
                n_noise += int(np.count_nonzero(~batch.signal))
        n_noise = n_noise if has_signal else None
        seg = ds.segment_boxes()
        have = ~np.isnan(seg).any(axis=1)
        duration = ds.duration_us / 1e6
        out = {
            "file": str(ds.path), "name": ds.name, "split": ds.split, "format_version": ds.format_version,
            "resolution": [ds.width, ds.height], "duration_s": duration, "events": ds.num_events,
            "event_rate_per_s": ds.num_events / duration if duration else 0.0,
            "positive_fraction": n_pos / ds.num_events if ds.num_events else None,
            "noise_events": n_noise, "segment_ms": ds.segment_us / 1000, "segments": ds.num_segments,
            "segments_with_box": int(have.sum()),
            "box_coverage": float(have.mean()) if ds.num_segments else 0.0,
            "box_samples": int(len(ds.boxes().t)),
            "t_offset_us": ds.t_offset_us,
            "ground_truth": "annotations" if ds.annotated else "rendered",
        }
        if ds.annotated:  # a recording: segments scored against an annotation (docs/benchmarks.md)
            out["segments_matched_to_annotation"] = int(ds.segment_scored().sum())
        if have.any():
            w, h = seg[have, 2], seg[have, 3]
            out["box_width_px"] = [float(w.min()), float(np.median(w)), float(w.max())]
            out["box_height_px"] = [float(h.min()), float(np.median(h)), float(h.max())]
        for key in ("simulator", "seed", "generator", "versions"):
            if key in ds.attrs:
                out[key] = ds.attrs[key]
    return out


def _text(info: dict) -> str:
    from dvsot.names import one_line

    lines = [f"{info['file']}  ({one_line(info['name'])}{', ' + one_line(info['split']) if info['split'] else ''})",
             f"  resolution     {info['resolution'][0]}x{info['resolution'][1]}",
             f"  duration       {info['duration_s']:.3f} s",
             f"  events         {info['events']:,}  ({info['event_rate_per_s'] / 1e6:.3f} Mev/s"
             + (f", {100 * info['positive_fraction']:.1f}% positive" if info['positive_fraction'] is not None else "")
             + (f", {info['noise_events']:,} noise" if info.get("noise_events") else "") + ")",
             f"  segments       {info['segments']} x {info['segment_ms']:g} ms, "
             f"{info['segments_with_box']} with a box ({100 * info['box_coverage']:.1f}%)"]
    if info.get("t_offset_us"):
        lines.append(f"  t_offset       {info['t_offset_us']} us (added to t for the recording's clock)")
    if info.get("ground_truth") == "annotations":
        lines.append(f"  annotations    {info['box_samples']} boxes, {info['segments_matched_to_annotation']} "
                     f"segments matched to one (only those are scored)")
    if "box_width_px" in info:
        w, h = info["box_width_px"], info["box_height_px"]
        lines.append(f"  box size       w {w[0]:.0f}/{w[1]:.0f}/{w[2]:.0f}  h {h[0]:.0f}/{h[1]:.0f}/{h[2]:.0f} px (min/median/max)")
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
