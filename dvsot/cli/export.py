"""Write a dataset file's events to a file other event-camera tools read, with its box track beside it as CSV.

The format follows the suffix: .aedat4 (iniVation DV), .raw (Prophesee EVT 2, or EVT 3 with --evt 3),
.dat (Prophesee DAT 2), .csv (t,x,y,p with t in microseconds; a file with per-event labels adds an object column,
and its object table goes to OUT.objects.csv as id,name,role), .txt (rpg/ESIM: first line "width
height", then "t x y p" with t in seconds). Timestamps are the recording's own clock (t + /t_offset).
The boxes go to OUT.boxes.csv as t_s,x,y,w,h (nan = no target), which `dvsot import --boxes` reads.
OUT is the output's full name: -o x.csv writes x.csv.boxes.csv (and x.csv.objects.csv). The side files are
replaced with the events in one step; one that this export does not write, left by an earlier export of the
same output, is removed then.

Examples:
  dvsot export data/dvsot21/woman_cat.h5 -o out/woman_cat.aedat4
  dvsot export data/dvsot21/woman_cat.h5 -o out/woman_cat.raw --evt 3
"""

from __future__ import annotations

import argparse


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Flags of `dvsot export`."""
    p.add_argument("file", help="dataset file (.h5)")
    p.add_argument("-o", "--output", required=True, help="events file to write: .aedat4, .raw, .dat, .csv or .txt")
    from dvsot.core.defaults import EXPORT_EVT_VERSION

    default = EXPORT_EVT_VERSION.removeprefix("evt")
    p.add_argument("--evt", choices=["2", "3"], default=default,
                   help=f"EVT version of a .raw file (default {default}: expelliarmus misreads EVT 3 times)")
    p.add_argument("--no-boxes", action="store_true", help="do not write OUT.boxes.csv (e.g. x.csv.boxes.csv)")


def run(args: argparse.Namespace) -> int:
    """Export the events (and boxes); print what was written."""
    from dvsot.interop.event_files import export_dataset

    for path in export_dataset(args.file, args.output, evt_version=f"evt{args.evt}", boxes=not args.no_boxes,
                               labels=args.param_flags):
        print(path)
    return 0
