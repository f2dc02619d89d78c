"""How the commands name the library's parameters: the one place a parameter's name becomes a flag.

Library messages name parameters (`out_path`, `segments_per_epoch`); each command passes the table of its own
parser as the library's `labels`, so its messages name its flags (`-o`, `--segments-per-epoch`) instead.
"""

from __future__ import annotations

import argparse

# library parameters whose flag is not the parameter's own name as a long option
RENAMED = {"out_path": "-o", "out": "-o", "output": "-o", "box_times": "--box-times-us", "sigma_cp": "--sigma",
           "sigma_cn": "--sigma"}


def flag_labels(parser: argparse.ArgumentParser) -> dict[str, str]:
    """{parameter: flag} of a command's parser: each option's destination names its long flag, plus RENAMED."""
    labels = {}
    for action in parser._actions:
        long = [s for s in action.option_strings if s.startswith("--")]
        if long and action.dest != "help":
            labels[action.dest] = long[0]
    return {**labels, **RENAMED}
