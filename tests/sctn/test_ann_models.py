"""The ANN side: SCTN's ANN twin (layers, input, MACs by hand, trained and tracked by SCTN's code) and SiamFC (crops,
labels, loss, cross-correlation, tracking geometry, MACs by hand); checkpoints name the model they hold."""

import sys
from pathlib import Path

import numpy as np
import pytest
import torch
from torch.nn import functional as F

from benchmarks.trackers.siamfc.crops import balanced_weights, crop, exemplar_extent, response_labels
from benchmarks.trackers.siamfc.model import SiamFC, SiamFCConfig
from benchmarks.trackers.siamfc.train import logistic_loss
from dvsot.core.errors import UserError
from sctn.ann import SCTNTwin, TwinConfig, count_macs, load_twin, train_twin, twin_macs
from sctn.checkpoint import load_checkpoint, save_checkpoint
from sctn.network import SCTN, NetworkConfig

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from synthetic import moving_square_file  # noqa: E402

torch.set_num_threads(1)


def test_twin_has_sctns_layers_and_reads_the_bins_as_channels():
    twin, net = SCTNTwin(), SCTN()
    for a, b in zip(list(twin.convs) + list(twin.fcs)[1:], list(net.convs) + list(net.fcs)[1:]):
        assert a.weight.shape[0] == b.weight.shape[0] and a.weight.shape[2:] == b.weight.shape[2:]
    assert [c.stride for c in twin.convs] == [c.stride for c in net.convs]
    assert twin.convs[0].in_channels == 20 and twin.fcs[0].in_features == net.fcs[0].in_features
    x = torch.zeros(2, 10, 2, 107, 107)
    x[1, 7, 1, 3, 4] = 1
    frame = twin.frame(x)
    assert frame.shape == (2, 20, 107, 107) and frame[1, 2 * 7 + 1, 3, 4] == 1 and frame.sum() == 1
    out = twin(x)
    assert out.shape == (2, 1, 2) and torch.equal(twin.score(x), out[:, 0, 1])
    summed = SCTNTwin(TwinConfig(input="sum"))
    assert summed.convs[0].in_channels == 2 and summed.frame(x)[1, 1, 3, 4] == 1


def test_twin_macs_are_counted_on_the_layers_run():
    macs = twin_macs(SCTNTwin())
    conv1 = 26 * 26 * 8 * (20 * 4 * 4)  # outputs x (inputs x kernel) of conv1, by hand
    assert macs["by_layer"]["SCTNTwin.convs.0"] == conv1
    by_hand = conv1 + 12 * 12 * 16 * 8 * 9 + 10 * 10 * 16 * 16 * 9 + 1600 * 64 + 64 * 32 + 32 * 2
    assert macs["mac_ops"] == by_hand == sum(macs["by_layer"].values())
    assert twin_macs(SCTNTwin(TwinConfig(input="sum")))["mac_ops"] == by_hand - conv1 + conv1 // 10


@pytest.mark.parametrize("form", ["bins", "sum"])
def test_twin_scores_from_the_events_equal_the_dense_evaluation(form, tmp_path):
    from dvsot.dataset import Dataset
    from sctn.ann import canvas_pixels
    from sctn.encoding import encode_boxes
    from sctn.samples import propose

    test_file = moving_square_file(tmp_path / "t.h5", duration_ms=30, split="test")
    with Dataset(test_file) as ds:
        seg = ds.segment(1)
    rng = np.random.default_rng(0)
    boxes = np.concatenate([propose(rng, seg.box.astype(np.float64), 40, "gaussian", 0.6, 1.05, (160, 120)),
                            [[0.0, 0.0, 150.0, 110.0]]])  # a box larger than the canvas: scaled down
    x = encode_boxes(seg.events, seg.t0_us, boxes)
    b, step, pol, v, u = canvas_pixels(seg.events, seg.t0_us, boxes)
    assert len(b) == int(x.sum()) and torch.all(x[b, step, pol, v, u] == 1)
    torch.manual_seed(1)
    twin = SCTNTwin(TwinConfig(input=form, bias=True)).eval()  # biases too (the paper preset has none)
    for layer in list(twin.convs) + list(twin.fcs):
        torch.nn.init.uniform_(layer.bias, -0.1, 0.1)
    with torch.no_grad():
        dense = twin.score(x).numpy()
    np.testing.assert_allclose(twin.candidate_scores(seg.events, seg.t0_us, boxes), dense, rtol=1e-5, atol=1e-6)


