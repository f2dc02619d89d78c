"""SCTN as a NIR graph: the exported file, run by a numpy simulator of NIR's node equations, reproduces dvsot's
spikes and voltages; `dvsot export-model` writes it atomically and refuses other models' files."""

from __future__ import annotations

import ast
import errno
from pathlib import Path

import nir
import numpy as np
import pytest
import torch

from dvsot.cli import main
from dvsot.core.errors import RunError
from sctn.checkpoint import default_checkpoint_path, load_checkpoint
from sctn.encoding import encode_boxes
from sctn.network import SCTN, NetworkConfig
from sctn.neurons import psp_kernel
from sctn.nir_export import DT_S, LAYER_NAMES, TARGET, clif_constants, cubalif_constants, export_nir, sctn_graph
from sctn.nir_sim import run_graph
from sctn.samples import TRACK, propose
from tests.synthetic import moving_square_file

ROOT = Path(__file__).resolve().parents[2]
LIF_NODES = [f"{name}_lif" for name in LAYER_NAMES]
V_TOL = 1e-4  # dvsot runs float32, the simulator float64


@pytest.fixture(scope="module")
def segment_input(tmp_path_factory) -> torch.Tensor:
    """SCTN's input (N, T, 2, 107, 107) for the true box and 7 tracker candidates of a synthetic segment."""
    from dvsot.dataset import Dataset

    path = moving_square_file(tmp_path_factory.mktemp("nir") / "square.h5", duration_ms=40, size=40)
    with Dataset(path) as ds:
        seg = ds.segment(2)
        box = seg.box.astype(np.float64)
        boxes = propose(np.random.default_rng(0), box, 7, "gaussian", TRACK.trans, TRACK.scale, (ds.width, ds.height))
        return encode_boxes(seg.events, seg.t0_us, np.concatenate([box[None], boxes]))


@pytest.fixture(scope="module")
def shipped() -> SCTN:
    """The shipped network with its target row of the output layer times -3: on the synthetic square (which it
    scores below zero) the target neuron then fires, so the output layer's reset is exercised too."""
    model = load_checkpoint(None)[0]
    with torch.no_grad():
        model.fcs[2].weight[TARGET] *= -3.0
    return model


def dvsot_run(model: SCTN, x: torch.Tensor) -> tuple[list[np.ndarray], np.ndarray]:
    """dvsot's spikes per C-LIF layer (T, N, ...) and output voltages (T, N, 2)."""
    with torch.no_grad():
        volts, spikes = model.forward_record(x)
    return [s.numpy() for s in spikes[1:]], volts.numpy().transpose(1, 0, 2)


def written_and_read(graph, path: Path):
    """The graph after a round trip through a NIR file (what another tool reads)."""
    nir.write(path, graph)
    return nir.read(path)


def test_exported_graph_run_by_nir_equations_reproduces_dvsot(shipped, segment_input, tmp_path):
    graph = written_and_read(sctn_graph(shipped), tmp_path / "sctn.nir")
    ref_spikes, ref_volts = dvsot_run(shipped, segment_input)
    outputs, volts = run_graph(graph, segment_input.numpy().transpose(1, 0, 2, 3, 4), DT_S, "exact", "subtract")
    for name, ref in zip(LIF_NODES, ref_spikes):
        assert ref.sum() > 0, f"{name}: no spike in dvsot's run, the comparison would prove little"
        np.testing.assert_array_equal(outputs[name].reshape(ref.shape), ref, err_msg=name)
    np.testing.assert_allclose(volts["out_lif"], ref_volts, atol=V_TOL)
    np.testing.assert_allclose(volts["out_lif"][:, :, TARGET].max(axis=0), ref_volts[:, :, TARGET].max(axis=0),
                               atol=V_TOL)


def test_euler_constants_make_forward_euler_reproduce_dvsot(shipped, segment_input):
    ref_spikes, ref_volts = dvsot_run(shipped, segment_input)
    steps = segment_input.numpy().transpose(1, 0, 2, 3, 4)
    outputs, volts = run_graph(sctn_graph(shipped, "euler"), steps, DT_S, "euler", "subtract")
    for name, ref in zip(LIF_NODES, ref_spikes):
        np.testing.assert_array_equal(outputs[name].reshape(ref.shape), ref, err_msg=name)
    np.testing.assert_allclose(volts["out_lif"], ref_volts, atol=V_TOL)
    # the exact constants under forward Euler at 1 ms are another network: that is why both are written
    wrong, _ = run_graph(sctn_graph(shipped, "exact"), steps, DT_S, "euler", "subtract")
    assert wrong["conv1_lif"].sum() != ref_spikes[0].sum()


