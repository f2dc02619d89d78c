"""Train SCTN on the training split of dataset files and write a checkpoint.

Examples:
  dvsot train --data data/dvsot21 -o runs/sctn.pt
  dvsot train --data 'data/dvsot21/*.h5' --epochs 2 --loss linear --seed 3 -o runs/sctn_linear.pt
"""

from __future__ import annotations

import argparse


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Flags of `dvsot train`."""
    p.add_argument("--data", nargs="+", default=["data/dvsot21"], help="dataset files, directories or globs")
    p.add_argument("--split", default="train", help="split attribute to train on, or 'any' (default train)")
    p.add_argument("-o", "--output", default="runs/sctn.pt", help="checkpoint to write")
    p.add_argument("--epochs", type=int, default=3)
    p.add_argument("--segments-per-epoch", type=int, default=400)
    p.add_argument("--batch-segments", type=int, default=4, help="segments per step (60 samples each)")
    p.add_argument("--lr", type=float, default=2e-3)
    p.add_argument("--loss", choices=["exp", "linear", "basic"], default="exp")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--max-minutes", type=float, default=None, help="stop after this much training time")
    p.add_argument("--channels", type=int, nargs=3, metavar="C", default=None,
                   help="output channels of the three convolutions (default: sctn.network.NetworkConfig)")
    p.add_argument("--fc", type=int, nargs=2, metavar="N", default=None,
                   help="widths of the two hidden fully connected layers (default: sctn.network.NetworkConfig)")
    p.add_argument("--ops-penalty", type=float, default=0.0, metavar="L",
                   help="add L x synaptic operations per sample, in millions, to the loss (lower energy; default 0)")
    p.add_argument("--squared-error", action="store_true",
                   help="deviation from the paper: square each sample's eq.-5 error (an ablation row)")
    p.add_argument("--background-term", action="store_true",
                   help="deviation from the paper: add the mirrored background-neuron error (an ablation row)")
    p.add_argument("--no-calibration", action="store_true",
                   help="initialise without the data-driven weight scaling (an ablation row)")
    p.add_argument("--tail-steps", type=int, default=0,
                   help="deviation from the paper: empty steps after the 10 ms window (default 0)")
    p.add_argument("--bias", action="store_true",
                   help="deviation from the paper: layers with biases (an empty input can then fire)")
    p.add_argument("--threads", type=int, default=None, help="torch CPU threads (default: torch's choice)")
    p.add_argument("--quiet", action="store_true")


def _network_config(args: argparse.Namespace):
    """The network's layer sizes from --channels / --fc (NetworkConfig's defaults otherwise)."""
    from dvsot.errors import UserError
    from sctn.network import NetworkConfig

    if args.tail_steps < 0:
        raise UserError(f"--tail-steps must be >= 0, got {args.tail_steps}")
    net = {"tail_steps": args.tail_steps, "bias": args.bias}
    for name in ("channels", "fc"):
        sizes = getattr(args, name)
        if sizes is not None:
            if min(sizes) < 1:
                raise UserError(f"--{name} sizes must be >= 1, got {' '.join(map(str, sizes))}")
            net[name] = tuple(sizes)
    return NetworkConfig(**net)


def _train_config(args: argparse.Namespace):
    """The training settings from the flags; an out-of-range value raises UserError naming its flag."""
    from dvsot.errors import UserError
    from sctn.train import TrainConfig, TrainConfigError

    try:
        return TrainConfig(epochs=args.epochs, segments_per_epoch=args.segments_per_epoch,
                           batch_segments=args.batch_segments, lr=args.lr, loss=args.loss, seed=args.seed,
                           max_minutes=args.max_minutes, ops_penalty=args.ops_penalty,
                           squared_error=args.squared_error, background_term=args.background_term,
                           calibrate=not args.no_calibration, network=_network_config(args))
    except TrainConfigError as exc:  # every field set here is the flag of the same name
        raise UserError(f"--{exc.field.replace('_', '-')} {exc.problem}") from None


def run(args: argparse.Namespace) -> int:
    """Train, then save the checkpoint (atomically) with its provenance."""
    import json

    import torch

    from dvsot.dataset import find_datasets
    from dvsot.errors import UserError
    from sctn.checkpoint import check_checkpoint_output, save_checkpoint
    from sctn.train import provenance, train

    cfg = _train_config(args)
    if args.threads is not None and args.threads < 1:
        raise UserError(f"--threads must be >= 1, got {args.threads}")
    files = find_datasets(args.data, split=None if args.split == "any" else args.split, need_events=True)
    out = check_checkpoint_output(args.output, "-o", inputs=files)
    if args.threads:
        torch.set_num_threads(args.threads)
    try:
        model, history = train(files, cfg, progress=not args.quiet)
    except ValueError as exc:
        raise UserError(f"{', '.join(map(str, args.data))}: {exc}") from None
    save_checkpoint(out, model, provenance(files, cfg, history))
    final = history["val"][-1] if history["val"] else {}
    print(json.dumps({"checkpoint": str(out), "steps": history["steps"], "minutes": round(history["minutes"], 2),
                      "train_segments": history["train_segments"], "val": final}))
    return 0
