"""Energy accounting (paper §3.4): synaptic operations from the spikes that actually occur vs dense ANN MACs.

SNN: every spike costs one accumulate (AC) per synapse it drives (its fan-out): input events into
conv1, each layer's spikes into the next; the output layer's spikes drive nothing. A convolution's
fan-out per input pixel is (out channels) x (number of output positions whose kernel covers the
pixel); a fully connected layer's is its output width. ANN MACs are counted on the layers that run
(count_macs, sctn.macs). Energy: AC 0.9 pJ, MAC 4.6 pJ (45 nm, 32-bit float; Han et al. 2015).

Neuron-state updates are counted apart (the paper counts synaptic operations only): an SNN updates
every neuron's C-LIF state at every step (neurons._clif_steps: 3 multiplies and 4 adds, counted for
every neuron, as a clock-driven implementation runs them); an ANN applies one activation per unit and
evaluation (a ReLU: one comparison, costed as an add). `tracker_energy` states one tracker's figures
per evaluation (one candidate box, or one Siamese frame) and per tracked segment (x its evaluations
per segment: 256 candidates for SCTN and its twin, 1 for a Siamese tracker), from one set of counts.
"""

from __future__ import annotations

import torch
from torch import nn
from torch.nn import functional as F

from sctn.network import SCTN

E_AC_PJ = 0.9
E_MAC_PJ = 4.6
E_MUL_PJ = E_MAC_PJ - E_AC_PJ  # a 32-bit float multiply: a MAC less its add (3.7 pJ)
CLIF_MULS, CLIF_ADDS = 3, 4  # one C-LIF update: V0 I, d_m (.), d_s (.); u + x, - theta S, w + x, u - w
E_CLIF_UPDATE_PJ = CLIF_MULS * E_MUL_PJ + CLIF_ADDS * E_AC_PJ
E_ACTIVATION_PJ = E_AC_PJ  # a ReLU: one comparison, costed as an add
LAYER_NAMES = ("input", "conv1", "conv2", "conv3", "fc1", "fc2", "output")


def conv_fanout(conv: nn.Conv2d, in_hw: tuple[int, int]) -> torch.Tensor:
    """Synapses driven by one spike at each input pixel of a convolution: (H, W) counts."""
    out_h = (in_hw[0] - conv.kernel_size[0]) // conv.stride[0] + 1
    out_w = (in_hw[1] - conv.kernel_size[1]) // conv.stride[1] + 1
    cover = F.conv_transpose2d(torch.ones(1, 1, out_h, out_w), torch.ones(1, 1, *conv.kernel_size), stride=conv.stride)
    full = torch.zeros(in_hw)
    full[: cover.shape[2], : cover.shape[3]] = cover[0, 0]
    return full * conv.out_channels


def layer_ops(model: SCTN, spikes: list[torch.Tensor]) -> list[torch.Tensor]:
    """AC operations per sample, (B,) per layer, driven by forward_record's spikes (input first); differentiable
    in the spikes, so training can penalise them (TrainConfig.ops_penalty)."""
    ops = []
    h = w = model.cfg.input_size
    for k, s in enumerate(spikes):
        per_sample = s.sum(dim=0)  # (B, C, H, W) or (B, N) spike counts over the steps
        if k < 3:
            ops.append((per_sample * conv_fanout(model.convs[k], (h, w))).flatten(1).sum(dim=1))
            h = w = model.cfg.conv_sizes()[k]
        elif k < 6:
            ops.append(per_sample.flatten(1).sum(dim=1) * model.fcs[k - 3].out_features)
        else:
            ops.append(per_sample.new_zeros(per_sample.shape[0]))  # the output layer drives nothing
    return ops


def count_synaptic_ops(model: SCTN, x: torch.Tensor) -> dict:
    """AC operations and firing rates per layer for input spikes x (B, T, 2, H, W); totals are per sample."""
    with torch.no_grad():
        _, spikes = model.forward_record(x)
        per_layer = layer_ops(model, spikes)
    ops = {name: float(o.mean()) for name, o in zip(LAYER_NAMES, per_layer)}
    counts = {name: float(s.sum()) / x.shape[0] for name, s in zip(LAYER_NAMES, spikes)}
    rates = {name: float(s.mean()) for name, s in zip(LAYER_NAMES, spikes)}
    total = sum(ops.values())
    return {
        "ac_ops_per_sample": total,
        "ac_ops_by_layer": ops,
        "spikes_by_layer": counts,
        "firing_rate_by_layer": rates,
        "energy_pj_per_sample": total * E_AC_PJ,
    }


def bias_additions(model: SCTN) -> float:
    """Bias additions per evaluated sample: one per neuron with a bias per time step (0 without biases)."""
    steps = model.cfg.steps + model.cfg.tail_steps
    sizes = model.cfg.conv_sizes()
    total = 0
    for k, conv in enumerate(model.convs):
        if conv.bias is not None:
            total += conv.out_channels * sizes[k] ** 2
    total += sum(fc.out_features for fc in model.fcs if fc.bias is not None)
    return float(total * steps)


