"""Where a sample's error sits in time (sctn.loss.error_steps): STCA's rule, the preset's, its authors' code's edge
cases ("stca_code"), against the maximum."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from sctn.loss import error_steps, error_voltages, last_cluster_peaks, peak_steps

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from synthetic import moving_square_file  # noqa: E402

torch.set_num_threads(1)


def _volts(*rows: list[float]) -> torch.Tensor:
    """(N, T, 1) voltages of one neuron from rows of T values."""
    return torch.tensor(rows, dtype=torch.float32)[:, :, None]


def test_peak_steps_closed_form() -> None:
    v = _volts([0.0, 0.2, 0.1, 0.3, 0.25],   # two peaks: 0.3 at step 3 is the higher
               [0.0, 0.0, -0.2, -0.4, -0.1],  # no peak: rest, then below rest, rising at the end from below
               [0.0, 0.0, -0.2, -0.1, -0.3],  # a peak below rest at step 3
               [0.1, 0.2, 0.3, 0.4, 0.45],    # rising to the end: the last step
               [0.0, 0.7, 0.2, 0.1, 0.0])     # its only peak is at theta or above: none below it
    assert peak_steps(v)[:, 0].tolist() == [3, 4, 3, 4, -1]
    assert peak_steps(_volts([0.0, 0.0, 0.0]))[:, 0].tolist() == [-1]  # resting: no peak


def test_stca_steps_by_case() -> None:
    v = _volts([0.0, 0.0, -0.3, -0.2, -0.4],  # should fire, never did, a peak at step 3
               [0.0, 0.0, -0.1, -0.2, -0.3],  # should fire, no peak: a drawn step
               [0.0, 0.6, 0.2, 0.8, 0.1],     # fired: its firing step of largest V
               [0.0, 0.3, 0.1, 0.0, 0.0])     # should not fire: the step of largest V
    should = torch.tensor([[True], [True], [True], [False]])
    rng = np.random.default_rng(5)
    drawn = np.random.default_rng(5).integers(0, 5, size=(4, 1))
    steps = error_steps(v, should, "stca", rng)[:, 0].tolist()
    assert steps == [3, int(drawn[1, 0]), 3, 1]
    assert error_steps(v, should, "max")[:, 0].tolist() == [0, 0, 3, 1]  # the first of equal maxima: a quiet step
    with pytest.raises(ValueError, match="random generator"):
        error_steps(v, should, "stca")
    with pytest.raises(ValueError, match="unknown error time"):
        error_steps(v, should, "mean")


def test_last_cluster_peaks_closed_form() -> None:
    v = _volts([0.0, 0.9, 0.2, 0.6, 0.7, 0.3],  # clusters {1} and {3, 4}: the last one's peak is step 4
               [0.6, 0.8, 0.55, 0.1, 0.0, 0.0],  # one cluster {0, 1, 2} from the first step: its peak, step 1
               [0.0, 0.1, 0.2, 0.3, 0.2, 0.1],   # never reaches theta: none
               [0.1, 0.2, 0.9, 0.1, 0.5, 0.5],   # last cluster {4, 5} at exactly theta: its first, step 4
               [0.0, 0.0, 0.0, 0.0, 0.7, 0.9])   # fires into the last step: the last step
    assert last_cluster_peaks(v)[:, 0].tolist() == [4, 1, -1, 4, 5]


def test_stca_code_steps_by_case() -> None:
    v = _volts([0.0, 0.0, -0.3, -0.2, -0.4],  # should fire, never did, a peak at step 3: as "stca"
               [0.0, 0.0, -0.1, -0.2, -0.3],  # should fire, no peak: the last step (STCA's code), not a drawn one
               [0.0, 0.6, 0.2, 0.8, 0.1],     # should fire and fired: its firing step of largest V, as "stca"
               [0.0, 0.3, 0.1, 0.0, 0.0],     # should not fire, did not: the step of largest V, as "stca"
               [0.0, 0.9, 0.1, 0.6, 0.2])     # should not fire, fired twice: the last cluster's peak, step 3
    should = torch.tensor([[True], [True], [True], [False], [False]])
    assert error_steps(v, should, "stca_code")[:, 0].tolist() == [3, 4, 3, 1, 3]
    rng = np.random.default_rng(5)
    stca = error_steps(v, should, "stca", rng)[:, 0].tolist()  # today's rule: a drawn step, the largest V overall
    assert stca[4] == 1 and stca[1] == int(np.random.default_rng(5).integers(0, 5, size=(5, 1))[1, 0])
    # the neurons of one sample are ruled apart: the background (should not fire) and the target (should)
    two = torch.stack([v[4, :, 0], v[1, :, 0]], dim=1)[None]
    assert error_steps(two, torch.tensor([[False, True]]), "stca_code")[0].tolist() == [3, 4]


def test_stca_code_draws_nothing_and_its_gradient_sits_at_one_step() -> None:
    volts = torch.randn(6, 10, 2, requires_grad=True)
    pos = torch.tensor([True, False, True, False, True, False])
    rng = np.random.default_rng(0)
    state = rng.bit_generator.state
    error_voltages(volts, pos, "stca_code", rng).sum().backward()
    assert rng.bit_generator.state == state
    assert torch.equal((volts.grad != 0).sum(dim=1), torch.ones(6, 2, dtype=torch.long))


def test_max_rule_is_vmax_and_gradient_sits_at_one_step() -> None:
    volts = torch.randn(6, 10, 2, requires_grad=True)
    pos = torch.tensor([True, False, True, False, True, False])
    assert torch.equal(error_voltages(volts, pos, "max"), volts.max(dim=1).values)
    v = error_voltages(volts, pos, "stca", np.random.default_rng(0))
    v.sum().backward()
    assert torch.equal((volts.grad != 0).sum(dim=1), torch.ones(6, 2, dtype=torch.long))


def test_shipped_checkpoint_with_negative_target_row_learns_only_with_stca(tmp_path) -> None:
    """The shipped network with its target neuron's weights set to -|w| never fires; on a segment whose first
    2 ms are quiet the maximum sits on a quiet step (zero gradient, loss not zero); STCA's rule reaches every
    layer."""
    from dvsot.dataset import Dataset
    from sctn.checkpoint import load_checkpoint
    from sctn.encoding import encode_boxes
    from sctn.samples import TRAIN, labelled_samples
    from sctn.training.snn import TrainConfig, batch_loss

    path = moving_square_file(tmp_path / "syn.h5", duration_ms=40, seed=1)
    model, _ = load_checkpoint(None)
    with torch.no_grad():
        model.fcs[2].weight[1] = -model.fcs[2].weight[1].abs()
    with Dataset(path) as ds:
        seg, wh = ds.segment(2), (ds.width, ds.height)
    boxes, iou, pos = labelled_samples(np.random.default_rng(0), seg.box, TRAIN, wh)
    x = encode_boxes(seg.events, seg.t0_us - 2000, boxes, model.cfg)  # the segment 2 ms later: steps 0-1 quiet
    assert x[:, :2].sum() == 0 and x.sum() > 0
    iou, pos = torch.from_numpy(iou), torch.from_numpy(pos)
    layers = list(model.convs) + list(model.fcs)
    grads = {}
    for rule in ("max", "stca"):
        model.zero_grad()
        loss = batch_loss(model(x), iou, pos, TrainConfig(error_time=rule), np.random.default_rng(0))
        loss.backward()
        assert float(loss.detach()) > 0
        grads[rule] = [float(layer.weight.grad.abs().sum()) for layer in layers]
    assert grads["max"] == [0.0] * len(layers)
    assert all(g > 0 for g in grads["stca"]), grads["stca"]


def test_checkpoints_trained_the_old_way_load_with_one_note(tmp_path) -> None:
    """No error_time recorded (the shipped checkpoints) is the old rule; "max" and a non-preset init are named;
    a checkpoint of today's preset, or one without a training config, loads without a note."""
    import warnings

    from sctn.checkpoint import TrainingRuleWarning, load_checkpoint, save_checkpoint
    from sctn.network import SCTN
    from sctn.training.snn import TrainConfig

    def notes(meta: dict) -> list[str]:
        path = save_checkpoint(tmp_path / "c.pt", SCTN(), meta)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            load_checkpoint(path)
        return [str(w.message) for w in caught if issubclass(w.category, TrainingRuleWarning)]

    old = TrainConfig().model_dump()
    del old["error_time"], old["init"]
    old["calibrate"] = False
    assert len(notes({"train_config": old})) == 1 and "old error-time rule" in notes({"train_config": old})[0]
    assert "init 'calibrate'" in notes({"train_config": {**old, "calibrate": True}})[0]
    max_rule = notes({"train_config": TrainConfig(error_time="max", init="fluctuation").model_dump()})
    assert len(max_rule) == 1 and "error_time 'max'" in max_rule[0] and "init 'fluctuation'" in max_rule[0]
    assert notes({"train_config": TrainConfig().model_dump()}) == [] and notes({}) == []


