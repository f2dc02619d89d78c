"""The background output neuron: kept and untrained (the preset: the paper's two output neurons, eq. 5 on the target),
trained by the mirrored error (row background_term), or left out of the network and its operation counts (row
no_background_neuron)."""

import json
import sys
from pathlib import Path

import nir
import numpy as np
import pytest
import torch

from benchmarks.experiments.ablation import ROWS, training_key
from sctn.ann import SCTNTwin, TwinConfig, twin_macs
from sctn.energy import count_synaptic_ops, snn_state_updates
from sctn.loss import error_voltages, voltage_loss
from sctn.network import SCTN, NetworkConfig
from sctn.nir_export import DT_S, sctn_graph, target_neuron
from sctn.nir_sim import run_graph
from sctn.training.loop import TrainConfigError
from sctn.training.snn import TrainConfig

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from synthetic import moving_square_file  # noqa: E402

torch.set_num_threads(1)
SMALL = {"channels": (4, 8, 8), "fc": (16, 8)}


def _pair(seed: int = 0, **cfg) -> tuple[SCTN, SCTN]:
    """The preset-layout network and the one without the background neuron, built from the same seed."""
    torch.manual_seed(seed)
    kept = SCTN(NetworkConfig(**cfg))
    torch.manual_seed(seed)
    left_out = SCTN(NetworkConfig(**cfg, background_neuron=False))
    return kept, left_out


def _input(seed: int, n: int = 6) -> torch.Tensor:
    g = torch.Generator().manual_seed(seed)
    return (torch.rand(n, 10, 2, 107, 107, generator=g) < 0.06).float()


def test_the_preset_keeps_both_output_neurons():
    assert NetworkConfig().background_neuron and NetworkConfig().outputs() == 2
    assert SCTN().fcs[2].out_features == 2 and not TrainConfig().background_term


def test_left_out_the_network_has_the_target_alone_with_the_presets_first_weights():
    kept, left_out = _pair(**SMALL)
    assert left_out.fcs[2].weight.shape == (1, 8) and left_out.neurons[5].p_m.shape == (1,)
    assert torch.equal(left_out.fcs[2].weight, kept.fcs[2].weight[1:])  # the target's row, drawn as the preset draws it
    for p, q in zip(list(kept.convs.parameters()) + list(kept.fcs[:2].parameters()),
                    list(left_out.convs.parameters()) + list(left_out.fcs[:2].parameters())):
        assert torch.equal(p, q)
    x = _input(1)
    v_kept, v_out = kept(x), left_out(x)
    assert v_out.shape == v_kept.shape == (6, 10, 2) and not v_out[:, :, 0].any()  # no neuron: a constant 0 there
    # the same target to float rounding (a one-column product may sum in another order than a two-column one)
    torch.testing.assert_close(v_out[:, :, 1], v_kept[:, :, 1], rtol=0, atol=1e-5)


def test_left_out_the_background_costs_no_operations():
    kept, left_out = _pair(2, **SMALL)
    x = _input(3)
    a, b = count_synaptic_ops(kept, x), count_synaptic_ops(left_out, x)
    fc2_spikes = a["spikes_by_layer"]["fc2"]
    assert fc2_spikes > 0 and b["spikes_by_layer"]["fc2"] == fc2_spikes
    assert a["ac_ops_by_layer"]["fc2"] == pytest.approx(2 * fc2_spikes)  # each fc2 spike drives both outputs
    assert b["ac_ops_by_layer"]["fc2"] == pytest.approx(fc2_spikes)  # ... or the target alone
    cfg = kept.cfg
    assert snn_state_updates(cfg) - snn_state_updates(left_out.cfg) == cfg.steps + cfg.tail_steps  # one neuron less
    twin_kept, twin_out = SCTNTwin(TwinConfig(**SMALL)), SCTNTwin(TwinConfig(**SMALL, background_neuron=False))
    assert twin_macs(twin_kept)["mac_ops"] - twin_macs(twin_out)["mac_ops"] == SMALL["fc"][1]  # one output unit less
    assert twin_out(x).shape == (6, 1, 2) and not twin_out(x)[:, :, 0].any()


