"""SCTN as a NIR graph (the Neuromorphic Intermediate Representation, package `nir`): C-LIF as NIR's CubaLIF.

The graph, node by node (names as written; shapes without a batch dimension):

    input (2, 107, 107) -> conv1 Conv2d -> conv1_lif CubaLIF -> conv2 -> conv2_lif -> conv3 -> conv3_lif
    -> flatten Flatten (16, 10, 10 -> 1600) -> fc1 Linear -> fc1_lif -> fc2 -> fc2_lif -> out -> out_lif -> output

Layers with biases (a non-preset network) become Affine nodes and Conv2d biases. The input encoding (the
events inside a candidate box on the 107 x 107 canvas, one 1-ms step per time step, sctn/encoding.py)
stays outside the graph: the graph's input is that canvas, step by step.

C-LIF (sctn/neurons.py) as CubaLIF, whose NIR equations are tau_syn dI/dt = -I + w_in S and
tau_mem dv/dt = (v_leak - v) + r I, z = [v > v_threshold], v -> v_reset after a spike. An input spike is
a value of 1 for one step of dt (an impulse of area dt, as a discrete simulator at dt integrates it; dt is
the network's step_us, 1 ms in the paper preset and in the formulas below), so a spike at time 0 gives
I(t) = w_in dt / tau_syn exp(-t / tau_syn) and

    v(t) = r w_in dt / (tau_mem - tau_syn) (exp(-t / tau_mem) - exp(-t / tau_syn)),

which is C-LIF's kernel V0 (exp(-t / a_m) - exp(-t / a_s)) exactly when tau_mem = a_m ms, tau_syn = a_s ms,
w_in = 1 and r = V0 (a_m - a_s) (times in ms; r is dimensionless). Read at the end of each 1 ms step, with
the input of a step arriving at its start, that is C-LIF's discrete recurrence exactly (`discretisation=
"exact"`, the default): a simulator that integrates the ODE exactly over each step (exponential decays
exp(-dt / tau)) reproduces dvsot. v_threshold = theta = 0.5, v_leak = 0.

A forward-Euler simulator at dt (Norse's `from_nir`, snnTorch's importer) decays by 1 - dt / tau per
step instead of exp(-dt / tau): with these time constants (1.5 ms against a 1 ms step) its kernel is far
from C-LIF's. `discretisation="euler"` writes the constants for which Euler at dt = 1 ms, updating the
synaptic current first and the voltage from the new current, is C-LIF exactly: tau = dt / (1 - d) for
each decay d = exp(-1 / a) and r = V0 (d_m - d_s) / ((1 - d_m)(1 - d_s)). Those are not C-LIF's
continuous time constants; an exact integrator runs that graph wrong. The graph's metadata names which.

What NIR cannot say:
- the reset. C-LIF subtracts theta from V after a spike (the subtraction decays with a_m, as V does);
  NIR's CubaLIF sets v to v_reset (written as 0). A simulator with a reset by subtraction (Norse's
  `reset_method=reset_subtract`) reproduces C-LIF; one that follows NIR loses each spike's overshoot
  V - theta. Measured in docs/nir.md.
- the comparison: C-LIF fires at V >= theta, NIR at v > v_threshold (different only at exact equality).
- one time constant per channel: NIR stores a constant per neuron, so each channel's (a_m, a_s) is
  repeated over its feature map; hardware that wants one per layer cannot take the trained values.
- learnability (the softplus parametrisation of a_m > a_s): a graph holds the trained values only.
"""

from __future__ import annotations

import io
import os
from pathlib import Path
from typing import Literal

import numpy as np
import torch

from dvsot.core.errors import UserError, exception_line
from sctn.network import SCTN

DT_S = 1e-3  # C-LIF's step in the paper preset (1 ms), in NIR's unit (seconds); a network's own is its step_us
DISCRETISATIONS = ("exact", "euler")
LAYER_NAMES = ("conv1", "conv2", "conv3", "fc1", "fc2", "out")
TARGET = 1  # index of the target neuron in the network's output voltages and out_lif (0 is the background neuron)


def target_neuron(cfg) -> int:
    """Index of the target neuron in out_lif: TARGET, or 0 for a network without the background neuron."""
    return TARGET if cfg.background_neuron else 0