@pytest.fixture(scope="module")
def twin_run(tmp_path_factory):
    """A tiny twin trained by SCTN's training code on a synthetic square, and a test sequence."""
    from sctn.training.snn import TrainConfig

    d = tmp_path_factory.mktemp("twin")
    train_file = moving_square_file(d / "train.h5", duration_ms=150, seed=0)
    test_file = moving_square_file(d / "test.h5", duration_ms=120, seed=1, velocity_px_s=(-120, 50),
                                   start=(110, 20), split="test")
    cfg = TrainConfig(epochs=3, segments_per_epoch=12, batch_segments=2, val_every=100, val_segments=2, seed=0,
                      lr=3e-3, network=TwinConfig(channels=(4, 8, 8), fc=(16, 16)))
    model, history = train_twin([train_file], cfg, progress=False)
    return model, history, test_file, d


def test_twin_trains_with_sctns_loss_and_tracks_with_sctns_tracker(twin_run):
    from benchmarks.trackers import get_tracker
    from dvsot.dataset import Dataset
    from dvsot.dataset.boxes import iou_xywh

    model, history, test_file, d = twin_run
    assert history["calibration"] is None and np.mean(history["train_loss"][-3:]) < np.mean(history["train_loss"][:3])
    final = history["val"][-1]
    assert final["vmax_pos"] > final["vmax_neg"]
    path = save_checkpoint(d / "twin.pt", model, {"note": "t"}, kind="sctn_ann")
    loaded, meta = load_twin(path)
    x = (torch.rand(3, 10, 2, 107, 107) < 0.02).float()
    assert meta["note"] == "t" and torch.equal(loaded(x), model(x))
    runs = []
    for _ in range(2):
        tracker = get_tracker("sctn_ann", checkpoint=str(path), finetune_iters=2, energy_every=1, n_candidates=64)
        with Dataset(test_file) as ds:
            segs = list(ds.segments())
            tracker.init(segs[0], segs[0].box, ds.width, ds.height)
            boxes = [tracker.update(s) for s in segs[1:5]]
        runs.append(np.array(boxes))
        iou = iou_xywh(runs[-1], np.array([s.box for s in segs[1:5]]))
    np.testing.assert_array_equal(runs[0], runs[1])  # fixed seed: the same track
    assert iou.mean() > 0.3
    energy = tracker.energy_per_segment()
    assert energy["mac_ops"] == twin_macs(model)["mac_ops"] * 64 and energy["ac_ops"] == 0
    assert energy["energy_pj"] == pytest.approx(energy["mac_ops"] * 4.6)


def test_a_checkpoint_of_another_model_is_refused_naming_what_it_holds(twin_run, tmp_path):
    model = twin_run[0]
    twin_path = save_checkpoint(tmp_path / "twin.pt", model, {}, kind="sctn_ann")
    sctn_path = save_checkpoint(tmp_path / "sctn.pt", SCTN(NetworkConfig(channels=(2, 2, 2), fc=(4, 4))), {})
    with pytest.raises(UserError, match=r"twin\.pt: holds a sctn_ann model, not an SCTN one"):
        load_checkpoint(twin_path)
    with pytest.raises(UserError, match=r"sctn\.pt: holds a sctn model, not an sctn_ann one"):
        load_twin(sctn_path)
    from benchmarks.trackers.siamfc.model import load_siamfc

    with pytest.raises(UserError, match=r"sctn\.pt: holds a sctn model, not a siamfc one"):
        load_siamfc(sctn_path)


def test_crop_places_a_pixel_where_the_geometry_says():
    frame = np.zeros((48, 64), np.float32)
    frame[20, 30] = 1.0  # pixel centre (30.5, 20.5)
    out = crop(frame, (30.5, 20.5), 9.0, 9)  # 1:1, centred on it
    assert out[4, 4] == pytest.approx(1.0) and out.sum() == pytest.approx(1.0)
    out = crop(frame, (28.5, 20.5), 9.0, 9)  # centre 2 px to the left: the pixel is 2 px right of the middle
    assert out[4, 6] == pytest.approx(1.0)
    assert crop(frame, (-100.0, -100.0), 9.0, 9).sum() == 0  # outside the sensor: zeros
    assert exemplar_extent(np.array([10.0, 30.0])) == pytest.approx(np.sqrt(30 * 50))