def test_only_the_mirrored_error_trains_the_background_neuron():
    torch.manual_seed(4)
    net = SCTN(NetworkConfig(**SMALL))
    net.calibrate(_input(5, 8), quantile=0.6)  # every layer reaches the output
    x, iou = _input(5, 8), torch.linspace(0.0, 1.0, 8)
    pos = iou >= 0.7
    grads = {}
    for background in (False, True):
        net.zero_grad()
        volts = net(x)
        loss = voltage_loss(error_voltages(volts, pos, "stca", np.random.default_rng(0)), iou, pos,
                            background=background)
        loss.backward()
        grads[background] = net.fcs[2].weight.grad.clone()
    assert not grads[False][0].any() and grads[False][1].any()  # eq. 5 of the target: the background gets nothing
    assert grads[True][0].any()


def test_the_mirrored_error_needs_the_background_neuron(tmp_path, capsys):
    with pytest.raises(TrainConfigError, match="background_term needs the background neuron"):
        TrainConfig(background_term=True, network=NetworkConfig(background_neuron=False))
    from dvsot.cli import main

    data = moving_square_file(tmp_path / "d.h5", width=64, height=48, size=12, duration_ms=30)
    out = tmp_path / "m.pt"
    assert main(["train", "--data", str(data), "-o", str(out), "--background-term", "--no-background-neuron"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--background-term needs the background neuron" in err[0] and not out.exists()


def test_a_network_without_the_background_neuron_trains_saves_and_loads(tmp_path, capsys):
    from dvsot.cli import main
    from sctn.checkpoint import load_checkpoint

    data = moving_square_file(tmp_path / "d.h5", width=64, height=48, size=12, duration_ms=60,
                              velocity_px_s=(100.0, 40.0), start=(10.0, 10.0))
    out = tmp_path / "m.pt"
    assert main(["train", "--data", str(data), "-o", str(out), "--no-background-neuron", "--epochs", "1",
                 "--segments-per-epoch", "2", "--batch-segments", "1", "--channels", "2", "2", "2", "--fc", "4", "4",
                 "--threads", "1", "--quiet"]) == 0
    capsys.readouterr()
    model, meta = load_checkpoint(out)
    assert model.fcs[2].out_features == 1 and meta["train_config"]["network"]["background_neuron"] is False
    assert json.loads(out.with_suffix(".json").read_text())["config"]["background_neuron"] is False


def test_the_nir_graph_of_a_network_without_the_background_neuron_reproduces_it(tmp_path):
    _, net = _pair(6, **SMALL)
    net.calibrate(_input(7, 4), quantile=0.6)
    x = _input(7, 4)
    with torch.no_grad():
        volts, spikes = net.forward_record(x)
    nir.write(tmp_path / "g.nir", sctn_graph(net))
    graph = nir.read(tmp_path / "g.nir")
    assert int(graph.metadata["target_index"]) == target_neuron(net.cfg) == 0
    outputs, v = run_graph(graph, x.numpy().transpose(1, 0, 2, 3, 4), DT_S, "exact", "subtract")
    np.testing.assert_array_equal(outputs["out_lif"].reshape(spikes[-1].shape), spikes[-1].numpy())
    np.testing.assert_allclose(v["out_lif"][:, :, 0], volts[:, :, 1].numpy().T, atol=1e-4)


def test_both_rows_are_named_ablation_rows():
    assert ROWS["background_term"] == ({"background_term": True}, {}, {})
    assert ROWS["no_background_neuron"] == ({}, {"background_neuron": False}, {})
    assert training_key("background_term") == "background_term"
    assert training_key("no_background_neuron") == "no_background_neuron"  # its own networks
