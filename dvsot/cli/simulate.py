"""Turn frames you already have (image directory, video, .npy stack) into events in a dataset file.

Examples:
  dvsot simulate frames/ --fps 1000 -o out/frames.h5
  dvsot simulate clip.mp4 -o out/clip.h5 --srgb --cp 0.25 --cn 0.25 --sigma 0.03
  dvsot simulate stack.npy --timestamps times.txt -o out/stack.h5 --refractory-us 100
  dvsot simulate frames/ --fps 1000 -o out/frames.h5 --preset davis346 --leak-hz 0.5
"""

from __future__ import annotations

import argparse

from dvsot.core.defaults import SEGMENT_US


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Flags of `dvsot simulate`."""
    p.add_argument("input", help="directory of images (sorted by name), a video file, or a .npy (T,H,W) stack")
    p.add_argument("-o", "--output", required=True, help="dataset file to write (.h5)")
    timing = p.add_mutually_exclusive_group()
    timing.add_argument("--fps", type=float, help="frame rate (frames per second); default: the video's own")
    timing.add_argument("--timestamps", help="file of timestamps in seconds, one per line (as ESIM reads them)")
    p.add_argument("--preset", help="sensor model the other simulator flags start from: ideal (default, ESIM's "
                                    "pixel), clean, noisy (v2e's), davis346, gen4 (docs/events.md)")
    # each simulator flag left out keeps the preset's value
    p.add_argument("--cp", type=float, help="ON contrast threshold, log intensity (ideal: 0.2)")
    p.add_argument("--cn", type=float, help="OFF contrast threshold, log intensity (ideal: 0.2)")
    p.add_argument("--sigma", type=float, help="per-pixel threshold std, log intensity (ideal: 0)")
    p.add_argument("--mismatch", choices=["fixed", "per_interval"],
                   help="draw per-pixel thresholds once (fixed) or every interval, as ESIM (per_interval)")
    p.add_argument("--refractory-us", type=float, help="refractory period, microseconds (ideal: 0)")
    p.add_argument("--log-eps", type=float, help="eps in log(I + eps) (default 1e-3)")
    p.add_argument("--shot-noise-hz", type=float, help="shot-noise events per pixel per second (ideal: 0)")
    p.add_argument("--leak-hz", type=float, help="leak events per pixel per second (ideal: 0)")
    for field, (kind, text) in _STAGE_FLAGS.items():
        p.add_argument("--" + field.replace("_", "-"), type=kind, help=text)
    p.add_argument("--srgb", action="store_true", help="undo the sRGB curve of 8/16-bit input before use")
    p.add_argument("--seed", type=int, default=0, help="random seed (thresholds, noise)")
    p.add_argument("--segment-us", type=int, default=SEGMENT_US,
                   help=f"segment length, microseconds (default {SEGMENT_US})")
    p.add_argument("--boxes", help="optional CSV of target boxes: t_s,x,y,w,h per line (pixels)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


# the sensor model's fields (dvsot.events.sensor), each with a flag of its name: its type and help (numpy and numba
# are not imported for --help)
_STAGE_FLAGS = {
    "linlog_intensity": (float, "intensity (1 = full scale) below which the photoreceptor is linear (ideal: 0, log)"),
    "lowpass_order": (int, "photoreceptor low-pass stages: 0 (ideal), 1 or 2"),
    "lowpass_cutoff_hz": (float, "low-pass 3 dB cutoff at full-scale intensity, Hz"),
    "photoreceptor_noise_hz": (float, "noise events per pixel per second from Gaussian photoreceptor noise "
                                      "(ideal: 0, off; needs --lowpass-order)"),
    "dark_intensity": (float, "dark current as an intensity (1 = full scale; default 20/255, v2e's)"),
    "shot_noise_bright_factor": (float, "shot-noise rate at full-scale intensity over the rate in the dark "
                                        "(ideal: 1)"),
    "leak_spread_decades": (float, "std of log10 of the pixels' leak rates, decades (ideal: 0)"),
    "leak_period_cv": (float, "coefficient of variation of leak periods (ideal: 1, Poisson; 0 periodic)"),
    "hot_pixel_fraction": (float, "fraction of pixels that are hot, 0..1 (ideal: 0)"),
    "hot_pixel_hz": (float, "events per second of a hot pixel"),
    "latency_us": (float, "delay of every event, microseconds (ideal: 0)"),
    "latency_jitter_us": (float, "std of the delay, microseconds (ideal: 0)"),
    "readout_limit_hz": (float, "events per second the readout passes (ideal: 0, unlimited; else >= 1)"),
    "readout_fifo_events": (int, "events waiting for the readout before new ones are dropped (0: none dropped)"),
}
def run(args: argparse.Namespace) -> int:
    """Stream frames through the event simulator into a dataset file; print a summary."""
    import json

    from dvsot.pipeline.simulate import simulate_file

    params = dict(preset=args.preset, cp=args.cp, cn=args.cn, sigma_cp=args.sigma, sigma_cn=args.sigma,
                  mismatch=args.mismatch, refractory_us=args.refractory_us, log_eps=args.log_eps,
                  shot_noise_hz=args.shot_noise_hz, leak_hz=args.leak_hz,
                  **{field: getattr(args, field) for field in _STAGE_FLAGS})
    summary = simulate_file(args.input, args.output, params, args.seed, fps=args.fps, timestamps=args.timestamps,
                            boxes=args.boxes, srgb=args.srgb, segment_us=args.segment_us, progress=not args.quiet,
                            labels=args.param_flags)
    print(json.dumps(summary) if args.quiet else "\n".join(f"{k:>18}: {v}" for k, v in summary.items()))
    return 0