def clif_constants(model: SCTN) -> list[dict[str, np.ndarray]]:
    """Per C-LIF layer, per channel (float64): a_m, a_s (steps: ms in the preset), d_m, d_s (decays per step), V0."""
    layers = []
    for neuron in model.neurons:
        with torch.no_grad():
            a_m, a_s = (t.detach().to(torch.float64) for t in neuron.time_constants())
            d_m, d_s = torch.exp(-1.0 / a_m), torch.exp(-1.0 / a_s)
            v0 = _kernel_norm(d_m.numpy(), d_s.numpy(), a_m.numpy(), a_s.numpy())
        layers.append({"a_m": a_m.numpy(), "a_s": a_s.numpy(), "d_m": d_m.numpy(), "d_s": d_s.numpy(), "v0": v0})
    return layers


def _kernel_norm(d_m: np.ndarray, d_s: np.ndarray, a_m: np.ndarray, a_s: np.ndarray) -> np.ndarray:
    """V0 of sctn.neurons.kernel_norm in float64: one over the peak of d_m^k - d_s^k over integer k >= 1."""
    t_star = a_m * a_s / (a_m - a_s) * np.log(a_m / a_s)
    k_lo = np.maximum(np.floor(t_star), 1.0)
    return 1.0 / np.maximum(d_m ** k_lo - d_s ** k_lo, d_m ** (k_lo + 1) - d_s ** (k_lo + 1))


def cubalif_constants(c: dict[str, np.ndarray], discretisation: str = "exact", dt: float = DT_S
                      ) -> dict[str, np.ndarray]:
    """CubaLIF's tau_mem, tau_syn (s), r and w_in per channel for one C-LIF layer's clif_constants entry, for
    steps of dt seconds."""
    if discretisation == "exact":
        tau_mem, tau_syn = c["a_m"] * dt, c["a_s"] * dt
        r = c["v0"] * (c["a_m"] - c["a_s"])
    elif discretisation == "euler":
        tau_mem, tau_syn = dt / (1.0 - c["d_m"]), dt / (1.0 - c["d_s"])
        r = c["v0"] * (c["d_m"] - c["d_s"]) / ((1.0 - c["d_m"]) * (1.0 - c["d_s"]))
    else:
        raise ValueError(f"discretisation must be one of {', '.join(DISCRETISATIONS)}, got {discretisation!r}")
    return {"tau_mem": tau_mem, "tau_syn": tau_syn, "r": r, "w_in": np.ones_like(r)}


def sctn_graph(model: SCTN, discretisation: Literal["exact", "euler"] = "exact", source: str = ""):
    """The nir.NIRGraph of an SCTN: its convolutions, fully connected layers and C-LIF neurons as CubaLIF."""
    import nir

    cfg = model.cfg
    dt = cfg.step_us * 1e-6
    sizes = cfg.conv_sizes()
    consts = clif_constants(model)
    nodes: dict = {"input": nir.Input(input_type={"input": np.array([2, cfg.input_size, cfg.input_size])})}
    chain = ["input"]
    in_size = cfg.input_size
    for k, conv in enumerate(model.convs):
        name = LAYER_NAMES[k]
        weight = conv.weight.detach().numpy().astype(np.float32)
        bias = (conv.bias.detach().numpy() if conv.bias is not None else np.zeros(conv.out_channels)).astype(np.float32)
        nodes[name] = nir.Conv2d(input_shape=(in_size, in_size), weight=weight, stride=conv.stride,
                                 padding=conv.padding, dilation=conv.dilation, groups=conv.groups, bias=bias)
        shape = (conv.out_channels, sizes[k], sizes[k])
        nodes[f"{name}_lif"] = _cubalif(nir, consts[k], shape, model.neurons[k].theta, discretisation, dt)
        chain += [name, f"{name}_lif"]
        in_size = sizes[k]
    last = (cfg.channels[-1], sizes[-1], sizes[-1])
    nodes["flatten"] = nir.Flatten(input_type={"input": np.array(last)}, start_dim=0, end_dim=-1)
    chain.append("flatten")
    for k, fc in enumerate(model.fcs):
        name = LAYER_NAMES[3 + k]
        weight = fc.weight.detach().numpy().astype(np.float32)
        if fc.bias is None:
            nodes[name] = nir.Linear(weight=weight)
        else:
            nodes[name] = nir.Affine(weight=weight, bias=fc.bias.detach().numpy().astype(np.float32))
        nodes[f"{name}_lif"] = _cubalif(nir, consts[3 + k], (fc.out_features,), model.neurons[3 + k].theta,
                                        discretisation, dt)
        chain += [name, f"{name}_lif"]
    nodes["output"] = nir.Output(output_type={"output": np.array([model.fcs[2].out_features])})
    chain.append("output")
    edges = list(zip(chain[:-1], chain[1:]))
    metadata = {
        "producer": "dvsot sctn.nir_export",
        "dt": dt,
        "discretisation": discretisation,
        "reset": "C-LIF subtracts v_threshold after a spike (reset by subtraction); NIR's v_reset = 0 cannot say so",
        "steps": int(cfg.steps),
        "tail_steps": int(cfg.tail_steps),
        "input": (f"per step of dt, channel 0 OFF and 1 ON events inside the candidate box on a {cfg.input_size} x "
                  f"{cfg.input_size} canvas centred on it (dvsot sctn.encoding.encode_boxes), 1 where a pixel had "
                  f"an event in the step"),
        "target_index": target_neuron(cfg),
        "target": (f"out_lif neuron {target_neuron(cfg)} ("
                   + ("0 is background" if cfg.background_neuron else "no background neuron")
                   + "); its maximum voltage over the steps scores a box"),
        "source": source,
    }
    return nir.NIRGraph(nodes=nodes, edges=edges, metadata=metadata)