def test_nir_reset_to_value_matches_until_each_neuron_first_fires(shipped, segment_input):
    """NIR's CubaLIF resets v to v_reset; C-LIF subtracts theta. conv1 sees the same input either way, so its
    voltages agree at every step up to and including each neuron's first spike, and not after."""
    ref_spikes, _ = dvsot_run(shipped, segment_input)
    steps = segment_input.numpy().transpose(1, 0, 2, 3, 4)
    _, sub = run_graph(sctn_graph(shipped), steps, DT_S, "exact", "subtract")
    _, val = run_graph(sctn_graph(shipped), steps, DT_S, "exact", "value")
    fired = ref_spikes[0].reshape(sub["conv1_lif"].shape) > 0
    before = np.cumsum(fired, axis=0) - fired == 0  # no spike in an earlier step
    np.testing.assert_allclose(val["conv1_lif"][before], sub["conv1_lif"][before], atol=1e-12)
    assert np.abs(val["conv1_lif"][~before] - sub["conv1_lif"][~before]).max() > 1e-3


def test_exported_neuron_kernel_is_clif_kernel_in_closed_form():
    """One C-LIF neuron of the preset (a_m = 4, a_s = 1.5 ms) as CubaLIF, fed one spike: v at the end of step k is
    the paper's kernel K(k ms) (eq. 4) scaled by the discrete V0, whose peak over the steps is exactly 1."""
    model = SCTN(NetworkConfig())
    c = clif_constants(model)[0]
    np.testing.assert_allclose(c["a_m"], 4.0)
    np.testing.assert_allclose(c["a_s"], 1.5)
    p = cubalif_constants({k: v[:1] for k, v in c.items()})
    node = nir.CubaLIF(tau_syn=p["tau_syn"], tau_mem=p["tau_mem"], r=p["r"], v_leak=np.zeros(1),
                       v_threshold=np.full(1, 1e9), w_in=p["w_in"])
    graph = nir.NIRGraph(nodes={"input": nir.Input(input_type={"input": np.array([1])}), "lif": node,
                                "output": nir.Output(output_type={"output": np.array([1])})},
                         edges=[("input", "lif"), ("lif", "output")])
    x = np.zeros((12, 1, 1))
    x[0] = 1.0
    _, v = run_graph(graph, x, DT_S, "exact")
    volts = v["lif"]
    k = np.arange(1, 13)
    continuous = psp_kernel(torch.tensor(k, dtype=torch.float64), 4.0, 1.5).numpy()  # peak 1 at t*, continuous
    expected = np.exp(-k / 4.0) - np.exp(-k / 1.5)
    np.testing.assert_allclose(volts[:, 0, 0], expected / expected.max(), rtol=1e-12)
    assert volts.max() == pytest.approx(1.0, abs=1e-12)
    ratio = volts[:, 0, 0] / continuous  # the continuous kernel sampled at whole ms, up to V0's normalisation
    np.testing.assert_allclose(ratio, ratio[0], rtol=1e-9)
    e = cubalif_constants({k_: v[:1] for k_, v in c.items()}, "euler")
    np.testing.assert_allclose(1 - DT_S / e["tau_mem"], np.exp(-1 / 4.0), rtol=1e-12)
    np.testing.assert_allclose(1 - DT_S / e["tau_syn"], np.exp(-1 / 1.5), rtol=1e-12)


def test_graph_nodes_shapes_and_metadata(shipped, tmp_path):
    graph = written_and_read(sctn_graph(shipped), tmp_path / "g.nir")
    kinds = {name: type(node).__name__ for name, node in graph.nodes.items()}
    assert kinds == {"input": "Input", "conv1": "Conv2d", "conv1_lif": "CubaLIF", "conv2": "Conv2d",
                     "conv2_lif": "CubaLIF", "conv3": "Conv2d", "conv3_lif": "CubaLIF", "flatten": "Flatten",
                     "fc1": "Linear", "fc1_lif": "CubaLIF", "fc2": "Linear", "fc2_lif": "CubaLIF", "out": "Linear",
                     "out_lif": "CubaLIF", "output": "Output"}
    assert graph.nodes["conv1_lif"].v_threshold.shape == (8, 26, 26)
    assert graph.nodes["out_lif"].v_threshold.shape == (2,)
    np.testing.assert_array_equal(graph.nodes["conv1"].weight, shipped.convs[0].weight.detach().numpy())
    a_m = shipped.neurons[3].time_constants()[0].detach().numpy()
    np.testing.assert_allclose(graph.nodes["fc1_lif"].tau_mem, a_m * 1e-3, rtol=1e-6)
    assert float(graph.metadata["dt"]) == DT_S
    assert graph.metadata["discretisation"] in ("exact", b"exact")


