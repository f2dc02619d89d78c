"""A small numpy simulator of NIR graphs, written from NIR's node equations (no torch, nothing of SCTN's code).

Nodes: Input, Output, Conv2d (dilation 1, one group), Flatten, Linear, Affine, Scale, CubaLIF, LIF.
Time runs in steps of dt seconds; every node of a step runs in the graph's topological order, so a spike
reaches the next layer in the step it is fired in (no delay per edge); cycles are refused. A node with
several incoming edges gets their sum.

Neurons, from NIR's equations (CubaLIF: tau_syn dI/dt = -I + w_in S, tau_mem dv/dt = (v_leak - v) + r I;
LIF: tau dv/dt = (v_leak - v) + r S; z = [v > v_threshold]). The input of step n is its value held for
the step, i.e. an impulse of area value x dt at the step's start; v is read and compared with the
threshold at the step's end:

- integrator "exact": the linear ODE solved in closed form over the step (decays exp(-dt / tau));
- integrator "euler": forward Euler at dt, the synaptic current updated first and the voltage from the
  new current: I += dt / tau_syn (w_in x - I), v += dt / tau_mem (v_leak - v + r I).

Reset "value" (NIR's): v = v_reset after a spike; "subtract": v -= v_threshold (not NIR's, for comparison
with models whose reset subtracts). Voltages are recorded before the reset, as C-LIF reports V.
"""

from __future__ import annotations

from typing import Literal

import numpy as np

INTEGRATORS = ("exact", "euler")
RESETS = ("value", "subtract")


def run_graph(graph, x: np.ndarray, dt: float, integrator: Literal["exact", "euler"] = "exact",
              reset: Literal["value", "subtract"] = "value") -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """Run a nir.NIRGraph on inputs x (T, B, *input shape) at step dt (s): each node's outputs (T, B, ...) and each
    neuron node's voltages before reset (T, B, ...), float64, by node name."""
    import nir

    if integrator not in INTEGRATORS or reset not in RESETS:
        raise ValueError(f"integrator must be one of {INTEGRATORS}, reset one of {RESETS}")
    order = topological_order(graph)
    inputs = [n for n in order if isinstance(graph.nodes[n], nir.Input)]
    if len(inputs) != 1:
        raise ValueError(f"need exactly one Input node, found {len(inputs)}")
    sources: dict[str, list[str]] = {n: [] for n in graph.nodes}
    for a, b in graph.edges:
        sources[b].append(a)
    x = np.asarray(x, np.float64)
    outputs: dict[str, np.ndarray] = {}
    volts: dict[str, np.ndarray] = {}
    for name in order:
        node = graph.nodes[name]
        if isinstance(node, nir.Input):
            outputs[name] = x
            continue
        if not sources[name]:
            raise ValueError(f"node {name!r} has no incoming edge")
        h = sum(outputs[s] for s in sources[name])
        t, b = h.shape[:2]
        if isinstance(node, nir.Output):
            outputs[name] = h
        elif isinstance(node, nir.Conv2d):
            y = conv2d(h.reshape((t * b,) + h.shape[2:]), node)
            outputs[name] = y.reshape((t, b) + y.shape[1:])
        elif isinstance(node, nir.Flatten):
            outputs[name] = flatten(h, node.start_dim, node.end_dim)
        elif isinstance(node, (nir.Linear, nir.Affine)):
            y = h @ np.asarray(node.weight, np.float64).T
            outputs[name] = y + node.bias if isinstance(node, nir.Affine) else y
        elif isinstance(node, nir.Scale):
            outputs[name] = h * node.scale
        elif isinstance(node, nir.CubaLIF):
            outputs[name], volts[name] = cubalif(h, node, dt, integrator, reset)
        elif isinstance(node, nir.LIF):
            outputs[name], volts[name] = lif(h, node, dt, integrator, reset)
        else:
            raise ValueError(f"node {name!r}: {type(node).__name__} is not simulated here")
    return outputs, volts


def topological_order(graph) -> list[str]:
    """The graph's node names with every edge's source before its target; ValueError for a cycle."""
    indegree = {n: 0 for n in graph.nodes}
    for _, b in graph.edges:
        indegree[b] += 1
    ready = [n for n, d in indegree.items() if d == 0]
    order = []
    while ready:
        n = ready.pop(0)
        order.append(n)
        for a, b in graph.edges:
            if a == n:
                indegree[b] -= 1
                if indegree[b] == 0:
                    ready.append(b)
    if len(order) != len(graph.nodes):
        raise ValueError("the graph has a cycle: recurrent graphs are not simulated here")
    return order


