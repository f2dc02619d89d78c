"""Write a trained SCTN checkpoint as a NIR graph (Neuromorphic Intermediate Representation) for other SNN tools.

C-LIF becomes NIR's CubaLIF with its time constants converted for a 1 ms step; the input encoding (the
events inside a candidate box on SCTN's canvas) stays outside the graph. docs/nir.md says how to run the
file in Norse or on a chip's toolchain, and what NIR cannot express of C-LIF (the reset by subtraction).

Examples:
  dvsot export-model sctn/checkpoints/sctn_dvsot21.pt -o sctn.nir
  dvsot export-model runs/sctn.pt -o sctn_euler.nir --discretisation euler   # for forward-Euler simulators
"""

from __future__ import annotations

import argparse


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Flags of `dvsot export-model`."""
    p.add_argument("checkpoint", help="SCTN checkpoint (.pt) written by `dvsot train`")
    p.add_argument("-o", "--output", required=True, help="NIR file to write (HDF5, conventionally .nir)")
    p.add_argument("--discretisation", choices=["exact", "euler"], default="exact",
                   help="exact (default): C-LIF's continuous time constants, exact for simulators that integrate "
                        "each 1 ms step exactly; euler: constants for which forward Euler at dt = 1 ms is C-LIF "
                        "(Norse's from_nir)")


def run(args: argparse.Namespace) -> int:
    """Export the checkpoint; print the path written."""
    from sctn import export_nir

    print(export_nir(args.checkpoint, args.output, args.discretisation))
    return 0
