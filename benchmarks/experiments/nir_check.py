"""SCTN exported to NIR, run by another library: spikes per layer and the target's V_max against dvsot's own.

Two steps, two Python environments (Norse is no dependency of dvsot; its venv needs torch, nir, norse):

    python -m benchmarks.experiments.nir_check reference --data data/dvsot21/city_bottle.h5 --out runs/nir_check
    /path/to/norse-venv/bin/python benchmarks/experiments/nir_check.py norse --out runs/nir_check

`reference` (dvsot's environment) draws the tracker's gaussian candidates (the true box first) on labelled
segments spread over each file, encodes them as SCTN does, runs dvsot's SCTN (every layer's spikes, the
output voltages), writes the checkpoint as NIR graphs (`exact` and `euler` constants) and runs them in
sctn.nir_sim (exact and Euler integration, reset by subtraction and NIR's reset to v_reset).
`norse` loads the two graph files with `norse.torch.from_nir` as a Norse user would (dt = 1 ms, each
reset method), runs every sample step by step, one sample per call (NIR's shapes have no batch
dimension and the graph's Flatten starts at dimension 0), and compares. Both print a table and write
JSON into --out. Run as a file, the `norse` step imports numpy, torch, nir and norse only.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

LIF_NODES = ("conv1_lif", "conv2_lif", "conv3_lif", "fc1_lif", "fc2_lif", "out_lif")
TARGET = 1  # the target in dvsot's output voltages; in a graph, its metadata's target_index (0 without background)
V_TOLERANCE = 1e-4  # |V_max difference| within which the target's V_max counts as equal (float32 against float64)


def compare(ref_spikes: list[np.ndarray], ref_vmax: np.ndarray, spikes: dict[str, np.ndarray],
            vmax: np.ndarray, group: int) -> dict:
    """Agreement of one run with dvsot's: per layer the spike totals and the (step, sample, neuron) entries that
    differ, the target's V_max difference (max and mean |dV|, samples beyond V_TOLERANCE), and the segments
    (each `group` consecutive samples) whose highest-scoring candidate is the same."""
    layers = {}
    for name, ref in zip(LIF_NODES, ref_spikes):
        got = spikes[name].reshape(ref.shape)
        layers[name] = {"dvsot": int(ref.sum()), "other": int(got.sum()), "differ": int((ref != got).sum())}
    dv = np.abs(np.asarray(vmax, np.float64) - ref_vmax)
    best = np.argmax(np.reshape(vmax, (-1, group)), axis=1) == np.argmax(np.reshape(ref_vmax, (-1, group)), axis=1)
    return {"layers": layers, "vmax_max_abs_diff": float(dv.max()), "vmax_mean_abs_diff": float(dv.mean()),
            "same_best_candidate": [int(best.sum()), int(best.size)],
            "vmax_beyond_tolerance": int((dv > V_TOLERANCE).sum()), "samples": int(len(dv)),
            "target_fires": [int((ref_vmax >= 0.5).sum()), int((np.asarray(vmax) >= 0.5).sum())]}


def table(results: dict) -> str:
    """Markdown rows: run, spikes per layer (other / dvsot, differing entries), target V_max difference."""
    lines = ["| run | " + " | ".join(LIF_NODES) + " | target V_max: max / mean abs diff | beyond 1e-4 "
             "| same best candidate |", "|---" * (len(LIF_NODES) + 4) + "|"]
    for run, r in results.items():
        cells = [f"{c['other']} / {c['dvsot']} ({c['differ']})" for c in r["layers"].values()]
        lines.append(f"| {run} | " + " | ".join(cells) + f" | {r['vmax_max_abs_diff']:.2e} / "
                     f"{r['vmax_mean_abs_diff']:.2e} | {r['vmax_beyond_tolerance']} of {r['samples']} "
                     f"| {r['same_best_candidate'][0]} of {r['same_best_candidate'][1]} segments |")
    return "\n".join(lines)


def reference(files: list[Path], out: Path, checkpoint: str | None, segments: int, candidates: int,
              seed: int) -> dict:
    """dvsot's outputs on the candidates of `segments` labelled segments per file, the exported graphs and the
    numpy simulator's agreement; written to out/reference.npz, out/sctn_{exact,euler}.nir, out/nir_sim.json."""
    import nir
    import torch

    from dvsot.dataset import Dataset
    from sctn.checkpoint import default_checkpoint_path, load_checkpoint
    from sctn.encoding import encode_boxes
    from sctn.nir_export import export_nir, target_neuron
    from sctn.nir_sim import run_graph
    from sctn.samples import TRACK, propose

    model, _ = load_checkpoint(checkpoint)
    xs = []
    for path in files:
        with Dataset(path) as ds:
            labelled = np.flatnonzero(np.isfinite(ds.segment_boxes()).all(axis=1))
            for i in labelled[np.linspace(0, len(labelled) - 1, segments).astype(int)]:
                seg = ds.segment(int(i))
                box = seg.box.astype(np.float64)
                boxes = propose(np.random.default_rng(seed + int(i)), box, candidates - 1, "gaussian", TRACK.trans,
                                TRACK.scale, (ds.width, ds.height))
                xs.append(encode_boxes(seg.events, seg.t0_us, np.concatenate([box[None], boxes])))
    x = torch.cat(xs)
    with torch.no_grad():
        volts, spikes = model.forward_record(x)
    ref_spikes = [s.numpy() for s in spikes[1:]]  # (T, N, ...) per C-LIF layer
    ref_vmax = volts[:, :, TARGET].amax(dim=1).numpy().astype(np.float64)
    out.mkdir(parents=True, exist_ok=True)
    ckpt = checkpoint or default_checkpoint_path()
    np.savez_compressed(out / "reference.npz", x=np.packbits(x.numpy().astype(bool)), x_shape=np.array(x.shape),
                        candidates=candidates,
                        vmax=ref_vmax, **{name: np.packbits(s.astype(bool)) for name, s in zip(LIF_NODES, ref_spikes)},
                        **{f"{name}_shape": np.array(s.shape) for name, s in zip(LIF_NODES, ref_spikes)})
    results = {}
    steps_first = x.numpy().transpose(1, 0, 2, 3, 4)
    for disc in ("exact", "euler"):
        graph_path = export_nir(ckpt, out / f"sctn_{disc}.nir", disc)
        graph = nir.read(graph_path)
        for integrator, reset in ((disc, "subtract"), (disc, "value"), ("euler" if disc == "exact" else "exact",
                                                                       "subtract")):
            outputs, v = run_graph(graph, steps_first, float(graph.metadata["dt"]), integrator, reset)
            results[f"nir_sim: {disc} graph, {integrator} integrator, reset {reset}"] = compare(
                ref_spikes, ref_vmax, outputs, v["out_lif"][:, :, target_neuron(model.cfg)].max(axis=0), candidates)
    (out / "nir_sim.json").write_text(json.dumps(results, indent=2))
    return results


