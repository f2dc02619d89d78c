"""Energy table like the paper's Table 3, and firing rate per layer over time (Fig. 8A), for SCTN.

Every row is stated two ways by one function (sctn.energy.tracker_energy): per evaluation (one
candidate box for SCTN and its twin, one frame for a Siamese tracker) and per tracked segment (x 256
candidates for SCTN and its twin, x 1 for a Siamese tracker), with the neuron-state updates (C-LIF
updates; an ANN's activations) in columns of their own. The paper's Table 3 rows are restated the
same two ways: its 7.69e6 ACs "on processing a frame or a segment" with firing rates sampled per
segment are read as one evaluation of the network (256 of them track a segment).
SCTN is counted as the tracker runs it: fine-tuned on each file's first labelled segment (Algorithm
1), then on that file's sampled segments.

SCTN's operations are counted from the spikes that actually occur on sampled segments. Paper-faithful
tracking evaluates the network once per candidate (each segment's events inside its ground-truth box
stand for one evaluation; a segment costs n_candidates of them). Fast search runs the convolutions
once over the region holding all candidates and only the fully connected layers per candidate
(tracking candidates drawn around the ground truth), with bilinear crops (the tracker's default:
fc1's sums of the up to four integer crops around a candidate are mixed, MACs) and with
nearest-cell ones. Each distinct integer crop is evaluated once. The ANN rows are counted by torch's FLOP counter on the
layers the trackers run: SCTN's ANN twin (sctn/ann.py) once per candidate, SiamFC's backbone on its
scale pyramid and the cross-correlation once per frame (benchmarks/trackers/siamfc/tracker.py frame_macs).

Beside these sampled rows, `dvsot bench` states each tracker's energy as it ran on the bench's own results
(energy_as_run_rows, one call of sctn.energy_run.energy_as_run per tracker): per evaluation, per tracked segment
(the real candidates), per initialisation (fine-tuning's forward and backward) and per sequence, each split into
synaptic operations and neuron-state updates, with the paper's convention (synaptic per evaluation) named.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from benchmarks.analysis import paper
from sctn.samples import TRACK


def _sample_by_file(files: list[Path], n_segments: int, seed: int) -> list:
    """n segments with a ground-truth box, drawn uniformly from all files: [(file, [(segment, (w, h))])], file order."""
    from dvsot.dataset import Dataset

    rng = np.random.default_rng(seed)
    picks = []
    for f in files:
        with Dataset(f) as ds:
            ok = np.flatnonzero(np.isfinite(ds.segment_boxes()).all(axis=1))
            picks += [(f, int(i)) for i in ok]
    if not picks:
        raise ValueError("no segments with a ground-truth box")
    chosen = [picks[k] for k in rng.choice(len(picks), min(n_segments, len(picks)), replace=False)]
    groups = []
    for f in files:
        mine = [i for g, i in chosen if g == f]
        if mine:
            with Dataset(f) as ds:
                groups.append((f, [(ds.segment(i), (ds.width, ds.height)) for i in mine]))
    return groups


def _sample_segments(files: list[Path], n_segments: int, seed: int) -> list:
    """n segments with a ground-truth box, drawn uniformly from all files: [(segment, (w, h))]."""
    return [sw for _, segs in _sample_by_file(files, n_segments, seed) for sw in segs]


def tuned_groups(model, files: list[Path], n_segments: int, seed: int, finetune: bool = True) -> list:
    """[(network, [(segment, (w, h))] of one file)] for the sampled segments: the network fine-tuned as SCTNTracker
    does at a sequence's start (on the file's first labelled segment, the tracker's defaults and `seed`), or the
    network itself with finetune=False."""
    from dvsot.dataset import Dataset
    from sctn.tracker import SCTNTracker

    out = []
    for f, segs in _sample_by_file(files, n_segments, seed):
        net = model
        if finetune:
            with Dataset(f) as ds:
                boxes = ds.segment_boxes()
                ok = np.flatnonzero(np.isfinite(boxes).all(axis=1))
                if len(ok):
                    first = ds.segment(int(ok[0]))
                    tracker = SCTNTracker(model, seed=seed)
                    tracker.init(first.events, first.t0_us, first.box, ds.width, ds.height)
                    net = tracker.model
        out.append((net, segs))
    return out


SCTN_MODES = ("per candidate", "fast bilinear", "fast nearest")


def sctn_energy(groups: list, n_candidates: int, seed: int = 0, modes: tuple[str, ...] = SCTN_MODES) -> dict:
    """SCTN's rows over the sampled segments of tuned_groups: {mode: tracker_energy(...)} for the `modes` of
    SCTN_MODES, and "firing" (sample_firing over all segments, weighted by segments): the one figure of each SCTN
    mode that the energy table, the ablation and the docs use."""
    from sctn.energy import snn_state_updates, tracker_energy

    firings = [(sample_firing(net, segs), len(segs)) for net, segs in groups]
    total = sum(n for _, n in firings)

    def mean(get) -> float:
        return float(sum(get(f) * n for f, n in firings) / total)

    per_eval = mean(lambda f: f["ac_ops_per_evaluation"])
    layers = list(firings[0][0]["ac_ops_by_layer"])
    firing = {"segments": total, "ac_ops_per_evaluation": per_eval,
              "ac_ops_by_layer": {k: mean(lambda f, k=k: f["ac_ops_by_layer"][k]) for k in layers},
              "firing_rate_by_layer": {k: mean(lambda f, k=k: f["firing_rate_by_layer"][k]) for k in layers},
              "firing_rate_per_step": {k: np.average([f["firing_rate_per_step"][k] for f, _ in firings], axis=0,
                                                     weights=[n for _, n in firings]).tolist() for k in layers}}
    model = groups[0][0]
    rows = {"per candidate": tracker_energy(n_candidates, ac_ops=per_eval,
                                            state_updates=snn_state_updates(model.cfg))}
    for crop in [m.removeprefix("fast ") for m in modes if m.startswith("fast ")]:
        runs = [(sample_search(net, segs, n_candidates, seed, crop), len(segs)) for net, segs in groups]
        seg = {k: float(sum(r[k] * n for r, n in runs) / total) for k in ("ac_ops", "mac_ops", "state_updates")}
        # per segment measured; per evaluation is a segment's share per candidate (the convolutions are shared)
        rows[f"fast {crop}"] = tracker_energy(n_candidates, ac_ops=seg["ac_ops"] / n_candidates,
                                              mac_ops=seg["mac_ops"] / n_candidates,
                                              state_updates=seg["state_updates"] / n_candidates)
    return {"rows": {m: rows[m] for m in modes}, "firing": firing}


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
    return {key: float(np.mean([r[key] for r in runs])) for key in ("ac_ops", "mac_ops", "energy_pj", "state_updates")}


# the paper's Table 3 ("on processing a frame or a segment"): SCTN's ACs read as one evaluation (one candidate),
# the Siamese trackers' MACs as one frame; their neuron-state updates are not given
REFERENCE = "SCTN per candidate (paper)"


def paper_rows(n_candidates: int) -> dict:
    """The paper's Table 3 restated per evaluation and per tracked segment (SCTN x n_candidates, Siamese x 1)."""
    from sctn.energy import tracker_energy

    rows = {"paper SCTN (Table 3, per evaluation)": tracker_energy(n_candidates, ac_ops=paper.SCTN_AC_PER_EVALUATION)}
    for name, macs in paper.SIAMESE_MAC_PER_FRAME.items():
        rows[f"paper {name} (Table 3, per frame)"] = tracker_energy(1, mac_ops=macs)
    return {name: _flat(row) for name, row in rows.items()}


