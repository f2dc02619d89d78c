"""Train SCTN (or its ANN twin, or SiamFC) on the training split of dataset files and write a checkpoint.

Examples:
  dvsot train --data data/dvsot21 -o runs/sctn.pt
  dvsot train --data 'data/dvsot21/*.h5' --epochs 2 --loss linear --seed 3 -o runs/sctn_linear.pt
  dvsot train --model sctn_ann -o runs/sctn_ann.pt        # SCTN's layers with ReLU, trained the same way
  dvsot train --model siamfc -o runs/siamfc.pt            # SiamFC on ATSLTD frames
  dvsot train --val-data data/val --val-every 50 --val-arscore-every 200 -o runs/sctn.pt  # learning curves (any model)
"""

from __future__ import annotations

import argparse

MODELS = ("sctn", "sctn_ann", "siamfc")
SCTN_LIKE = ("sctn", "sctn_ann")
# flags that only some models have: {flag dest: models}; a flag is given when its value is not None
ONLY = {"loss": SCTN_LIKE, "channels": SCTN_LIKE, "fc": SCTN_LIKE, "squared_error": SCTN_LIKE,
        "background_term": SCTN_LIKE, "no_background_neuron": SCTN_LIKE, "bias": SCTN_LIKE,
        "ops_penalty": ("sctn",), "calibrate": ("sctn",), "tail_steps": ("sctn",), "input": ("sctn_ann",),
        "error_time": SCTN_LIKE, "init": ("sctn",),
        "fluctuation_xi": ("sctn",)}


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Flags of `dvsot train`."""
    p.add_argument("--model", choices=MODELS, default="sctn",
                   help="sctn (default), sctn_ann (SCTN's layers with ReLU) or siamfc (on ATSLTD frames)")
    p.add_argument("--data", nargs="+", default=["data/dvsot21"], help="dataset files, directories or globs")
    p.add_argument("--split", default="train", help="split attribute to train on, or 'any' (default train)")
    p.add_argument("-o", "--output", default=None, help="checkpoint to write (default runs/<model>.pt)")
    p.add_argument("--epochs", type=int, default=None, help="default: the model's (sctn 3, siamfc 20)")
    p.add_argument("--segments-per-epoch", type=int, default=None, help="default 400 (siamfc: search segments)")
    p.add_argument("--batch-segments", type=int, default=None,
                   help="segments per step (sctn: 60 samples each, default 4; siamfc: pairs, default 8)")
    p.add_argument("--lr", type=float, default=None, help="default: the model's (sctn 2e-3, siamfc 1e-3)")
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
    p.add_argument("--val-every", type=int, default=None, metavar="K", help="validate every K steps (default 50)")
    p.add_argument("--val-segments", type=int, default=None, metavar="M",
                   help="validation segments, spread over the files (default 40)")
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


MAX_WIDTH = 1024  # --channels and --fc: weights and activations grow with them (1024 x 107^2 x T: 0.5 GB a sample)


def _network_config(args: argparse.Namespace):
    """The network's layer sizes from --channels / --fc (NetworkConfig's defaults otherwise); the twin's TwinConfig."""
    from dvsot.errors import UserError
    from sctn.ann import TwinConfig
    from sctn.network import NetworkConfig

    from dvsot.limits import MAX_TAIL_STEPS, range_problem

    tail = args.tail_steps or 0
    problem = range_problem("--tail-steps", tail, 0, MAX_TAIL_STEPS, "steps of 1 ms")
    if problem:
        raise UserError(problem)
    net = {"tail_steps": tail, "bias": bool(args.bias), "background_neuron": not args.no_background_neuron}
    for name in ("channels", "fc"):
        sizes = getattr(args, name)
        if sizes is not None:
            if min(sizes) < 1 or max(sizes) > MAX_WIDTH:  # bounded: the weights are allocated from these
                raise UserError(f"--{name} sizes must be between 1 and {MAX_WIDTH} (the bound), "
                                f"got {' '.join(map(str, sizes))}")
            net[name] = tuple(sizes)
    if args.model == "sctn_ann":
        return TwinConfig(**net, input=args.input or "bins")
    return NetworkConfig(**net)


def _train_config(args: argparse.Namespace):
    """The model's training settings from the flags; a flag the model lacks or an out-of-range value raises
    UserError naming the flag."""
    from dvsot.errors import UserError
    from sctn.training.snn import TrainConfig, TrainConfigError

    for dest, models in ONLY.items():
        if getattr(args, dest) is not None and args.model not in models:
            raise UserError(f"--{dest.replace('_', '-')}: not a setting of --model {args.model} "
                            f"(only of {', '.join(models)})")
    common = {k: getattr(args, k) for k in ("epochs", "segments_per_epoch", "batch_segments", "lr", "lr_schedule",
                                            "val_every", "val_segments", "val_arscore_every")
              if getattr(args, k) is not None}
    common.update(seed=args.seed, max_minutes=args.max_minutes)
    try:
        if args.model == "siamfc":
            from benchmarks.trackers.siamfc.train import SiamFCTrainConfig

            return SiamFCTrainConfig(**common)
        extra = {k: getattr(args, k) for k in ("error_time", "init", "fluctuation_xi")
                 if getattr(args, k) is not None}
        return TrainConfig(**common, **extra, loss=args.loss or "exp", ops_penalty=args.ops_penalty or 0.0,
                           squared_error=bool(args.squared_error), background_term=bool(args.background_term),
                           calibrate=bool(args.calibrate), network=_network_config(args))
    except TrainConfigError as exc:  # every field set here is the flag of the same name
        raise UserError(f"--{exc.field.replace('_', '-')} {exc.problem}") from None


