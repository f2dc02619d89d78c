"""Energy table like the paper's Table 3, and firing rate per layer over time (Fig. 8A), for SCTN.

SCTN's operations are counted from the spikes that actually occur on sampled segments. Paper-faithful
tracking evaluates the network once per candidate (each segment's events inside its ground-truth box
stand for one evaluation; a segment costs n_candidates of them). Fast search runs the convolutions
once over the region holding all candidates and only the fully connected layers per candidate
(tracking candidates drawn around the ground truth), with bilinear crops (the tracker's default:
fc1's sums of the up to four integer crops around a candidate are mixed, MACs) and with
nearest-cell ones. Each distinct integer crop is evaluated once. The ANN row is the same layers run densely as a
conventional network on one frame per candidate, counted by torch's FLOP counter.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np


def _sample_segments(files: list[Path], n_segments: int, seed: int) -> list:
    """n segments with a ground-truth box, drawn uniformly from all files."""
    from dvsot.dataset import Dataset

    rng = np.random.default_rng(seed)
    picks = []
    for f in files:
        with Dataset(f) as ds:
            ok = np.flatnonzero(np.isfinite(ds.segment_boxes()).all(axis=1))
            picks += [(f, int(i)) for i in ok]
    if not picks:
        raise ValueError("no segments with a ground-truth box")
    segments = []
    for k in rng.choice(len(picks), min(n_segments, len(picks)), replace=False):
        f, i = picks[k]
        with Dataset(f) as ds:
            segments.append((ds.segment(i), (ds.width, ds.height)))
    return segments


def sample_firing(model, segments: list) -> dict:
    """Mean AC ops of one network evaluation (the segment's events inside its ground-truth box) and firing rates."""
    import torch

    from sctn.encoding import encode_boxes
    from sctn.energy import LAYER_NAMES, count_synaptic_ops

    cfg = model.cfg
    x = torch.cat([encode_boxes(seg.events, seg.t0_us, seg.box[None], cfg.input_size, cfg.steps, cfg.step_us)
                   for seg, _ in segments])
    counts = count_synaptic_ops(model, x)
    with torch.no_grad():
        _, spikes = model.forward_record(x)
    per_step = {name: s.float().mean(dim=tuple(range(1, s.dim()))).tolist() for name, s in zip(LAYER_NAMES, spikes)}
    return {"segments": len(segments), "ac_ops_per_evaluation": counts["ac_ops_per_sample"],
            "ac_ops_by_layer": counts["ac_ops_by_layer"], "firing_rate_by_layer": counts["firing_rate_by_layer"],
            "firing_rate_per_step": per_step}


def sample_search(model, segments: list, n_candidates: int, seed: int = 0, crop: str = "bilinear") -> dict:
    """Mean operations of one fast-mode search: tracking candidates drawn around each segment's ground truth."""
    from sctn.encoding import encode_search
    from sctn.energy import count_search_ops
    from sctn.samples import TRACK, propose

    rng = np.random.default_rng(seed)
    cfg = model.cfg
    runs = []
    for seg, wh in segments:
        boxes = propose(rng, seg.box.astype(np.float64), n_candidates, "gaussian", TRACK.trans, TRACK.scale, wh)
        region, origins, rboxes = encode_search(seg.events, seg.t0_us, boxes, seg.box, model.receptive_field(),
                                                cfg.input_size, cfg.steps, cfg.step_us, cfg.tail_steps)
        runs.append(count_search_ops(model, region, origins, rboxes, crop=crop))
    return {key: float(np.mean([r[key] for r in runs])) for key in ("ac_ops", "mac_ops", "energy_pj")}


def energy_table(model, files: list[Path], n_candidates: int = 256, n_segments: int = 64, seed: int = 0) -> dict:
    """Rows {method: {ac_ops, mac_ops, energy_pj}} per tracking segment (n_candidates), plus firing statistics."""
    from sctn.energy import E_AC_PJ, E_MAC_PJ, ann_macs

    segments = _sample_segments(files, n_segments, seed)
    firing = sample_firing(model, segments)
    searches = {crop: sample_search(model, segments, n_candidates, seed, crop) for crop in ("nearest", "bilinear")}
    ann = ann_macs(model.cfg)["mac_ops"]
    faithful = firing["ac_ops_per_evaluation"] * n_candidates
    rows = {"SCTN per candidate (paper)": {"ac_ops": faithful, "mac_ops": 0.0, "energy_pj": faithful * E_AC_PJ},
            "SCTN fast search (bilinear)": searches["bilinear"],
            "SCTN fast search (nearest cell)": searches["nearest"],
            "same-structure ANN": {"ac_ops": 0.0, "mac_ops": ann * n_candidates,
                                   "energy_pj": ann * n_candidates * E_MAC_PJ},
            "paper SCTN (Table 3)": {"ac_ops": 7.69e6, "mac_ops": 0.0, "energy_pj": 6.93e6}}
    per_candidate = {"SCTN": firing["ac_ops_per_evaluation"], "same-structure ANN": ann}
    return {"per_segment": rows, "per_candidate_ops": per_candidate, "n_candidates": n_candidates,
            "network": model.cfg.model_dump(), "firing": firing}


def format_energy_table(table: dict) -> str:
    """Terminal text of the energy table."""
    lines = [f"{'per segment (' + str(table['n_candidates']) + ' candidates)':30s} {'AC ops':>10s} {'MAC ops':>10s}"
             f" {'energy':>12s}", "-" * 66]
    for name, row in table["per_segment"].items():
        lines.append(f"{name:30s} {row['ac_ops']:>10.3g} {row['mac_ops']:>10.3g} {row['energy_pj']:>9.3g} pJ")
    per = table["per_candidate_ops"]
    net = table["network"]
    lines.append(f"one candidate evaluation: SCTN {per['SCTN']:.3g} AC, ANN {per['same-structure ANN']:.3g} MAC; "
                 f"network conv {'/'.join(map(str, net['channels']))}, fc {'/'.join(map(str, net['fc']))}/2")
    rates = table["firing"]["firing_rate_by_layer"]
    lines.append("firing rate per layer: " + ", ".join(f"{k} {v:.4f}" for k, v in rates.items()))
    lines.append(f"(SNN ops from {table['firing']['segments']} sampled segments; fast search: convolutions once "
                 "over the candidates' region, fc1 once per distinct integer crop; bilinear adds the MACs that "
                 "mix fc1's sums of the four crops around each candidate)")
    return "\n".join(lines)


def plot_firing_rates(firing: dict, out_png: Path) -> Path:
    """Fig. 8A: firing rate of each layer at each time step."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(firing["firing_rate_per_step"])
    data = np.array([firing["firing_rate_per_step"][n] for n in names])
    fig, ax = plt.subplots(figsize=(7, 3.2))
    im = ax.imshow(data, aspect="auto", cmap="viridis")
    ax.set_yticks(range(len(names)), names)
    ax.set_xlabel("time step (ms)")
    ax.set_title(f"SCTN firing rate per layer ({firing['segments']} segments)")
    fig.colorbar(im, ax=ax, label="spikes / neuron / step")
    fig.tight_layout()
    out_png = Path(out_png)
    out_png.parent.mkdir(parents=True, exist_ok=True)
    from benchmarks.pictures import save_figure

    return save_figure(fig, out_png, dpi=120)
