"""Turn frames you already have (image directory, video, .npy stack) into events in a dataset file.

Examples:
  dvsot simulate frames/ --fps 1000 -o out/frames.h5
  dvsot simulate clip.mp4 -o out/clip.h5 --srgb --cp 0.25 --cn 0.25 --sigma 0.03
  dvsot simulate stack.npy --timestamps times.txt -o out/stack.h5 --refractory-us 100
"""

from __future__ import annotations

import argparse

from dvsot.defaults import SEGMENT_US


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
    p.add_argument("--segment-us", type=int, default=SEGMENT_US,
                   help=f"segment length, microseconds (default {SEGMENT_US})")
    p.add_argument("--boxes", help="optional CSV of target boxes: t_s,x,y,w,h per line (pixels)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


# EventParams field -> the flag that sets it, so that a bad value is reported by its flag
_PARAM_FLAGS = {"cp": "--cp", "cn": "--cn", "sigma_cp": "--sigma", "sigma_cn": "--sigma", "mismatch": "--mismatch",
                "refractory_us": "--refractory-us", "log_eps": "--log-eps", "shot_noise_hz": "--shot-noise-hz",
                "leak_hz": "--leak-hz"}
MAX_FPS = 1e6  # timestamps are whole microseconds: a faster rate would give frames the same time


def _event_params(args: argparse.Namespace):
    """The simulator parameters from the flags; a bad value raises UserError naming its flag."""
    from pydantic import ValidationError

    from dvsot.errors import UserError
    from dvsot.events import EventParams

    values = dict(cp=args.cp, cn=args.cn, sigma_cp=args.sigma, sigma_cn=args.sigma, mismatch=args.mismatch,
                  refractory_us=args.refractory_us, log_eps=args.log_eps, shot_noise_hz=args.shot_noise_hz,
                  leak_hz=args.leak_hz)
    try:
        return EventParams(**values)
    except ValidationError as exc:
        err = exc.errors()[0]
        field = str(err["loc"][0]) if err["loc"] else "?"
        raise UserError(f"{_PARAM_FLAGS.get(field, field)} {values.get(field)}: {err['msg']}") from None


def _check_flags(args: argparse.Namespace) -> None:
    """Range checks of the numeric flags EventParams does not cover."""
    import math

    from dvsot.errors import UserError
    from dvsot.validate import MIN_SEGMENT_US

    if not 0 <= args.seed < 2**63:  # numpy's seeds are non-negative; the file stores the seed as int64
        raise UserError(f"--seed must be >= 0 (and below 2**63), got {args.seed}")
    if args.segment_us < MIN_SEGMENT_US:
        raise UserError(f"--segment-us must be at least {MIN_SEGMENT_US} (1 ms), got {args.segment_us}")
    if args.fps is not None and not (math.isfinite(args.fps) and 0 < args.fps <= MAX_FPS):
        raise UserError(f"--fps must be positive and finite (at most {MAX_FPS:g}), got {args.fps}")


def _box_row(path: str, no: int, line: str) -> list[float]:
    """One CSV line t_s,x,y,w,h as numbers; times finite, w and h positive (or the whole box NaN: absent)."""
    import math

    from dvsot.errors import UserError
    from dvsot.frames import MAX_SECONDS

    cells = [c.strip() for c in line.split(",")]
    if len(cells) != 5:
        raise UserError(f"{path}:{no}: expected 5 columns t_s,x,y,w,h, found {len(cells)}")
    try:
        row = [float(c) for c in cells]
    except ValueError:
        raise UserError(f"{path}:{no}: not a number in {line!r} (columns t_s,x,y,w,h)") from None
    t, x, y, w, h = row
    if not (math.isfinite(t) and abs(t) < MAX_SECONDS):
        raise UserError(f"{path}:{no}: box time must be a finite number of seconds below {MAX_SECONDS:g}, "
                        f"got {cells[0]!r}")
    if all(math.isnan(v) for v in (x, y, w, h)):
        return row  # NaN box: the target is absent at this time
    if not all(math.isfinite(v) for v in (x, y, w, h)):
        raise UserError(f"{path}:{no}: x,y,w,h must be finite (or all nan for no target), got {line!r}")
    if w <= 0 or h <= 0:
        raise UserError(f"{path}:{no}: box width and height must be positive, got w={cells[3]} h={cells[4]}")
    return row


def _read_boxes(path: str, t_origin_us: int, width: int, height: int):
    """Box times (us, relative to the first frame) and x,y,w,h rows from the --boxes CSV; checked line by line."""
    import numpy as np

    from dvsot.errors import UserError
    from dvsot.frames import text_lines
    from dvsot.validate import box_problem

    numbered = text_lines(path, "boxes as CSV t_s,x,y,w,h")
    if not numbered:
        raise UserError(f"{path}: no boxes (expected lines t_s,x,y,w,h)")
    rows = np.array([_box_row(path, no, ln) for no, ln in numbered], np.float64)
    problem = box_problem(rows[:, 1:5], width, height, lambda i: f"the box on line {numbered[i][0]}")
    if problem:
        raise UserError(f"{path}: {problem}")
    t = np.rint(rows[:, 0] * 1e6).astype(np.int64) - t_origin_us
    bad = np.flatnonzero(np.diff(t) <= 0)
    if bad.size:
        raise UserError(f"{path}:{numbered[bad[0] + 1][0]}: box times must increase")
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
    from dvsot.events import EventSimulator
    from dvsot.frames import open_frames, read_timestamps
    from dvsot.outputs import output_file
    from dvsot.validate import MAX_DURATION_S, MAX_SENSOR_PIXELS
    from dvsot.simulation import simulate_frames

    params = _event_params(args)
    _check_flags(args)
    inputs = [Path(p) for p in (args.input, args.timestamps, args.boxes) if p]
    if inputs[0].is_dir():  # a frames directory: none of its files may be overwritten either
        inputs += sorted(inputs[0].iterdir())
    output_file(args.output, "-o", inputs)
    source = open_frames(args.input, srgb=args.srgb)
    if source.width * source.height > MAX_SENSOR_PIXELS:
        raise UserError(f"{args.input}: frames of {source.width}x{source.height} px, more than the bound of "
                        f"{MAX_SENSOR_PIXELS} pixels")
    if args.timestamps:
        t_us = read_timestamps(args.timestamps, source.count)
        span, what = (int(t_us[-1]) - int(t_us[0])) / 1e6 if len(t_us) else 0.0, f"{args.timestamps}: timestamps"
    else:
        fps = args.fps if args.fps is not None else source.fps
        if not fps or not 0 < fps <= MAX_FPS:  # a video's own rate: None, or whatever its header says
            raise UserError(f"{args.input}: give --fps N (positive) or --timestamps FILE")
        span = (source.count - 1) / fps  # before any array is made: a tiny rate would overflow microseconds
        what = f"--fps {args.fps:g}: {source.count} frames" if args.fps is not None else f"{args.input}: its frames"
    if span >= MAX_DURATION_S:  # ms_to_idx holds an entry per millisecond of the span
        raise UserError(f"{what} span {span:g} s, more than the bound of {MAX_DURATION_S} s per dataset file")
    if not args.timestamps:
        t_us = np.rint(np.arange(source.count) * 1e6 / fps).astype(np.int64)
    if source.count < 2:
        raise UserError(f"{args.input}: need at least two frames, found {source.count}")
    t0 = int(t_us[0])
    t_us = t_us - t0
    boxes = _read_boxes(args.boxes, t0, source.width, source.height) if args.boxes else None

    sim = EventSimulator(source.width, source.height, params, args.seed)
    attrs = {"name": Path(args.output).name.removesuffix(".h5"), "split": "", "source": str(args.input),
             "simulator": params.model_dump(), "seed": args.seed, "generator": "dvsot simulate",
             "versions": {"dvsot": __version__, "numpy": np.__version__}}
    start = time.perf_counter()
    with DatasetWriter(args.output, source.width, source.height, args.segment_us, attrs) as writer:
        bar = tqdm(total=source.count, unit="frame", disable=args.quiet, desc="simulate")

        def progress(done: int, events: int) -> None:
            bar.update(1)
            bar.set_postfix(events=events, refresh=False)

        # log intensities (or 8/16-bit images and their log table) from the decoding threads, taken as they are
        counts = simulate_frames(source.log_frames(params.log_eps, coded=True), t_us, sim, writer, str(args.input),
                                 progress, is_log=True)
        bar.close()
        if counts.frames != source.count:
            raise UserError(f"{args.input}: expected {source.count} frames, read {counts.frames}")
        if boxes is not None:
            writer.append_boxes(boxes[0], boxes[1])
        n_events, n_pos = counts.events, counts.positive
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