def count_search_ops(model: SCTN, region: torch.Tensor, origins: torch.Tensor, boxes: torch.Tensor,
                     crop: str = "bilinear") -> dict:
    """Operations of one fast-mode search (SCTN.forward_search) over N candidates: a whole segment's cost.

    What actually runs is counted: the convolutions once over the region (each spike times its
    fan-out); each distinct integer crop once, its conv3 spikes driving fc1's width of synapses (ACs);
    fc1 and fc2 spikes per evaluated candidate (ACs); with crop="bilinear" also the multiply-adds that
    mix up to four crops' fc1 sums per candidate (MACs).
    """
    with torch.no_grad():
        _, rec = model.forward_search(region, origins, boxes, record=True, crop=crop)
    return {"candidates": int(origins.shape[0]), "crops_evaluated": int(rec["crops"].shape[1]),
            **search_record_ops(model, tuple(region.shape[-2:]), rec)}


def search_record_ops(model: SCTN, region_hw: tuple[int, int], rec: dict) -> dict:
    """count_search_ops' figures from the record of one forward_search over a region of region_hw pixels (also one
    run with gradients, as fine-tuning's fast-mode mini-batches run it): ac_ops, ac_ops_by_layer, mac_ops, energy_pj,
    state_updates."""
    ops: dict[str, float] = {}
    h, w = region_hw
    for k, name in enumerate(LAYER_NAMES[:3]):
        fan = conv_fanout(model.convs[k], (h, w))
        ops[name] = float((rec[name][:, 0].detach().sum(dim=0) * fan).sum())
        h = (h - model.cfg.kernels[k]) // model.cfg.strides[k] + 1
        w = (w - model.cfg.kernels[k]) // model.cfg.strides[k] + 1
    ops["conv3"] = float(rec["crops"].detach().sum()) * model.fcs[0].out_features  # binary crops: one AC per synapse
    ops["fc1"] = float(rec["fc1"].detach().sum()) * model.fcs[1].out_features
    ops["fc2"] = float(rec["fc2"].detach().sum()) * model.fcs[2].out_features
    ops["output"] = 0.0
    ac = sum(ops.values())
    macs = rec["mix_macs"]
    # C-LIF updates that run: every conv neuron over the region, the fc neurons per row they ran on, the outputs
    states = sum(float(rec[name].numel()) for name in ("conv1", "conv2", "conv3", "fc1", "fc2"))
    states += float(rec["fc2"].shape[0] * rec["fc2"].shape[1] * model.fcs[2].out_features)
    return {"ac_ops": ac, "ac_ops_by_layer": ops, "mac_ops": macs, "energy_pj": ac * E_AC_PJ + macs * E_MAC_PJ,
            "state_updates": states}


def energy_pj(ac_ops: float = 0.0, mac_ops: float = 0.0, e_ac: float = E_AC_PJ, e_mac: float = E_MAC_PJ) -> dict:
    """E = n_AC e_AC + n_MAC e_MAC in picojoules (eq. 13-14)."""
    return {"ac_ops": ac_ops, "mac_ops": mac_ops, "energy_pj": ac_ops * e_ac + mac_ops * e_mac}


def count_macs(fn, *inputs: torch.Tensor) -> dict:
    """Multiply-accumulates of one call fn(*inputs) (a module or any function of modules), counted on the operations
    that run (sctn.macs): {"mac_ops": total, "by_layer": {module: MACs}, "by_kind": {conv|...: MACs}}."""
    from sctn.macs import count_macs as count

    return count(fn, *inputs)


def snn_state_updates(cfg) -> float:
    """C-LIF state updates of one evaluation of an SCTN of config cfg: every neuron (conv maps, fc layers, the
    output neurons that exist) at every step, tail steps included."""
    sizes = cfg.conv_sizes()
    neurons = sum(c * n * n for c, n in zip(cfg.channels, sizes)) + sum(cfg.fc) + cfg.outputs()
    return float(neurons * (cfg.steps + cfg.tail_steps))


def count_activations(fn, *inputs: torch.Tensor) -> float:
    """Activation-function outputs (ReLU elements) of one call fn(*inputs): an ANN's per-unit state updates."""
    from torch.overrides import TorchFunctionMode

    relus = {F.relu, torch.relu, torch.relu_, torch.Tensor.relu, torch.Tensor.relu_}
    count = [0]

    class Counter(TorchFunctionMode):
        def __torch_function__(self, func, types, args=(), kwargs=None):
            out = func(*args, **(kwargs or {}))
            if func in relus and isinstance(out, torch.Tensor):
                count[0] += out.numel()
            return out

    with Counter(), torch.no_grad():
        fn(*inputs)
    return float(count[0])


def tracker_energy(evaluations_per_segment: float, ac_ops: float = 0.0, mac_ops: float = 0.0,
                   state_updates: float | None = None, state_update_pj: float = E_CLIF_UPDATE_PJ) -> dict:
    """One tracker's operations and energy per evaluation (arguments: one candidate's or frame's counts) and per
    tracked segment (x evaluations_per_segment): {per_evaluation: {...}, per_segment: {...}}, each with ac_ops,
    mac_ops, energy_pj (synaptic: the paper's measure), state_updates and state_energy_pj (None if unknown)."""
    def figures(k: float) -> dict:
        states = None if state_updates is None else state_updates * k
        return {"ac_ops": ac_ops * k, "mac_ops": mac_ops * k, "energy_pj": (ac_ops * E_AC_PJ + mac_ops * E_MAC_PJ) * k,
                "state_updates": states, "state_energy_pj": None if states is None else states * state_update_pj}
    return {"evaluations_per_segment": evaluations_per_segment, "per_evaluation": figures(1.0),
            "per_segment": figures(float(evaluations_per_segment))}