def ann_rows(n_candidates: int, twin=None, siamfc=None, siamfc_scales: int = 3, response_up: int = 16) -> dict:
    """Rows of the ANN trackers counted on their layers (tracker_energy): the twin (n_candidates evaluations per
    segment; also with the paper's two-channel summed input, whose MACs do not depend on the weights) and SiamFC
    (one update per frame: the scale pyramid); their activations as state updates; {} for a model not given."""
    import torch

    from sctn.energy import E_ACTIVATION_PJ, count_activations, tracker_energy

    rows = {}
    if twin is not None:
        from sctn.ann import SCTNTwin, TwinConfig, twin_macs

        inputs = [twin.cfg.input] + [i for i in ("bins", "sum") if i != twin.cfg.input]
        for form in inputs:
            net = twin if form == twin.cfg.input else SCTNTwin(TwinConfig(**{**twin.cfg.model_dump(), "input": form}))
            c = net.cfg
            acts = count_activations(net, torch.zeros(1, c.steps, 2, c.input_size, c.input_size))
            rows[f"SCTN's ANN twin (sctn_ann, input {form})"] = tracker_energy(
                n_candidates, mac_ops=twin_macs(net)["mac_ops"], state_updates=acts, state_update_pj=E_ACTIVATION_PJ)
    if siamfc is not None:
        from benchmarks.trackers.siamfc.tracker import frame_macs

        c = siamfc.cfg
        acts = count_activations(siamfc.features, torch.zeros(siamfc_scales, 1, c.search_size, c.search_size))
        rows[f"SiamFC (siamfc), {siamfc_scales} scales"] = tracker_energy(
            1, mac_ops=frame_macs(siamfc, siamfc_scales, response_up)["mac_ops"], state_updates=acts,
            state_update_pj=E_ACTIVATION_PJ)
    return {name: _flat(row) for name, row in rows.items()}


