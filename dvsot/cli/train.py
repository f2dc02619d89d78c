"""Train SCTN, its ANN twin or an ANN tracker on ATSLTD frames on dataset files' training split; write a checkpoint.

With no flags it trains the recipe the shipped checkpoints are trained with (sctn.training.snn.TrainConfig's
defaults). The command parses its flags and calls the library: benchmarks.train_model (the training registry's model,
the checks, validation, the checkpoint; benchmarks/training/).

Examples:
  dvsot train --data data/dvsot21 -o runs/sctn.pt
  dvsot train --data 'data/dvsot21/*.h5' --epochs 2 --loss linear --seed 3 -o runs/sctn_linear.pt
  dvsot train --model sctn_ann -o runs/sctn_ann.pt        # SCTN's layers with ReLU, trained the same way
  dvsot train --model siamfc -o runs/siamfc.pt            # SiamFC on ATSLTD frames
  dvsot train --val-data data/val --val-every 50 --val-arscore-every 200 -o runs/sctn.pt  # learning curves (any model)
"""

from __future__ import annotations

import argparse


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Flags of `dvsot train`."""
    from benchmarks.training.registry import TRAINERS

    frame_models = ", ".join(m for m in TRAINERS if m not in ("sctn", "sctn_ann"))
    p.add_argument("--model", choices=list(TRAINERS), default="sctn",
                   help=f"a model of the training registry: sctn (default), sctn_ann (SCTN's layers with ReLU), "
                        f"or on ATSLTD frames {frame_models}")
    p.add_argument("--data", nargs="+", default=["data/dvsot21"], help="dataset files, directories or globs")
    p.add_argument("--split", default="train", help="split attribute to train on, or 'any' (default train)")
    p.add_argument("-o", "--output", default=None, help="checkpoint to write (default runs/<model>.pt)")
    p.add_argument("--epochs", type=int, default=None,
                   help="default: the model's recipe (sctn, sctn_ann: sctn.training.snn.TrainConfig)")
    p.add_argument("--segments-per-epoch", type=int, default=None,
                   help="default: the model's recipe (siamfc: search segments)")
    p.add_argument("--batch-segments", type=int, default=None,
                   help="segments per step (sctn: 60 samples each; siamfc: pairs); default: the model's recipe")
    p.add_argument("--lr", type=float, default=None, help="Adam's rate; default: the model's recipe")
    p.add_argument("--lr-schedule", choices=["constant", "cosine"], default=None,
                   help="constant (default) or cosine: from --lr to 0 over the planned steps (an ablation row)")
    p.add_argument("--loss", choices=["exp", "linear", "basic"], default=None, help="default exp (sctn, sctn_ann)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--max-minutes", type=float, default=None, help="stop after this much training time")
    p.add_argument("--channels", type=int, nargs=3, metavar="C", default=None,
                   help="output channels of the three convolutions (default: sctn.network.NetworkConfig)")
    p.add_argument("--fc", type=int, nargs=2, metavar="N", default=None,
                   help="widths of the two hidden fully connected layers (default: sctn.network.NetworkConfig)")
    p.add_argument("--ops-penalty", type=float, default=None, metavar="L",
                   help="sctn: add L x synaptic operations per sample, in millions, to the loss (default 0)")
    p.add_argument("--squared-error", action="store_true", default=None,
                   help="deviation from the paper: square each sample's eq.-5 error (an ablation row)")
    p.add_argument("--background-term", action="store_true", default=None,
                   help="deviation from the paper: add the mirrored background-neuron error (an ablation row)")
    p.add_argument("--no-background-neuron", action="store_true", default=None,
                   help="deviation from the paper: leave the background output neuron out of the network and its "
                        "operation counts (an ablation row)")
    p.add_argument("--calibrate", action="store_true", default=None,
                   help="sctn: the same as --init calibrate")
    p.add_argument("--init", choices=["kaiming", "calibrate", "fluctuation"], default=None,
                   help="sctn: initial weights: kaiming (default), calibrate (data-driven scale per layer) or "
                        "fluctuation (Rossbroich et al. 2022: V's fluctuations theta / xi on a first batch)")
    p.add_argument("--fluctuation-xi", type=float, default=None, metavar="XI",
                   help="sctn, --init fluctuation: theta over the initial standard deviation of V (default 2)")
    p.add_argument("--error-time", choices=["stca", "stca_code", "max"], default=None,
                   help="the step each sample's error sits at: stca (default; STCA's rule), stca_code (its authors' "
                        "code's edge cases) or max (V's maximum over all steps, the rule before it): ablation rows")
    p.add_argument("--val-data", nargs="+", default=None, metavar="DIR",
                   help="validation files, directories or globs (any split): validate on them instead of every "
                        "10th training segment, which then all train")
    p.add_argument("--val-every", type=int, default=None, metavar="K",
                   help="validate every K steps (default: the model's recipe)")
    p.add_argument("--val-segments", type=int, default=None, metavar="M",
                   help="validation segments, spread over the files (default: the model's recipe)")
    p.add_argument("--val-arscore-every", type=int, default=None, metavar="K",
                   help="with --val-data: also track the validation sequences every K steps and at the end, and "
                        "record their ARscore (sctn, sctn_ann: a copy of the network, fine-tuned as the tracker "
                        "does; siamfc: the network as it is)")
    p.add_argument("--val-arscore-segments", type=int, default=None, metavar="N",
                   help="with --val-arscore-every: track at most N segments of each validation sequence")
    p.add_argument("--tail-steps", type=int, default=None,
                   help="sctn, deviation from the paper: empty steps after the 10 ms window (default 0)")
    p.add_argument("--bias", action="store_true", default=None,
                   help="deviation from the paper: layers with biases (an empty input can then fire)")
    p.add_argument("--input", choices=["bins", "sum"], default=None,
                   help="sctn_ann: the ten 1-ms bins as 20 channels (default) or their sum (2 channels)")
    p.add_argument("--threads", type=int, default=None, help="torch CPU threads (default: torch's choice)")
    p.add_argument("--quiet", action="store_true")


def run(args: argparse.Namespace) -> int:
    """Train, then save the checkpoint (atomically) with its provenance; print the run's summary as JSON."""
    import json

    from benchmarks.training.registry import setting_names
    from benchmarks.training.run import train_model

    settings = {k: getattr(args, k) for k in setting_names() if hasattr(args, k)}
    summary = train_model(args.model, args.data, args.output, split=args.split, val_data=args.val_data,
                          val_arscore_segments=args.val_arscore_segments, threads=args.threads,
                          progress=not args.quiet, labels=args.param_flags, **settings)
    print(json.dumps(summary))
    return 0
