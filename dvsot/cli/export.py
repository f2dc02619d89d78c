"""Write a dataset file's events to a file other event-camera tools read, with its box track and per-segment ground
truth beside it as CSV; or datasets' ground truth and challenge tags in the GOT-10k, LaSOT or VOT layout.

The format follows the suffix: .aedat4 (iniVation DV), .raw (Prophesee EVT 2, or EVT 3 with --evt 3),
.dat (Prophesee DAT 2), .csv (t,x,y,p with t in microseconds; a file with per-event labels adds an object column,
and its object table goes to OUT.objects.csv as id,name,role), .txt (rpg/ESIM: first line "width
height", then "t x y p" with t in seconds). Timestamps are the recording's own clock (t + /t_offset).
The boxes go to OUT.boxes.csv as t_s,x,y,w,h (nan = no target), which `dvsot import --boxes` reads; the
ground truth per segment to OUT.gt.csv: segment, t_s (its end), amodal and visible box, visibility,
truncation, absent and the challenge tags (0/1) the file can decide (docs/dataset-files.md).
OUT is the output's full name: -o x.csv writes x.csv.boxes.csv, x.csv.gt.csv (and x.csv.objects.csv). The side
files are replaced with the events in one step; one that this export does not write, left by an earlier export
of the same output, is removed then. Formats other than .csv have no field for per-event labels: a note on
stderr says they are left out.

With --layout got10k|lasot|vot, FILE may be a directory or glob of dataset files and -o names a directory: each
sequence's ground truth and tag files (GOT-10k's absence/cover/cut_by_image.label, LaSOT's full_occlusion.txt
and out_of_view.txt, VOT's .tag files), one line per segment.

Examples:
  dvsot export data/dvsot21/woman_cat.h5 -o out/woman_cat.aedat4
  dvsot export data/dvsot21/woman_cat.h5 -o out/woman_cat.raw --evt 3
  dvsot export data/dvsot21 --layout got10k -o out/got10k/val
"""

from __future__ import annotations

import argparse


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Flags of `dvsot export`."""
    from dvsot.interop.toolkit_layouts import LAYOUTS

    p.add_argument("file", help="dataset file (.h5); with --layout also a directory or glob of them")
    p.add_argument("-o", "--output", required=True,
                   help="events file to write: .aedat4, .raw, .dat, .csv or .txt; with --layout, a directory")
    from dvsot.core.defaults import EXPORT_EVT_VERSION

    default = EXPORT_EVT_VERSION.removeprefix("evt")
    p.add_argument("--evt", choices=["2", "3"], default=default,
                   help=f"EVT version of a .raw file (default {default}: expelliarmus misreads EVT 3 times)")
    p.add_argument("--no-boxes", action="store_true",
                   help="do not write OUT.boxes.csv and OUT.gt.csv (e.g. x.csv.boxes.csv)")
    p.add_argument("--layout", choices=LAYOUTS,
                   help="write the ground truth and tags of every dataset file FILE names in this toolkit's "
                        "per-sequence layout into the directory -o (no events)")


def run(args: argparse.Namespace) -> int:
    """Export the events (and boxes and ground truth), or the ground truth in a layout; print what was written."""
    from dvsot.core.errors import UserError
    from dvsot.interop.event_files import export_dataset
    from dvsot.interop.toolkit_layouts import export_layout

    if args.layout:
        if args.no_boxes:
            raise UserError("--no-boxes: a --layout export is the ground truth; leave one of them out")
        written = export_layout(args.file, args.output, args.layout, labels={"out_dir": "-o", "layout": "--layout"})
    else:
        written = export_dataset(args.file, args.output, evt_version=f"evt{args.evt}", boxes=not args.no_boxes,
                                 labels=args.param_flags)
    for path in written:
        print(path)
    return 0
