"""Energy table like the paper's Table 3, and firing rate per layer over time (Fig. 8A), for SCTN.

SCTN's operations are counted from the spikes that actually occur on sampled segments. Paper-faithful
tracking evaluates the network once per candidate (each segment's events inside its ground-truth box
stand for one evaluation; a segment costs n_candidates of them). Fast search runs the convolutions
once over the region holding all candidates and only the fully connected layers per candidate
(tracking candidates drawn around the ground truth), with bilinear crops (the tracker's default:
fc1's sums of the up to four integer crops around a candidate are mixed, MACs) and with
nearest-cell ones. Each distinct integer crop is evaluated once. The ANN rows are counted by torch's FLOP counter on the
layers the trackers run: SCTN's ANN twin (sctn/ann.py) once per candidate, SiamFC's backbone on its
scale pyramid and the cross-correlation once per frame (benchmarks/trackers/siamfc/tracker.py frame_macs).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from sctn.samples import TRACK


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
    x = torch.cat([encode_boxes(seg.events, seg.t0_us, seg.box[None], cfg)
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
        region, origins, rboxes = encode_search(seg.events, seg.t0_us, boxes, seg.box, cfg)
        runs.append(count_search_ops(model, region, origins, rboxes, crop=crop))
    return {key: float(np.mean([r[key] for r in runs])) for key in ("ac_ops", "mac_ops", "energy_pj")}


# the paper's Table 3: operations and energy per frame (ANNs) or segment (SCTN)
PAPER_ROWS = {"paper SCTN (Table 3)": {"ac_ops": 7.69e6, "mac_ops": 0.0, "energy_pj": 6.93e6},
              "paper SiamRPN (Table 3)": {"ac_ops": 0.0, "mac_ops": 4.82e9, "energy_pj": 2.22e10},
              "paper SiamMask (Table 3)": {"ac_ops": 0.0, "mac_ops": 1.26e10, "energy_pj": 5.79e10}}
REFERENCE = "SCTN per candidate (paper)"


def ann_rows(n_candidates: int, twin=None, siamfc=None, siamfc_scales: int = 3, response_up: int = 16) -> dict:
    """Rows of the ANN trackers counted on their layers: the twin (n_candidates evaluations per segment) and SiamFC
    (one update per frame: the scale pyramid); {} for a model not given."""
    from sctn.energy import E_MAC_PJ

    rows = {}
    if twin is not None:
        from sctn.ann import twin_macs

        macs = twin_macs(twin)["mac_ops"] * n_candidates
        rows[f"SCTN's ANN twin (sctn_ann, input {twin.cfg.input})"] = {"ac_ops": 0.0, "mac_ops": macs,
                                                                     "energy_pj": macs * E_MAC_PJ}
    if siamfc is not None:
        from benchmarks.trackers.siamfc.tracker import frame_macs

        macs = frame_macs(siamfc, siamfc_scales, response_up)["mac_ops"]
        rows[f"SiamFC (siamfc), {siamfc_scales} scales"] = {"ac_ops": 0.0, "mac_ops": macs,
                                                           "energy_pj": macs * E_MAC_PJ}
    return rows


def energy_table(model, files: list[Path], n_candidates: int = TRACK.n, n_segments: int = 64, seed: int = 0,
                 twin=None, siamfc=None, notes: tuple[str, ...] = ()) -> dict:
    """Rows {method: {ac_ops, mac_ops, energy_pj, x_sctn}} per tracking segment (n_candidates) or frame, plus firing
    statistics; x_sctn is a row's energy over SCTN's per-candidate energy (the paper's ratio). `twin` (sctn.ann's
    SCTNTwin) and `siamfc` (benchmarks.trackers.siamfc's SiamFC) add their rows; `notes` are printed with the table."""
    from sctn.energy import E_AC_PJ

    segments = _sample_segments(files, n_segments, seed)
    firing = sample_firing(model, segments)
    searches = {crop: sample_search(model, segments, n_candidates, seed, crop) for crop in ("nearest", "bilinear")}
    faithful = firing["ac_ops_per_evaluation"] * n_candidates
    rows = {REFERENCE: {"ac_ops": faithful, "mac_ops": 0.0, "energy_pj": faithful * E_AC_PJ},
            "SCTN fast search (bilinear)": searches["bilinear"],
            "SCTN fast search (nearest cell)": searches["nearest"],
            **ann_rows(n_candidates, twin, siamfc), **PAPER_ROWS}
    for row in rows.values():
        ref = rows[REFERENCE]["energy_pj"]
        row["x_sctn"] = row["energy_pj"] / ref if ref else float("nan")
    per_candidate = {"SCTN": firing["ac_ops_per_evaluation"]}
    if twin is not None:
        from sctn.ann import twin_macs

        per_candidate["sctn_ann"] = twin_macs(twin)["mac_ops"]
    return {"per_segment": rows, "per_candidate_ops": per_candidate, "n_candidates": n_candidates,
            "network": model.cfg.model_dump(), "firing": firing, "notes": list(notes)}


def format_energy_table(table: dict) -> str:
    """Terminal text of the energy table."""
    from sctn.energy import E_AC_PJ, E_MAC_PJ

    lines = [f"{'per segment (' + str(table['n_candidates']) + ' candidates) or frame':42s} {'AC ops':>10s} "
             f"{'MAC ops':>10s} {'energy':>12s} {'x SCTN':>8s}", "-" * 86]
    for name, row in table["per_segment"].items():
        lines.append(f"{name:42s} {row['ac_ops']:>10.3g} {row['mac_ops']:>10.3g} {row['energy_pj']:>9.3g} pJ"
                     f" {row.get('x_sctn', float('nan')):>8.3g}")
    per = table["per_candidate_ops"]
    net = table["network"]
    twin = f", ANN twin {per['sctn_ann']:.3g} MAC" if "sctn_ann" in per else ""
    lines.append(f"one candidate evaluation: SCTN {per['SCTN']:.3g} AC{twin}; "
                 f"network conv {'/'.join(map(str, net['channels']))}, fc {'/'.join(map(str, net['fc']))}/2")
    rates = table["firing"]["firing_rate_by_layer"]
    lines.append("firing rate per layer: " + ", ".join(f"{k} {v:.4f}" for k, v in rates.items()))
    lines.append(f"(SNN ops from {table['firing']['segments']} sampled segments; fast search: convolutions once "
                 "over the candidates' region, fc1 once per distinct integer crop; bilinear adds the MACs that "
                 "mix fc1's sums of the four crops around each candidate; ANN MACs counted on the layers run; "
                 f"AC {E_AC_PJ} pJ, MAC {E_MAC_PJ} pJ; x SCTN: energy over SCTN's per-candidate energy)")
    lines += table.get("notes", [])
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
    from benchmarks.analysis.pictures import save_figure

    return save_figure(fig, out_png, dpi=120)