def _flat(row: dict) -> dict:
    """A tracker_energy row as the table keeps it: its per-segment figures at the top (ac_ops, mac_ops, energy_pj,
    state_updates, state_energy_pj), evaluations_per_segment and per_evaluation beside them."""
    return {**row["per_segment"], "evaluations_per_segment": row["evaluations_per_segment"],
            "per_evaluation": row["per_evaluation"]}


def energy_table(model, files: list[Path], n_candidates: int = TRACK.n, n_segments: int = 64, seed: int = 0,
                 twin=None, siamfc=None, notes: tuple[str, ...] = (), finetune: bool = True) -> dict:
    """Rows {method: {ac_ops, mac_ops, energy_pj, state_updates, state_energy_pj (per tracked segment),
    evaluations_per_segment, per_evaluation: {...}, x_sctn}}, plus firing statistics; x_sctn is a row's synaptic
    energy per segment over SCTN's per-candidate one. SCTN is fine-tuned per file as the tracker is (finetune).
    `twin` (sctn.ann's SCTNTwin) and `siamfc` (benchmarks.trackers.siamfc's SiamFC) add their rows; `notes` print
    below."""
    groups = tuned_groups(model, files, n_segments, seed, finetune)
    sctn = sctn_energy(groups, n_candidates, seed, SCTN_MODES)
    firing = sctn["firing"]
    rows = {REFERENCE: _flat(sctn["rows"]["per candidate"]),
            "SCTN fast search (bilinear)": _flat(sctn["rows"]["fast bilinear"]),
            "SCTN fast search (nearest cell)": _flat(sctn["rows"]["fast nearest"]),
            **ann_rows(n_candidates, twin, siamfc), **paper_rows(n_candidates)}
    ref = rows[REFERENCE]["energy_pj"]
    for row in rows.values():
        row["x_sctn"] = row["energy_pj"] / ref if ref else float("nan")
    per_candidate = {"SCTN": firing["ac_ops_per_evaluation"]}
    if twin is not None:
        from sctn.ann import twin_macs

        per_candidate["sctn_ann"] = twin_macs(twin)["mac_ops"]
    return {"per_segment": rows, "per_candidate_ops": per_candidate, "n_candidates": n_candidates,
            "finetuned": finetune, "network": model.cfg.model_dump(), "firing": firing, "notes": list(notes)}


def format_energy_table(table: dict) -> str:
    """Terminal text of the energy table: each row per evaluation and per tracked segment."""
    from sctn.energy import E_AC_PJ, E_CLIF_UPDATE_PJ, E_MAC_PJ

    def g(v) -> str:
        return "-" if v is None else f"{v:.3g}"

    lines = [f"{'tracker':44s} {'evals':>5s} | {'per evaluation: AC':>18s} {'MAC':>8s} {'pJ':>8s} {'states':>8s} | "
             f"{'per segment: AC':>15s} {'MAC':>8s} {'pJ':>8s} {'states':>8s} {'state pJ':>8s} {'x SCTN':>7s}",
             "-" * 160]
    for name, row in table["per_segment"].items():
        e = row["per_evaluation"]
        lines.append(f"{name:44s} {row['evaluations_per_segment']:>5g} | {g(e['ac_ops']):>18s} {g(e['mac_ops']):>8s} "
                     f"{g(e['energy_pj']):>8s} {g(e['state_updates']):>8s} | {g(row['ac_ops']):>15s} "
                     f"{g(row['mac_ops']):>8s} {g(row['energy_pj']):>8s} {g(row['state_updates']):>8s} "
                     f"{g(row['state_energy_pj']):>8s} {g(row.get('x_sctn')):>7s}")
    per = table["per_candidate_ops"]
    net = table["network"]
    twin = f", ANN twin {per['sctn_ann']:.3g} MAC" if "sctn_ann" in per else ""
    lines.append(f"one candidate evaluation: SCTN {per['SCTN']:.3g} AC{twin}; "
                 f"network conv {'/'.join(map(str, net['channels']))}, fc {'/'.join(map(str, net['fc']))}/2")
    rates = table["firing"]["firing_rate_by_layer"]
    lines.append("firing rate per layer: " + ", ".join(f"{k} {v:.4f}" for k, v in rates.items()))
    tuned = "fine-tuned on each file's first segment, " if table.get("finetuned") else ""
    lines.append(f"(SNN ops from {table['firing']['segments']} sampled segments, {tuned}spikes x fan-out; evals: "
                 "evaluations per tracked segment (candidates; 1 frame for a Siamese tracker); fast search: "
                 "convolutions once over the candidates' region, per evaluation its share; states: C-LIF updates "
                 f"(every neuron and step, {E_CLIF_UPDATE_PJ:.3g} pJ each) or ANN activations ({E_AC_PJ} pJ), "
                 f"not in pJ; AC {E_AC_PJ} pJ, MAC {E_MAC_PJ} pJ; x SCTN: synaptic energy per segment over "
                 "SCTN's per-candidate one; the paper's Table 3 read per evaluation)")
    lines += table.get("notes", [])
    as_run = format_energy_as_run(table.get("as_run") or {})
    return "\n".join(lines + ([""] + [as_run] if as_run else []))