def test_calibrate_flag_is_the_calibrate_init() -> None:
    from sctn.training.snn import TrainConfig, TrainConfigError

    assert TrainConfig(calibrate=True).init == "calibrate" and TrainConfig(calibrate=True).calibrate
    assert TrainConfig(calibrate=False).init == "kaiming" and "calibrate" not in TrainConfig().model_dump()
    with pytest.raises(TrainConfigError):
        TrainConfig(calibrate=True, init="fluctuation")
    with pytest.raises(TrainConfigError, match="init"):
        TrainConfig(init="xavier")


def test_fluctuation_init_sets_the_membrane_fluctuations_to_theta_over_xi() -> None:
    """On Bernoulli input of rate nu, conv1's V at the last step varies over input draws (fixed weights) by
    n sigma_w^2 nu (1 - nu) eps2 = (theta / xi)^2 (1 - nu): the closed form the initialisation solves."""
    from sctn.network import SCTN, window_rate

    torch.manual_seed(0)
    nu, xi = 0.05, 2.0
    x = (torch.rand(48, 10, 2, 107, 107) < nu).float()
    net = SCTN()
    stds = net.fluctuation_init(x[:8], xi=xi)
    assert len(stds) == 6 and all(s > 0 for s in stds)
    assert window_rate(net.convs[0], x[:8].transpose(0, 1)) == pytest.approx(nu, rel=0.05)
    with torch.no_grad():
        v = net._run(x, record=False, capture=0)[1][-1]  # (B, C, H, W) conv1's V at the last step
    measured = float(v.var(dim=0).mean())
    theta = net.neurons[0].theta
    assert measured == pytest.approx((theta / xi) ** 2 * (1 - nu), rel=0.15)


def test_window_rate_counts_only_windows_that_receive_input() -> None:
    from torch import nn

    from sctn.network import window_rate

    conv = nn.Conv2d(2, 4, 2, stride=2)
    spikes = torch.zeros(5, 1, 2, 4, 4)
    spikes[0, 0, 0, 0, 0] = 1  # one spike in the top-left window, three more in the same window later
    spikes[1:4, 0, 1, 1, 1] = 1
    assert window_rate(conv, spikes) == pytest.approx(4 / (2 * 2 * 2 * 5))
    fc = nn.Linear(32, 3)
    assert window_rate(fc, spikes.reshape(5, 1, -1)) == pytest.approx(4 / (32 * 5))
    assert window_rate(fc, torch.zeros(5, 2, 32)) == 0.0
