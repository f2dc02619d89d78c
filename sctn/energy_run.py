"""Energy of a tracker as it ran: one function from the benchmark's own run records, on four bases.

The records are the protocol's per sequence (benchmarks.evaluation.protocol.SequenceResult, or dicts with
the same keys): `energy`, the mean counts of a tracked segment (the real candidates scored, counted on
every `energy_every`-th segment), `init_energy`, the mean counts of an initialisation, and how many
segments were tracked and how many initialisations ran. Counts (each tracker's bench wrapper in
benchmarks/trackers reports them):

- synaptic operations: accumulates (AC, 0.9 pJ) and multiply-accumulates (MAC, 4.6 pJ);
- neuron-state updates: an SNN's C-LIF updates (every neuron at every step; E_CLIF_UPDATE_PJ each), an
  ANN's activations (one per unit and evaluation; E_ACTIVATION_PJ each);
- `evaluations`: evaluations per tracked segment (candidates for SCTN and its twin, 1 for SiamFC).

An initialisation's counts are its forward passes and, where it fine-tunes, the backward passes:
the forward of a spiking network is counted from the spikes that ran (as tracking is); the backward
of every convolution and linear layer is costed at twice the layer's dense forward MACs per sample and
step (the input gradient and the weight gradient, each one MAC per synapse: the back-propagated errors
are real-valued, so no spike sparsity applies), and one C-LIF (or activation-derivative) update per
neuron-state update of the forward. A twin's forward is its dense MACs per sample; its backward twice
that (finetune_operations). SiamFC's initialisation is the exemplar's forward pass, no backward.

The bases: per evaluation, per tracked segment, per initialisation, per sequence (initialisations x
per initialisation + tracked segments x per segment, averaged over sequences). The paper's convention
(Table 3) is the synaptic energy per evaluation alone: `paper_convention`.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from sctn.energy import E_AC_PJ, E_ACTIVATION_PJ, E_CLIF_UPDATE_PJ, E_MAC_PJ

COUNTS = ("ac_ops", "mac_ops", "state_updates", "activations")
BACKWARD_FACTOR = 2.0  # a layer's backward: its input and weight gradients, each about its forward's MACs


def dense_macs(cfg) -> float:
    """MACs of one evaluation of an SCTN of config cfg if every synapse ran at every step (tail steps included):
    what its backward pass costs per sample (once per gradient)."""
    size, channels_in, total = cfg.input_size, 2, 0
    for c, k, s in zip(cfg.channels, cfg.kernels, cfg.strides):
        size = (size - k) // s + 1
        total += c * size * size * channels_in * k * k
        channels_in = c
    widths = [channels_in * size * size, *cfg.fc, cfg.outputs()]
    total += sum(a * b for a, b in zip(widths[:-1], widths[1:]))
    return float(total * (cfg.steps + cfg.tail_steps))


def finetune_operations(stats: dict | None, spiking: bool, dense_macs_per_sample: float,
                        activations_per_sample: float = 0.0) -> dict:
    """One initialisation's counts {ac_ops, mac_ops, state_updates, activations} from fine-tuning's record
    (sctn.finetune's "finetune_ops"; None or {}: nothing ran): forward as it ran, backward at BACKWARD_FACTOR x the
    dense MACs per sample (the module docstring). A spiking model's forward ACs and C-LIF updates are counted from
    its spikes; an ANN's forward is dense_macs_per_sample and activations_per_sample per sample."""
    ops = (stats or {}).get("finetune_ops") or {}
    n = float(ops.get("samples", 0))
    backward_macs = BACKWARD_FACTOR * dense_macs_per_sample * n
    if spiking:
        states = float(ops.get("forward_state_updates", 0.0))
        return {"ac_ops": float(ops.get("forward_ac_ops", 0.0)),
                "mac_ops": float(ops.get("forward_mac_ops", 0.0)) + backward_macs,
                "state_updates": 2.0 * states, "activations": 0.0}  # forward and its surrogate-gradient backward
    return {"ac_ops": 0.0, "mac_ops": dense_macs_per_sample * n + backward_macs, "state_updates": 0.0,
            "activations": 2.0 * activations_per_sample * n}  # forward ReLUs and their derivatives


def split(counts: dict, scale: float = 1.0) -> dict:
    """Counts {ac_ops, mac_ops, state_updates, activations} x scale as {synaptic: {ac_ops, mac_ops, energy_pj},
    state: {state_updates, activations, energy_pj}, energy_pj} (picojoules)."""
    c = {k: float(counts.get(k) or 0.0) * scale for k in COUNTS}
    syn = c["ac_ops"] * E_AC_PJ + c["mac_ops"] * E_MAC_PJ
    state = c["state_updates"] * E_CLIF_UPDATE_PJ + c["activations"] * E_ACTIVATION_PJ
    return {"synaptic": {"ac_ops": c["ac_ops"], "mac_ops": c["mac_ops"], "energy_pj": syn},
            "state": {"state_updates": c["state_updates"], "activations": c["activations"], "energy_pj": state},
            "energy_pj": syn + state}


def _get(record: Any, key: str, default=None):
    return record.get(key, default) if isinstance(record, dict) else getattr(record, key, default)


def _mean(pairs: list[tuple[float, dict]]) -> dict:
    """The weighted mean of count dicts."""
    total = sum(w for w, _ in pairs)
    return {k: sum(w * float(d.get(k) or 0.0) for w, d in pairs) / total if total else 0.0
            for k in (*COUNTS, "evaluations")}


def energy_as_run(records: Iterable[Any]) -> dict | None:
    """A tracker's energy over the run records of its sequences: per_evaluation, per_segment, per_initialisation,
    per_sequence (each split(): synaptic operations and neuron-state updates, pJ), paper_convention (synaptic
    energy per evaluation: the paper's Table 3), and the sequences, segments and initialisations counted. A sequence
    that failed, or whose tracked segments or initialisations were not counted (energy_every 0, a tracker that does
    not count them), is left out; None if none is left."""
    seqs = []
    for r in records:
        seg, init = _get(r, "energy"), _get(r, "init_energy")
        tracked, inits = int(_get(r, "tracked_segments", 0)), len(_get(r, "init_segments", []) or [])
        if _get(r, "error") is None and seg and init is not None and (tracked or inits):
            seqs.append((tracked, inits, seg, init))
    if not seqs:
        return None
    per_seg = _mean([(t, s) for t, _, s, _ in seqs if t])
    per_init = _mean([(i, d) for _, i, _, d in seqs if i])
    per_seq = _mean([(1.0, {k: t * float(s.get(k) or 0) + i * float(d.get(k) or 0) for k in COUNTS})
                     for t, i, s, d in seqs])
    evaluations = per_seg["evaluations"] or 1.0
    per_eval = split(per_seg, 1.0 / evaluations)
    return {"evaluations_per_segment": evaluations, "per_evaluation": per_eval, "per_segment": split(per_seg),
            "per_initialisation": split(per_init), "per_sequence": split(per_seq),
            "paper_convention": {"basis": "synaptic operations per evaluation (the paper's Table 3)",
                                 **per_eval["synaptic"]},
            "sequences": len(seqs), "tracked_segments": sum(t for t, _, _, _ in seqs),
            "initialisations": sum(i for _, i, _, _ in seqs)}