def test_labels_weights_and_logistic_loss():
    labels = response_labels(17, np.array([[8.0, 8.0], [10.0, 8.0]]), 2.0)
    assert labels.shape == (2, 1, 17, 17) and labels[0, 0, 8, 8] == 1 and labels[1, 0, 8, 12] == 1
    assert labels[0].sum() == 13 and labels[0, 0, 8, 11] == 0  # the cells within distance 2 of the centre
    w = balanced_weights(labels)
    assert (w[0] * labels[0]).sum() == pytest.approx((w[0] * (1 - labels[0])).sum())
    assert w[0].mean() == pytest.approx(1.0)
    v = torch.randn(2, 1, 17, 17)
    y = 2 * torch.from_numpy(labels) - 1
    by_hand = (torch.from_numpy(w) * torch.log1p(torch.exp(-y * v))).mean()
    assert float(logistic_loss(v, torch.from_numpy(labels), torch.from_numpy(w))) == pytest.approx(float(by_hand),
                                                                                                     rel=1e-5)


def test_siamfc_sizes_and_cross_correlation():
    torch.manual_seed(0)
    cfg = SiamFCConfig()
    assert cfg.feature_size(127) == 7 and cfg.feature_size(255) == 23 and cfg.response_size() == 17
    net = SiamFC(cfg).eval()
    z, x = torch.rand(2, 1, 127, 127), torch.rand(2, 1, 255, 255)
    resp = net(z, x)
    assert resp.shape == (2, 1, 17, 17)
    fz, fx = net.features(z), net.features(x)
    for b in range(2):  # the grouped correlation is each pair's own
        ref = F.conv2d(fx[b:b + 1], fz[b:b + 1]) * net.gain + net.offset
        torch.testing.assert_close(resp[b:b + 1], ref, rtol=1e-4, atol=1e-5)
    pyramid = net.correlate(fz[:1], fx)  # one exemplar over several search crops
    torch.testing.assert_close(pyramid[1:], F.conv2d(fx[1:], fz[:1]) * net.gain + net.offset, rtol=1e-4, atol=1e-5)


def test_siamfc_macs_by_hand():
    from benchmarks.trackers.siamfc.tracker import frame_macs

    m = frame_macs(SiamFC(), scale_num=3, response_up=16)
    assert m["by_layer"]["Sequential.0"] == 3 * 126 * 126 * 24 * (1 * 5 * 5)  # conv1 on the three search crops
    assert m["by_layer"]["functional"] == 3 * 17 * 17 * 32 * 7 * 7  # the cross-correlation
    assert m["postprocess_mac_ops"] == 3 * 272 * 272 * 16 + 272 * 272
    assert m["mac_ops"] == m["network_mac_ops"] + m["postprocess_mac_ops"]
    from benchmarks.analysis.energy_table import ann_rows

    rows = ann_rows(256, twin=SCTNTwin(), siamfc=SiamFC())
    siam, twin = rows["SiamFC (siamfc), 3 scales"], rows["SCTN's ANN twin (sctn_ann, input bins)"]
    assert siam["mac_ops"] == m["mac_ops"] and siam["energy_pj"] == pytest.approx(4.6 * m["mac_ops"])
    assert twin["mac_ops"] == 256 * twin_macs(SCTNTwin())["mac_ops"] and twin["ac_ops"] == 0


def test_siamfc_tracker_moves_to_the_response_peak(tmp_path, monkeypatch):
    from benchmarks.trackers.siamfc.tracker import SiamFCTracker
    from dvsot.dataset import Dataset

    path = save_checkpoint(tmp_path / "s.pt", SiamFC(), {}, kind="siamfc")
    tracker = SiamFCTracker(checkpoint=str(path), scale_lr=0.0)
    test_file = moving_square_file(tmp_path / "t.h5", duration_ms=40, split="test")
    with Dataset(test_file) as ds:
        s0, s1 = ds.segment(0), ds.segment(1)
        tracker.init(s0, s0.box, ds.width, ds.height)

        def peak_right(z_feat, x_feat):  # a response peaked one cell right of the centre, at every scale
            r = torch.zeros(x_feat.shape[0], 1, 17, 17)
            r[:, 0, 8, 9] = 1.0
            return r

        monkeypatch.setattr(tracker.model, "correlate", peak_right)
        centre, extent = tracker.centre.copy(), tracker.x_extent
        box = tracker.update(s1)
    moved = box[:2] + box[2:] / 2 - centre
    # one response cell is 8 search-crop px, i.e. 8 x extent / 255 sensor px; the window pulls towards the centre;
    # a cell's centre falls between two upsampled pixels (16 per cell): half of one (0.25 crop px) either way
    px = extent / 255
    assert moved[0] == pytest.approx(8 * px, abs=1.0 * px) and abs(moved[1]) <= 0.26 * px
    np.testing.assert_allclose(box[2:], s0.box[2:], rtol=1e-6)  # scale_lr 0: the size stays