def norse_runs(out: Path) -> dict:
    """Run out/sctn_{exact,euler}.nir in Norse (from_nir, dt = 1 ms, each reset method) on out/reference.npz's
    inputs; agreement with dvsot per run, written to out/norse.json."""
    import nir
    import norse
    import norse.torch as norse_torch
    import torch
    from norse.torch.functional.reset import reset_subtract, reset_value

    ref = np.load(out / "reference.npz")
    shape = tuple(ref["x_shape"])
    x = torch.from_numpy(np.unpackbits(ref["x"], count=int(np.prod(shape))).reshape(shape).astype(np.float32))
    ref_spikes = [np.unpackbits(ref[name], count=int(np.prod(ref[f"{name}_shape"]))).reshape(ref[f"{name}_shape"])
                  for name in LIF_NODES]
    results = {}
    for disc in ("exact", "euler"):
        graph = nir.read(out / f"sctn_{disc}.nir")
        for reset_name, method in (("subtract", reset_subtract), ("value", reset_value)):
            net = norse_torch.from_nir(graph, dt=float(graph.metadata["dt"]), reset_method=method)
            spikes = {name: np.zeros(s.shape, bool) for name, s in zip(LIF_NODES, ref_spikes)}
            vmax = np.full(shape[0], -np.inf)
            out_lif = net.get_submodule("out_lif")
            target = int(graph.metadata.get("target_index", TARGET))
            with torch.no_grad():
                for i in range(shape[0]):
                    state = None
                    v_prev = torch.zeros(ref_spikes[-1].shape[2])
                    for t in range(shape[1]):
                        _, state = net(x[i, t], state)
                        for name in LIF_NODES:
                            spikes[name][t, i] = state.cache[name].numpy().reshape(spikes[name].shape[2:]) > 0
                        # the output voltage before its reset, from Norse's own update of v
                        (syn_state, lif_state), = state.state["out_lif"]  # the executor keeps (module state,)
                        p = out_lif.lif.p
                        v_pre = v_prev + out_lif.lif.dt * p.tau_mem_inv * (p.v_leak - v_prev + out_lif.r * syn_state.v)
                        vmax[i] = max(vmax[i], float(v_pre[target]))
                        v_prev = lif_state.v
            results[f"norse {norse.__version__}: {disc} graph, reset_{reset_name}"] = compare(
                ref_spikes, ref["vmax"], {k: v.astype(np.float64) for k, v in spikes.items()}, vmax,
                int(ref["candidates"]))
    (out / "norse.json").write_text(json.dumps(results, indent=2))
    return results


def main(argv: list[str] | None = None) -> int:
    """Command line: `reference` in dvsot's environment, then `norse` in one with Norse."""
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="step", required=True)
    r = sub.add_parser("reference", help="dvsot's outputs, the exported graphs and the numpy simulator's agreement")
    r.add_argument("--data", nargs="+", required=True, help="dataset files (.h5)")
    r.add_argument("--checkpoint", default=None, help="SCTN checkpoint (default: the shipped one)")
    r.add_argument("--segments", type=int, default=4, help="labelled segments per file")
    r.add_argument("--candidates", type=int, default=16, help="boxes per segment: the true one and gaussian ones")
    r.add_argument("--seed", type=int, default=0)
    r.add_argument("--out", type=Path, required=True)
    n = sub.add_parser("norse", help="run the graphs in Norse and compare (a venv with torch, nir and norse)")
    n.add_argument("--out", type=Path, required=True)
    args = parser.parse_args(argv)
    if args.step == "reference":
        results = reference([Path(f) for f in args.data], args.out, args.checkpoint, args.segments, args.candidates,
                            args.seed)
    else:
        results = norse_runs(args.out)
    print(table(results))
    return 0


if __name__ == "__main__":
    sys.exit(main())