def _cubalif(nir, c: dict[str, np.ndarray], shape: tuple[int, ...], theta: float, discretisation: str, dt: float):
    """A CubaLIF node of `shape` whose per-channel constants (first axis) are those of C-LIF layer `c`."""
    p = cubalif_constants(c, discretisation, dt)
    expand = (-1,) + (1,) * (len(shape) - 1)

    def full(values) -> np.ndarray:
        return np.ascontiguousarray(np.broadcast_to(np.reshape(values, expand), shape), np.float64)

    return nir.CubaLIF(tau_syn=full(p["tau_syn"]), tau_mem=full(p["tau_mem"]), r=full(p["r"]),
                       v_leak=np.zeros(shape), v_threshold=np.full(shape, theta), v_reset=np.zeros(shape),
                       w_in=full(p["w_in"]))


def _sctn_checkpoint(path: Path) -> SCTN:
    """The SCTN of a checkpoint file; UserError naming the file and what it holds otherwise."""
    from dvsot.core.bounds import file_kind_problem
    from sctn.checkpoint import load_checkpoint, read_checkpoint

    held = _hdf5_content(path) if file_kind_problem(path) is None else None
    if held:
        raise UserError(f"{path}: holds {held}, not an SCTN checkpoint (the .pt that `dvsot train` writes)")
    try:
        model, _ = load_checkpoint(path)
    except UserError as exc:
        try:
            read_checkpoint(path, "sctn_ann", "sctn_ann", article="an")
        except UserError:
            raise exc from None
        raise UserError(f"{path}: holds a sctn_ann model (SCTN's ANN twin, ReLU units), which NIR cannot express "
                        f"(it has no rectifier node); only SCTN checkpoints export") from None
    except Exception as exc:  # a config or tensors that do not fit the network
        raise UserError(f"{path}: not a usable SCTN checkpoint ({exception_line(exc, 200)})") from None
    return model


def _hdf5_content(path: Path) -> str | None:
    """What an HDF5 file holds ("a NIR graph", "a dvsot dataset", ...), or None if the file is not HDF5."""
    import h5py

    from dvsot.dataset.format import FORMAT, decode_attr

    with open(path, "rb") as f:
        if f.read(8) != b"\x89HDF\r\n\x1a\n":
            return None
    try:
        with h5py.File(path, "r") as f:
            if "node" in f and "version" in f:
                return "a NIR graph"
            return "a dvsot dataset" if decode_attr(f.attrs.get("format")) == FORMAT else "HDF5 data"
    except OSError:
        return "a damaged HDF5 file"


def export_nir(checkpoint: str | os.PathLike, output: str | os.PathLike,
               discretisation: Literal["exact", "euler"] = "exact") -> Path:
    """Write an SCTN checkpoint as a NIR graph file (HDF5) at `output`, atomically; the path written.

    UserError (one line naming the file) for a file that is not an SCTN checkpoint, another model's
    included, or an output that cannot be written; nothing is written then.
    """
    import nir

    from dvsot.runtime.outputs import output_file, replacing

    if discretisation not in DISCRETISATIONS:
        raise UserError(f"discretisation must be one of {', '.join(DISCRETISATIONS)}, got {discretisation!r}")
    src = Path(checkpoint)
    out = output_file(output, "-o", [src])
    model = _sctn_checkpoint(src)
    graph = sctn_graph(model, discretisation, source=src.name)
    buffer = io.BytesIO()  # HDF5 built in memory: a full disk then fails one plain write, not h5py's teardown
    nir.write(buffer, graph)
    with replacing(out) as tmp, open(tmp, "wb") as f:
        f.write(buffer.getbuffer())
    return out