def _trainer(model: str):
    """The public training function of a model: (files, cfg, progress) -> (model, history)."""
    if model == "siamfc":
        from benchmarks.trackers.siamfc.train import train
    elif model == "sctn_ann":
        from sctn.ann import train_twin as train
    else:
        from sctn.training.snn import train
    return train


def validation_scorer(model_kind: str, files: list, max_segments: int | None, seed: int):
    """model -> {"arscore", "accuracy_tracking", "robustness"} of the model's tracker on the validation sequences with
    the paper's protocol (re-initialisation): SCTNTracker for sctn and sctn_ann (a fine-tuned copy of the network per
    sequence), SiamFCTracker for siamfc (the network read as it is)."""
    def tracker(model):
        if model_kind == "siamfc":
            from benchmarks.trackers.siamfc.tracker import SiamFCTracker

            return SiamFCTracker.from_model(model)
        from benchmarks.trackers.sctn import SCTNBenchTracker
        from sctn.tracker import SCTNTracker

        return SCTNBenchTracker.wrap(SCTNTracker(model, seed=seed))

    def score(model) -> dict:
        from benchmarks.evaluation.metrics import pooled
        from benchmarks.evaluation.protocol import run_sequence
        from dvsot.dataset import Dataset

        ious = []
        for f in files:
            with Dataset(f) as ds:
                ious.append(run_sequence(tracker(model), ds, model_kind, max_segments=max_segments).iou)
        s = pooled(ious)
        return {"arscore": s.arscore, "accuracy_tracking": s.accuracy, "robustness": s.robustness}
    return score


def run(args: argparse.Namespace) -> int:
    """Train, then save the checkpoint (atomically) with its provenance."""
    import json

    import torch

    from dvsot.dataset import find_datasets
    from dvsot.errors import RunError, UserError
    from sctn.checkpoint import check_checkpoint_output, save_checkpoint
    from sctn.training.snn import provenance

    from dvsot.limits import MAX_THREADS, range_problem

    cfg = _train_config(args)
    problem = args.threads is not None and range_problem("--threads", args.threads, 1, MAX_THREADS)
    if problem:
        raise UserError(problem)
    files = find_datasets(args.data, split=None if args.split == "any" else args.split, need_events=True)
    val_files = find_datasets(args.val_data, split=None, need_events=True) if args.val_data else None
    if val_files and set(map(str, val_files)) & set(map(str, files)):
        raise UserError(f"{', '.join(sorted(set(map(str, val_files)) & set(map(str, files))))}: in both --data and "
                        "--val-data (validation must be apart from training)")
    if args.val_arscore_every is not None and not val_files:
        raise UserError("--val-arscore-every needs --val-data (the sequences to track)")
    if args.val_arscore_segments is not None and args.val_arscore_segments < 1:
        raise UserError(f"--val-arscore-segments must be >= 1, got {args.val_arscore_segments}")
    out = check_checkpoint_output(args.output or f"runs/{args.model}.pt", "-o", inputs=files + (val_files or []))
    if args.threads:
        torch.set_num_threads(args.threads)
    try:
        validation = {}
        if val_files:
            validation["val_files"] = val_files
            if args.val_arscore_every is not None:
                validation["val_score"] = validation_scorer(args.model, val_files, args.val_arscore_segments, args.seed)
        model, history = _trainer(args.model)(files, cfg, progress=not args.quiet, **validation)
    except UserError:  # already names its file (a UserError is a ValueError too)
        raise
    except ValueError as exc:
        raise UserError(f"{', '.join(map(str, args.data))}: {exc}") from None
    final = history["val"][-1] if history["val"] else {}
    if history.get("silent"):  # a dead network is no checkpoint: keep what -o held
        raise RunError(f"{out}: not written: the trained network is silent (target output {final['vmax_max']:g} "
                       f"at most on the {history['val_segments']} validation segments' samples); train again "
                       f"with another --seed" + (" or --init calibrate / fluctuation" if args.model == "sctn" else ""))
    from dvsot.runtime import interrupts

    with interrupts.last_step():  # once the checkpoint's renames begin the run has completed: a signal then is late
        save_checkpoint(out, model, provenance(files, cfg, history), kind=args.model)
    print(json.dumps({"checkpoint": str(out), "model": args.model, "steps": history["steps"],
                      "minutes": round(history["minutes"], 2), "train_segments": history["train_segments"],
                      "validation": history.get("validation"), "val": final,
                      "nearly_silent": history.get("nearly_silent")}))
    return 0
