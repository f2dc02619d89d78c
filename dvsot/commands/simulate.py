"""Turn frames you already have (image directory, video, .npy stack) into events in a dataset file.

Examples:
  dvsot simulate frames/ --fps 1000 -o out/frames.h5
  dvsot simulate clip.mp4 -o out/clip.h5 --srgb --cp 0.25 --cn 0.25 --sigma 0.03
  dvsot simulate stack.npy --timestamps times.txt -o out/stack.h5 --refractory-us 100
"""

from __future__ import annotations

import argparse


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Flags of `dvsot simulate`."""
    p.add_argument("input", help="directory of images (sorted by name), a video file, or a .npy (T,H,W) stack")
    p.add_argument("-o", "--output", required=True, help="dataset file to write (.h5)")
    timing = p.add_mutually_exclusive_group()
    timing.add_argument("--fps", type=float, help="frame rate (frames per second); default: the video's own")
    timing.add_argument("--timestamps", help="file of timestamps in seconds, one per line (as ESIM reads them)")
    p.add_argument("--cp", type=float, default=0.2, help="ON contrast threshold, log intensity (default 0.2)")
    p.add_argument("--cn", type=float, default=0.2, help="OFF contrast threshold, log intensity (default 0.2)")
    p.add_argument("--sigma", type=float, default=0.0, help="per-pixel threshold std, log intensity (default 0)")
    p.add_argument("--mismatch", choices=["fixed", "per_interval"], default="fixed",
                   help="draw per-pixel thresholds once (fixed) or every interval, as ESIM (per_interval)")
    p.add_argument("--refractory-us", type=float, default=0.0, help="refractory period, microseconds (default 0)")
    p.add_argument("--log-eps", type=float, default=1e-3, help="eps in log(I + eps) (default 1e-3)")
    p.add_argument("--shot-noise-hz", type=float, default=0.0, help="shot-noise events per pixel per second")
    p.add_argument("--leak-hz", type=float, default=0.0, help="leak events per pixel per second")
    p.add_argument("--srgb", action="store_true", help="undo the sRGB curve of 8/16-bit input before use")
    p.add_argument("--seed", type=int, default=0, help="random seed (thresholds, noise)")
    p.add_argument("--segment-us", type=int, default=10_000, help="segment length, microseconds (default 10000)")
    p.add_argument("--boxes", help="optional CSV of target boxes: t_s,x,y,w,h per line (pixels)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def _read_boxes(path: str, t_origin_us: int):
    import numpy as np

    from dvsot.errors import UserError

    try:
        rows = np.loadtxt(path, delimiter=",", ndmin=2, comments="#")
    except (OSError, ValueError) as exc:
        raise UserError(f"{path}: cannot read boxes as CSV t_s,x,y,w,h ({' '.join(str(exc).split())})") from None
    if rows.shape[1] != 5:
        raise UserError(f"{path}: expected 5 columns t_s,x,y,w,h, found {rows.shape[1]}")
    t = np.rint(rows[:, 0] * 1e6).astype(np.int64) - t_origin_us
    if np.any(np.diff(t) <= 0):
        raise UserError(f"{path}: box times must increase")
    return t, rows[:, 1:5]


def run(args: argparse.Namespace) -> int:
    """Stream frames through the event simulator into a dataset file; print a summary."""
    import json
    import time
    from pathlib import Path

    import numpy as np
    from tqdm import tqdm

    from dvsot import __version__
    from dvsot.dataset import DatasetWriter
    from dvsot.errors import UserError
    from dvsot.events import EventParams, EventSimulator
    from dvsot.frames import open_frames, read_timestamps

    params = EventParams.parse(dict(cp=args.cp, cn=args.cn, sigma_cp=args.sigma, sigma_cn=args.sigma,
                                    mismatch=args.mismatch, refractory_us=args.refractory_us,
                                    log_eps=args.log_eps, shot_noise_hz=args.shot_noise_hz,
                                    leak_hz=args.leak_hz), "command line")
    if args.segment_us <= 0:
        raise UserError(f"command line: --segment-us must be positive, got {args.segment_us}")
    source = open_frames(args.input, srgb=args.srgb)
    if args.timestamps:
        t_us = read_timestamps(args.timestamps, source.count)
    else:
        fps = args.fps or source.fps
        if not fps or fps <= 0:
            raise UserError(f"{args.input}: give --fps N (positive) or --timestamps FILE")
        t_us = np.rint(np.arange(source.count) * 1e6 / fps).astype(np.int64)
    if source.count < 2:
        raise UserError(f"{args.input}: need at least two frames, found {source.count}")
    t0 = int(t_us[0])
    t_us = t_us - t0
    boxes = _read_boxes(args.boxes, t0) if args.boxes else None

    sim = EventSimulator(source.width, source.height, params, args.seed)
    attrs = {"name": Path(args.output).name.removesuffix(".h5"), "split": "", "source": str(args.input),
             "simulator": params.model_dump(), "seed": args.seed, "generator": "dvsot simulate",
             "versions": {"dvsot": __version__, "numpy": np.__version__}}
    start = time.perf_counter()
    n_pos = 0
    with DatasetWriter(args.output, source.width, source.height, args.segment_us, attrs) as writer:
        bar = tqdm(total=source.count, unit="frame", disable=args.quiet, desc="simulate")
        for i, frame in enumerate(source.frames()):
            try:
                batch = sim.step(frame, int(t_us[i]))
            except UserError as exc:
                raise UserError(f"{args.input}: frame {i}: {exc}") from None
            writer.append_events(batch)
            n_pos += int(np.count_nonzero(batch.p))
            bar.update(1)
            bar.set_postfix(events=writer.num_events, refresh=False)
        bar.close()
        if i + 1 != source.count:
            raise UserError(f"{args.input}: expected {source.count} frames, read {i + 1}")
        if boxes is not None:
            writer.append_boxes(boxes[0], boxes[1])
        n_events = writer.num_events
        path = writer.close(int(t_us[-1]) + 1)
    wall = time.perf_counter() - start
    duration = (int(t_us[-1]) + 1) / 1e6
    summary = {"output": str(path), "frames": source.count, "resolution": f"{source.width}x{source.height}",
               "duration_s": round(duration, 6), "events": n_events,
               "event_rate_per_s": round(n_events / duration, 1),
               "positive_fraction": round(n_pos / n_events, 4) if n_events else None,
               "wall_s": round(wall, 3)}
    print(json.dumps(summary) if args.quiet else "\n".join(f"{k:>18}: {v}" for k, v in summary.items()))
    return 0