def _pair(v) -> tuple[int, int]:
    a = np.broadcast_to(np.asarray(v, np.int64).reshape(-1), (2,))
    return int(a[0]), int(a[1])


def conv2d(x: np.ndarray, node) -> np.ndarray:
    """NIR Conv2d (cross-correlation, as torch's) of x (N, C, H, W): (N, C_out, H', W') plus the bias."""
    if isinstance(node.padding, str) or _pair(node.dilation) != (1, 1) or int(node.groups) != 1:
        raise ValueError("Conv2d: only integer padding, dilation 1 and one group are simulated here")
    w = np.asarray(node.weight, np.float64)
    kh, kw = w.shape[-2:]
    (sh, sw), (ph, pw) = _pair(node.stride), _pair(node.padding)
    if ph or pw:
        x = np.pad(x, ((0, 0), (0, 0), (ph, ph), (pw, pw)))
    windows = np.lib.stride_tricks.sliding_window_view(x, (kh, kw), axis=(2, 3))[:, :, ::sh, ::sw]
    y = np.einsum("nchwij,ocij->nohw", windows, w, optimize=True)
    return y + np.asarray(node.bias, np.float64)[None, :, None, None]


def flatten(h: np.ndarray, start_dim: int, end_dim: int) -> np.ndarray:
    """NIR Flatten of (T, B, *shape): dims start_dim..end_dim of the shape (no batch in NIR's types) made one."""
    shape = h.shape[2:]
    end = end_dim % len(shape)
    new = shape[:start_dim] + (int(np.prod(shape[start_dim:end + 1])),) + shape[end + 1:]
    return h.reshape(h.shape[:2] + new)


def _fire(v: np.ndarray, node, reset: str) -> tuple[np.ndarray, np.ndarray]:
    """Spikes z = [v > v_threshold] and v after the reset."""
    z = v > node.v_threshold
    after = np.where(z, node.v_reset if reset == "value" else v - node.v_threshold, v)
    return z, after


def cubalif(h: np.ndarray, node, dt: float, integrator: str, reset: str) -> tuple[np.ndarray, np.ndarray]:
    """CubaLIF over inputs h (T, B, *shape): spikes and voltages before reset (T, B, *shape)."""
    tau_s, tau_m = np.asarray(node.tau_syn, np.float64), np.asarray(node.tau_mem, np.float64)
    r, w_in, v_leak = (np.asarray(a, np.float64) for a in (node.r, node.w_in, node.v_leak))
    cur = np.zeros(h.shape[1:])
    v = np.zeros(h.shape[1:]) + v_leak
    spikes, volts = np.zeros(h.shape, bool), np.zeros(h.shape)
    if integrator == "exact":
        a, b = np.exp(-dt / tau_m), np.exp(-dt / tau_s)
        # v's response over dt to a current I that starts the step at I and decays with tau_s
        same = np.isclose(tau_m, tau_s)
        gain = np.where(same, dt / tau_m * a, tau_s / np.where(same, 1.0, tau_m - tau_s) * (a - b))
    for n in range(h.shape[0]):
        if integrator == "exact":
            cur = cur + w_in * h[n] * dt / tau_s
            v = v_leak + (v - v_leak) * a + r * cur * gain
            cur = cur * b
        else:
            cur = cur + dt / tau_s * (w_in * h[n] - cur)
            v = v + dt / tau_m * (v_leak - v + r * cur)
        volts[n] = v
        spikes[n], v = _fire(v, node, reset)
    return spikes.astype(np.float64), volts


def lif(h: np.ndarray, node, dt: float, integrator: str, reset: str) -> tuple[np.ndarray, np.ndarray]:
    """LIF over inputs h (T, B, *shape): spikes and voltages before reset (T, B, *shape)."""
    tau, r, v_leak = (np.asarray(a, np.float64) for a in (node.tau, node.r, node.v_leak))
    v = np.zeros(h.shape[1:]) + v_leak
    spikes, volts = np.zeros(h.shape, bool), np.zeros(h.shape)
    a = np.exp(-dt / tau)
    for n in range(h.shape[0]):
        if integrator == "exact":  # the impulse r x dt / tau at the step's start, then a free decay
            v = v_leak + (v - v_leak + r * h[n] * dt / tau) * a
        else:
            v = v + dt / tau * (v_leak - v + r * h[n])
        volts[n] = v
        spikes[n], v = _fire(v, node, reset)
    return spikes.astype(np.float64), volts
