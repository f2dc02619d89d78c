"""Read an events file (and a recording's boxes) into a dataset file that bench, train and info use.

Events: .aedat4, .raw (EVT 3, or EVT 2 with --evt 2, when the header does not say), .dat (CD or 2D
events), .csv (t,x,y,p, t in whole microseconds) or .txt (t x y p, t in seconds, at most 6 decimals; a
first line "width height"); --size WxH where the file gives no sensor size (CSV, TXT without the line, a
.raw or .dat header without geometry). Every other line is an event or an error naming it: a header line
other than dvsot's own "t,x,y,p" needs --header. Timestamps are rebased to the earliest event or
annotation, which goes to /t_offset. Boxes (FE108/VisEvent style): x,y,w,h per annotated frame with
--box-times-us (one time per line) or --box-times-from-frames (the .aedat4 file's frame timestamps, FE108),
or t_s,x,y,w,h per line; --absent gives one 0/1 per box (1 = absent). Boxes stay at their annotation times
and bench scores only the segments matched to one (docs/benchmarks.md); --interpolate treats them as a
dense track instead (a file exported by dvsot).

Examples:
  dvsot import out/woman_cat.aedat4 --boxes out/woman_cat.aedat4.boxes.csv --interpolate -o out/woman_cat.h5
  dvsot import seq/events.aedat4 --boxes seq/groundtruth_rect.txt --box-times-from-frames -o data/fe108/seq.h5
  dvsot import seq/events.raw --size 640x480 --boxes seq/groundtruth.txt --box-times-us seq/frame_times.txt \\
      --absent seq/absent.txt -o data/recorded/seq.h5
"""

from __future__ import annotations

import argparse

from dvsot.core.defaults import IMPORT_EVT_VERSION, SEGMENT_US


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Flags of `dvsot import`."""
    p.add_argument("events", help="events file: .aedat4, .raw, .dat, .csv or .txt")
    p.add_argument("-o", "--output", required=True, help="dataset file to write (.h5)")
    p.add_argument("--boxes", help="box file: x,y,w,h (with --box-times-us) or t_s,x,y,w,h per line")
    p.add_argument("--box-times-us", help="annotation times, one integer microsecond per line, on the events' clock")
    p.add_argument("--box-times-from-frames", action="store_true",
                   help="annotation times are the timestamps of the .aedat4 file's frame track, one per box (FE108)")
    p.add_argument("--absent", help="absent flags, one 0/1 per box (1 = target absent)")
    p.add_argument("--size", help="sensor WIDTHxHEIGHT, for files that do not say (CSV; TXT without a size line; "
                                  ".raw or .dat whose header has no geometry)")
    p.add_argument("--segment-us", type=int, default=SEGMENT_US,
                   help=f"segment length, microseconds (default {SEGMENT_US})")
    p.add_argument("--evt", choices=["2", "3"], default=IMPORT_EVT_VERSION.removeprefix("evt"),
                   help="EVT version of a .raw file without one in its header (default "
                        f"{IMPORT_EVT_VERSION.removeprefix('evt')})")
    p.add_argument("--header", action="store_true",
                   help="the .csv/.txt file's first line is a header, not an event (dvsot's own 't,x,y,p' needs "
                        "no flag)")
    p.add_argument("--interpolate", action="store_true",
                   help="boxes are a dense track: interpolate to segment ends instead of scoring annotations only")


def run(args: argparse.Namespace) -> int:
    """Import the events and boxes; print a one-line summary."""
    from dvsot.dataset import Dataset
    from dvsot.interop.event_files import parse_size
    from dvsot.interop.recordings import import_recording

    size = parse_size(args.size, args.param_flags["size"]) if args.size else None
    path = import_recording(args.events, args.output, boxes=args.boxes, box_times=args.box_times_us,
                            absent=args.absent, size=size, segment_us=args.segment_us,
                            evt_version=f"evt{args.evt}", interpolate=args.interpolate, labels=args.param_flags,
                            box_times_from_frames=args.box_times_from_frames, header=args.header)
    with Dataset(path) as ds:
        scored = int(ds.segment_scored().sum()) if ds.annotated else None
        print(f"{path}: {ds.width}x{ds.height}, {ds.num_events:,} events, {ds.duration_us / 1e6:.3f} s, "
              f"t_offset {ds.t_offset_us} us, {ds.num_segments} segments"
              + (f", {scored} matched to an annotation" if scored is not None else ""))
    return 0