def test_export_model_cli_writes_a_nir_file(tmp_path, capsys):
    out = tmp_path / "sctn.nir"
    assert main(["export-model", str(default_checkpoint_path()), "-o", str(out), "--discretisation", "euler"]) == 0
    assert capsys.readouterr().out.strip() == str(out)
    graph = nir.read(out)
    assert graph.metadata["discretisation"] in ("euler", b"euler")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["sctn.nir"]


@pytest.mark.parametrize("name, held", [
    ("sctn/checkpoints/sctn_ann_dvsot21.pt", "holds a sctn_ann model"),
    ("benchmarks/trackers/siamfc/checkpoints/siamfc_dvsot21.pt", "holds a siamfc model, not an SCTN one"),
])
def test_export_model_refuses_another_models_checkpoint(tmp_path, capsys, name, held):
    out = tmp_path / "sctn.nir"
    out.write_bytes(b"the previous export")
    assert main(["export-model", str(ROOT / name), "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(ROOT / name) in err[0] and held in err[0], err
    assert out.read_bytes() == b"the previous export"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["sctn.nir"]


def test_export_model_refuses_an_output_it_cannot_write(tmp_path, capsys):
    ckpt = str(default_checkpoint_path())
    assert main(["export-model", ckpt, "-o", str(tmp_path / "no" / "sctn.nir")]) == 2
    assert main(["export-model", ckpt, "-o", ckpt]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and "does not exist" in err[0] and "would overwrite an input file" in err[1], err


def test_export_model_names_what_a_non_checkpoint_holds(tmp_path, capsys):
    graph_file = tmp_path / "g.nir"
    nir.write(graph_file, sctn_graph(SCTN()))
    assert main(["export-model", str(graph_file), "-o", str(tmp_path / "out.nir")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and f"{graph_file}: holds a NIR graph, not an SCTN checkpoint" in err
    data = moving_square_file(tmp_path / "d.h5", duration_ms=20)
    assert main(["export-model", str(data), "-o", str(tmp_path / "out.nir")]) == 2
    assert "holds a dvsot dataset" in capsys.readouterr().err
    assert not (tmp_path / "out.nir").exists()


def test_a_failed_write_keeps_the_previous_file(tmp_path, monkeypatch):
    out = tmp_path / "sctn.nir"
    out.write_bytes(b"the previous export")

    import sctn.nir_export as module

    def full_disk(path, mode="r", *args, **kwargs):  # the graph, built in memory, written to a disk that fills up
        if "w" not in mode:
            return open(path, mode, *args, **kwargs)
        Path(path).write_bytes(b"half a file")
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(module, "open", full_disk, raising=False)
    with pytest.raises(RunError, match="No space left on device"):
        export_nir(default_checkpoint_path(), out)
    assert out.read_bytes() == b"the previous export"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["sctn.nir"]


def test_the_simulator_is_independent_of_what_it_checks():
    """sctn/nir_sim.py is written from NIR's equations: it imports no module of dvsot or sctn."""
    tree = ast.parse((ROOT / "sctn" / "nir_sim.py").read_text())
    names = {a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
    names |= {n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) and n.module}
    assert names <= {"__future__", "typing", "numpy", "nir"}, names


def test_a_network_with_biases_and_tail_steps_exports_too():
    """The older layout: biases become Conv2d biases and Affine nodes (a constant input each step), the tail
    steps are empty input steps the user appends (the metadata's tail_steps)."""
    torch.manual_seed(0)
    model = SCTN(NetworkConfig(bias=True, tail_steps=2, channels=(4, 8, 8), fc=(16, 8))).eval()
    with torch.no_grad():
        for layer in list(model.convs) + list(model.fcs):
            layer.bias.uniform_(-0.05, 0.1)
    x = (torch.rand(3, 10, 2, 107, 107) < 0.05).float()
    graph = sctn_graph(model)
    assert type(graph.nodes["fc1"]).__name__ == "Affine" and int(graph.metadata["tail_steps"]) == 2
    ref_spikes, ref_volts = dvsot_run(model, x)
    steps = np.concatenate([x.numpy(), np.zeros((3, 2, 2, 107, 107), np.float32)], axis=1).transpose(1, 0, 2, 3, 4)
    outputs, volts = run_graph(graph, steps, DT_S, "exact", "subtract")
    for name, ref in zip(LIF_NODES[:5], ref_spikes):
        assert ref.sum() > 0, name
        np.testing.assert_array_equal(outputs[name].reshape(ref.shape), ref, err_msg=name)
    np.testing.assert_allclose(volts["out_lif"], ref_volts, atol=V_TOL)