def test_siamfc_tracker_on_a_network_in_memory_tracks_as_from_its_checkpoint(tmp_path):
    """SiamFCTracker.from_model (the validation score during training) tracks as the tracker loaded from the same
    weights, and leaves the network unchanged."""
    from benchmarks.trackers.siamfc.tracker import SiamFCTracker
    from dvsot.dataset import Dataset

    torch.manual_seed(3)
    net = SiamFC().eval()
    before = {k: v.clone() for k, v in net.state_dict().items()}
    path = save_checkpoint(tmp_path / "s.pt", net, {}, kind="siamfc")
    test_file = moving_square_file(tmp_path / "t.h5", duration_ms=40, split="test")
    boxes = []
    for tracker in (SiamFCTracker(checkpoint=str(path)), SiamFCTracker.from_model(net)):
        with Dataset(test_file) as ds:
            s0 = ds.segment(0)
            tracker.init(s0, s0.box, ds.width, ds.height)
            boxes.append([tracker.update(ds.segment(i)) for i in (1, 2, 3)])
    np.testing.assert_array_equal(np.array(boxes[0]), np.array(boxes[1]))
    assert all(torch.equal(v, before[k]) for k, v in net.state_dict().items())
    with pytest.raises(ValueError, match="no checkpoint"):
        SiamFCTracker.from_model(net, checkpoint=str(path))


def test_count_macs_counts_a_linear_layer():
    layer = torch.nn.Linear(7, 3)
    assert count_macs(layer, torch.zeros(5, 7))["mac_ops"] == 5 * 7 * 3


def test_bench_refuses_a_checkpoint_of_another_model(twin_run, tmp_path, capsys):
    from dvsot.cli import main

    model, _, test_file, _ = twin_run
    twin = save_checkpoint(tmp_path / "twin.pt", model, {}, kind="sctn_ann")
    sctn = save_checkpoint(tmp_path / "sctn.pt", SCTN(NetworkConfig(channels=(2, 2, 2), fc=(4, 4))), {})
    cases = [(["--tracker", "siamfc", "--checkpoint", str(sctn)], "sctn.pt: holds a sctn model, not a siamfc one"),
             (["--tracker", "sctn", "--checkpoint", str(twin)], "twin.pt: holds a sctn_ann model, not an SCTN one"),
             (["--tracker", "sctn_ann", "--option", f"sctn_ann.checkpoint={sctn}"], "sctn.pt: holds a sctn model"),
             (["--tracker", "sctn", "--tracker", "siamfc", "--checkpoint", str(sctn)], "sctn, siamfc all take a")]
    for argv, words in cases:
        out = tmp_path / "out"
        assert main(["bench", *argv, "--data", str(test_file), "--out", str(out), "--quiet"]) == 2, argv
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and words in err[0], (argv, err)
        assert not out.exists()


def test_train_refuses_flags_the_model_lacks(tmp_path, capsys):
    from dvsot.cli import main

    data = moving_square_file(tmp_path / "d.h5", width=64, height=48, size=12, duration_ms=30)
    for model, flag in (("siamfc", ["--fc", "4", "4"]), ("siamfc", ["--loss", "linear"]),
                        ("sctn_ann", ["--ops-penalty", "0.1"]), ("sctn", ["--input", "sum"])):
        assert main(["train", "--model", model, "--data", str(data), "-o", str(tmp_path / "m.pt"), *flag]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and f"{flag[0]}: not a setting of --model {model}" in err[0]
    assert not (tmp_path / "m.pt").exists()