AS_RUN_BASES = (("per_evaluation", "per evaluation"), ("per_segment", "per tracked segment"),
                ("per_initialisation", "per initialisation"), ("per_sequence", "per sequence"))
PAPER_CONVENTION = "the paper's convention (Table 3): synaptic operations per evaluation, no neuron-state updates"


def energy_as_run_rows(results) -> dict:
    """{tracker: sctn.energy_run.energy_as_run of its sequences' run records} for every tracker of a bench run's
    results (benchmarks.evaluation.protocol.SequenceResult) that counted its operations, in run order."""
    from sctn.energy_run import energy_as_run

    by_tracker: dict[str, list] = {}
    for r in results:
        by_tracker.setdefault(r.tracker, []).append(r)
    rows = {name: energy_as_run(records) for name, records in by_tracker.items()}
    return {name: row for name, row in rows.items() if row is not None}


def format_energy_as_run(rows: dict) -> str:
    """Terminal text of the trackers' energy as they ran: per evaluation, tracked segment, initialisation and
    sequence, each split into synaptic operations (AC, MAC, pJ) and neuron-state updates (C-LIF updates or ANN
    activations, pJ); the total over SCTN's on each basis; the paper's convention named. '' if no tracker counted."""
    from sctn.energy import E_AC_PJ, E_ACTIVATION_PJ, E_CLIF_UPDATE_PJ, E_MAC_PJ

    if not rows:
        return ""

    def g(v) -> str:
        return "-" if v is None else f"{v:.3g}"

    ref = rows.get("sctn")
    lines = ["energy of each tracker as it ran (this run's own segments and initialisations; sctn.energy_run):",
             f"{'tracker':12s} {'basis':20s} | {'synaptic: AC':>12s} {'MAC':>9s} {'pJ':>9s} | "
             f"{'state: C-LIF':>12s} {'activations':>11s} {'pJ':>9s} | {'total pJ':>9s} {'x sctn':>7s}", "-" * 124]
    for name, row in rows.items():
        for key, basis in AS_RUN_BASES:
            b = row[key]
            syn, state = b["synaptic"], b["state"]
            x = b["energy_pj"] / ref[key]["energy_pj"] if ref and ref[key]["energy_pj"] else None
            lines.append(f"{name:12s} {basis:20s} | {g(syn['ac_ops']):>12s} {g(syn['mac_ops']):>9s} "
                         f"{g(syn['energy_pj']):>9s} | {g(state['state_updates']):>12s} {g(state['activations']):>11s} "
                         f"{g(state['energy_pj']):>9s} | {g(b['energy_pj']):>9s} {g(x):>7s}")
        paper = row["paper_convention"]
        x = paper["energy_pj"] / ref["paper_convention"]["energy_pj"] if ref and ref["paper_convention"]["energy_pj"] \
            else None
        lines.append(f"{name:12s} {'paper convention':20s} | {g(paper['ac_ops']):>12s} {g(paper['mac_ops']):>9s} "
                     f"{g(paper['energy_pj']):>9s} | (synaptic x sctn {g(x)}; "
                     f"{row['evaluations_per_segment']:g} evaluations per tracked segment; {row['sequences']} "
                     f"sequences, {row['tracked_segments']} tracked segments, {row['initialisations']} "
                     "initialisations counted)")
    lines.append(f"(per sequence: initialisations x per initialisation + tracked segments x per tracked segment, "
                 f"averaged over sequences; an initialisation: fine-tuning's forward as it ran and its backward; "
                 f"AC {E_AC_PJ} pJ, MAC {E_MAC_PJ} pJ, C-LIF update {E_CLIF_UPDATE_PJ:.3g} pJ, activation "
                 f"{E_ACTIVATION_PJ:.3g} pJ; {PAPER_CONVENTION}; x sctn: total energy over "
                 "sctn's on the same basis)")
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
