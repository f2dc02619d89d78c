"""Energy table like the paper's Table 3, and firing rate per layer over time (Fig. 8A), for SCTN.

SCTN's operations are counted from the spikes that actually occur on sampled segments (each
segment's events inside its ground-truth box, one network evaluation); a tracking step evaluates
`n_candidates` such inputs. The ANN row is the same layers run densely as a conventional network on
one frame per candidate, counted by torch's FLOP counter.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np


def sample_firing(model, files: list[Path], n_segments: int = 64, seed: int = 0) -> dict:
    """Mean AC ops per evaluation and per-layer, per-step firing rates over n sampled segments with a box."""
    import torch

    from dvsot.dataset import Dataset
    from sctn.encoding import encode_boxes
    from sctn.energy import LAYER_NAMES

    rng = np.random.default_rng(seed)
    picks = []
    for f in files:
        with Dataset(f) as ds:
            ok = np.flatnonzero(np.isfinite(ds.segment_boxes()).all(axis=1))
            picks += [(f, int(i)) for i in ok]
    if not picks:
        raise ValueError("no segments with a ground-truth box")
    chosen = [picks[i] for i in rng.choice(len(picks), min(n_segments, len(picks)), replace=False)]
    cfg = model.cfg
    xs = []
    for f, i in chosen:
        with Dataset(f) as ds:
            seg = ds.segment(i)
        xs.append(encode_boxes(seg.events, seg.t0_us, seg.box[None], cfg.input_size, cfg.steps, cfg.step_us))
    x = torch.cat(xs)
    from sctn.energy import count_synaptic_ops

    counts = count_synaptic_ops(model, x)
    with torch.no_grad():
        _, spikes = model.forward_record(x)
    per_step = {name: s.float().mean(dim=tuple(range(1, s.dim()))).tolist() for name, s in zip(LAYER_NAMES, spikes)}
    return {"segments": len(chosen), "ac_ops_per_evaluation": counts["ac_ops_per_sample"],
            "ac_ops_by_layer": counts["ac_ops_by_layer"], "firing_rate_by_layer": counts["firing_rate_by_layer"],
            "firing_rate_per_step": per_step}


def energy_table(model, files: list[Path], n_candidates: int = 256, n_segments: int = 64) -> dict:
    """Rows {method: {ops, ops_kind, energy_pj}} per tracking segment, plus the firing statistics."""
    from sctn.energy import E_AC_PJ, E_MAC_PJ, ann_macs

    firing = sample_firing(model, files, n_segments)
    ann = ann_macs(model.cfg)["mac_ops"]
    snn_ops = firing["ac_ops_per_evaluation"] * n_candidates
    rows = {"SCTN (SNN, AC)": {"ops": snn_ops, "kind": "AC", "energy_pj": snn_ops * E_AC_PJ},
            "same-structure ANN (MAC)": {"ops": ann * n_candidates, "kind": "MAC",
                                         "energy_pj": ann * n_candidates * E_MAC_PJ},
            "paper SCTN (Table 3)": {"ops": 7.69e6, "kind": "AC", "energy_pj": 6.93e6}}
    return {"per_segment": rows, "n_candidates": n_candidates, "firing": firing}


def format_energy_table(table: dict) -> str:
    """Terminal text of the energy table."""
    lines = [f"{'method':28s} {'ops/segment':>14s}  {'energy/segment':>16s}",
             "-" * 62]
    for name, row in table["per_segment"].items():
        lines.append(f"{name:28s} {row['ops']:>11.3g} {row['kind']:3s} {row['energy_pj']:>13.3g} pJ")
    rates = table["firing"]["firing_rate_by_layer"]
    lines.append("firing rate per layer: " + ", ".join(f"{k} {v:.4f}" for k, v in rates.items()))
    lines.append(f"({table['n_candidates']} candidates per segment; SNN ops from "
                 f"{table['firing']['segments']} sampled segments)")
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
    out_png.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out_png, dpi=120)
    plt.close(fig)
    return out_png
