"""Ocean and AutoMatch: shapes, the anchor-free geometry in closed form, each AutoMatch operator by hand, training
steps, the tracker's step, checkpoints refused in one line, and the commands on synthetic files."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest
import torch
from torch import nn

from benchmarks.trackers.automatch.crops import template_mask
from benchmarks.trackers.automatch.model import AutoMatch, AutoMatchConfig
from benchmarks.trackers.automatch.operators import OPERATORS, Matching
from benchmarks.trackers.ocean.boxes import assign, decode, iou_loss, locations
from benchmarks.trackers.ocean.crops import box_in_crop
from benchmarks.trackers.ocean.model import Ocean, OceanConfig, depthwise_xcorr
from dvsot.core.errors import UserError
from sctn.checkpoint import save_checkpoint

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
from synthetic import moving_square_file  # noqa: E402

torch.set_num_threads(1)


@pytest.fixture(scope="module")
def data(tmp_path_factory) -> Path:
    """A small labelled training file (64x48, 60 ms)."""
    return moving_square_file(tmp_path_factory.mktemp("af") / "syn.h5", width=64, height=48, size=12, duration_ms=60,
                              velocity_px_s=(100.0, 40.0), start=(10.0, 10.0))


def test_network_shapes_and_the_cached_template_is_the_whole_pass():
    torch.manual_seed(0)
    z, x = torch.rand(2, 1, 127, 127), torch.rand(2, 1, 255, 255)
    z_box = torch.tensor([[40.0, 50.0, 90.0, 80.0], [30.0, 30.0, 100.0, 100.0]])
    for net, r in ((Ocean().eval(), 17), (AutoMatch().eval(), 23)):
        assert net.response_size() == r
        with torch.no_grad():
            dist, cls, aware = net(z, x, z_box)
            again = net.track(net.template(z, z_box), x)
        assert dist.shape == (2, 4, r, r) and cls.shape == aware.shape == (2, 1, r, r)
        assert bool((dist > 0).all())  # distances are exp(.)
        for a, b in zip((dist, cls, aware), again):
            torch.testing.assert_close(a, b)
    with pytest.raises(ValueError, match="give no response"):
        Ocean(OceanConfig(exemplar_size=255, search_size=127))


def test_depthwise_xcorr_is_each_channels_own_correlation():
    x, z = torch.rand(2, 3, 9, 9), torch.rand(2, 3, 4, 4)
    out = depthwise_xcorr(x, z)
    assert out.shape == (2, 3, 6, 6)
    assert float(out[1, 2, 3, 1]) == pytest.approx(float((x[1, 2, 3:7, 1:5] * z[1, 2]).sum()), rel=1e-5)


def test_locations_decode_and_assign_in_closed_form():
    pos = locations(3, 64, 8)
    assert pos.tolist() == [24.0, 32.0, 40.0]  # the middle cell at the crop's centre, 8 px apart
    dist = torch.zeros(1, 4, 3, 3)
    dist[0, :, 1, 2] = torch.tensor([5.0, 6.0, 7.0, 8.0])  # l t r b at (x 40, y 32)
    box = decode(dist, pos)[0, :, 1, 2]
    assert box.tolist() == [35.0, 26.0, 47.0, 40.0]  # (40 - 5, 32 - 6, 40 + 7, 32 + 8)
    boxes = torch.tensor([[20.0, 28.0, 37.0, 45.0]])  # 17 x 17 around (28.5, 36.5)
    target, inside, labels = assign(boxes, pos, 8)
    assert target[0, :, 1, 1].tolist() == [12.0, 4.0, 5.0, 13.0]  # at (32, 32): 32-20, 32-28, 37-32, 45-32
    assert inside[0, 0].tolist() == [[0, 0, 0], [1, 1, 0], [1, 1, 0]]  # x 24, 32 inside [20, 37]; y 32, 40 in [28, 45]
    # ellipse of semi-axes max(17 / 4, 8) = 8 around (28.5, 36.5): (32, 32): (3.5/8)^2 + (4.5/8)^2 < 1; (24, 40) too;
    # (24, 32): (4.5/8)^2 + (4.5/8)^2 = 0.63; (40, 40): (11.5/8)^2 > 1
    assert labels[0, 0].tolist() == [[0, 0, 0], [1, 1, 0], [1, 1, 0]]
    assert decode(target, pos)[0, :, 2, 0].tolist() == boxes[0].tolist()  # targets decode to the box everywhere


def test_iou_loss_by_hand():
    pred = torch.tensor([2.0, 2.0, 2.0, 2.0]).view(1, 4, 1, 1)  # a 4 x 4 box around the location
    target = torch.tensor([1.0, 1.0, 3.0, 3.0]).view(1, 4, 1, 1)  # 4 x 4, shifted by 1 px both ways
    inter = 3.0 * 3.0
    union = 16 + 16 - inter
    assert float(iou_loss(pred, target, torch.ones(1, 1, 1, 1))) == pytest.approx(-math.log((inter + 1) / (union + 1)))
    assert float(iou_loss(pred, target, torch.zeros(1, 1, 1, 1))) == 0.0
    assert float(iou_loss(pred, pred, torch.ones(1, 1, 1, 1))) == pytest.approx(0.0, abs=1e-7)


def test_box_in_crop_and_template_mask():
    b = box_in_crop(np.array([10.0, 20.0, 8.0, 4.0]), np.array([14.0, 22.0]), 32.0, 64)
    assert b.tolist() == [24.0, 28.0, 40.0, 36.0]  # 2x scale, centred
    m = template_mask(torch.tensor([[40.0, 50.0, 80.0, 70.0], [63.0, 63.0, 64.0, 64.0]]), 7, 127)
    # locations 63.5 + 8 (j - 3): 39.5, 47.5, ..., 87.5: x in [40, 80] at j 1..5, y in [50, 70] at j 2, 3
    assert m.shape == (2, 1, 7, 7) and m[0, 0, 2, 1:6].tolist() == [1] * 5 and m[0, 0, 2, 0] == m[0, 0, 2, 6] == 0
    assert m[0, 0, 3, 1:6].tolist() == [1] * 5 and m[0].sum() == 5 * 2
    assert m[1].sum() == 1 and m[1, 0, 3, 3] == 1  # a box between locations: its nearest one


def _set(conv: nn.Conv2d, weight: torch.Tensor, bias: torch.Tensor | None = None) -> None:
    with torch.no_grad():
        conv.weight.copy_(weight.view_as(conv.weight))
        conv.bias.copy_(torch.zeros_like(conv.bias) if bias is None else bias)


@pytest.mark.parametrize("name", list(OPERATORS))
def test_every_operator_keeps_the_search_grid(name):
    op = OPERATORS[name](4, 9)
    out = op(torch.rand(2, 4, 3, 3), torch.rand(2, 4, 5, 6), torch.rand(2, 1, 3, 3))
    assert out.shape == (2, 4, 5, 6)


def test_operators_by_hand():
    # one channel, a 1 x 2 template [1, 3] (mean 2), a 1 x 2 search map [2, 5], mask [1, 0]
    z, x, m = torch.tensor([[[[1.0, 3.0]]]]), torch.tensor([[[[2.0, 5.0]]]]), torch.tensor([[[[1.0, 0.0]]]])
    one = torch.ones(1)
    cat = OPERATORS["concatenation"](1, 2)
    _set(cat.w, torch.tensor([1.0, 10.0]), one)
    assert cat(z, x, m).flatten().tolist() == [2 + 20 + 1, 5 + 20 + 1]
    add = OPERATORS["pointwise_addition"](1, 2)
    _set(add.w, 3 * one)
    assert add(z, x, m).flatten().tolist() == [3 * 4, 3 * 7]
    rel = OPERATORS["pairwise_relation"](1, 2)
    _set(rel.w, torch.tensor([1.0, 100.0]))  # x_i z_1 + 100 x_i z_2
    assert rel(z, x, m).flatten().tolist() == [2 + 600, 5 + 1500]
    film = OPERATORS["film"](1, 2)
    _set(film.gamma, 2 * one, one)  # gamma = 2 x 2 + 1 = 5
    _set(film.beta, -one)  # beta = -2
    assert film(z, x, m).flatten().tolist() == [5 * 2 - 2, 5 * 5 - 2]
    st = OPERATORS["simple_transformer"](1, 2)
    for conv in (st.q, st.k, st.v, st.o):
        _set(conv, one)
    a = torch.softmax(torch.tensor([[2.0, 6.0], [5.0, 15.0]]), dim=1)  # q_i k_j / sqrt(1)
    expect = x.flatten() + a @ torch.tensor([1.0, 3.0])
    torch.testing.assert_close(st(z, x, m).flatten(), expect)
    tg = OPERATORS["transductive_guidance"](1, 2)
    _set(tg.w, one)
    g = a[:, 0]  # attention on the masked (first) template location
    torch.testing.assert_close(tg(z, x, m).flatten(), x.flatten() * (1 + g))
    both = Matching(("concatenation", "film"), 1, 2).eval()
    both.ops[0], both.ops[1] = cat, film
    total = torch.tensor([23.0 + 8.0, 26.0 + 23.0])  # concatenation's plus FiLM's, normalised over the group
    expected = torch.relu((total - total.mean()) / torch.sqrt(total.var(unbiased=False) + both.norm[0].eps))
    torch.testing.assert_close(both(z, x, m).flatten(), expected)


def test_automatch_config_refuses_unknown_operators():
    with pytest.raises(ValueError, match="give distinct ones of concatenation"):
        AutoMatchConfig(cls_ops=("correlation",))
    assert AutoMatch(AutoMatchConfig(reg_ops=("concatenation",), cls_ops=("pointwise_addition",))).response_size() == 23


@pytest.mark.parametrize("model", ["ocean", "automatch"])
def test_three_training_steps(data, model):
    from benchmarks.training.registry import configure, resolve, trainer

    entry = trainer(model)
    cfg = configure(model, {"epochs": 1, "segments_per_epoch": 3, "batch_segments": 1})
    net, history = resolve(entry.train)([data], cfg, progress=False)
    assert history["steps"] == 3 and len(history["train_loss"]) == 3
    assert all(np.isfinite(history["train_loss"])) and {"reg_loss", "cls_loss", "aware_loss"} <= set(history)
    assert np.isfinite(history["val"][-1]["centre_error_px"])


@pytest.mark.parametrize("name, build", [("ocean", Ocean), ("automatch", AutoMatch)])
def test_tracker_moves_to_the_best_location(tmp_path, monkeypatch, name, build):
    from benchmarks.trackers import get_tracker
    from dvsot.dataset import Dataset

    path = save_checkpoint(tmp_path / f"{name}.pt", build(), {}, kind=name)
    tracker = get_tracker(name, checkpoint=str(path), window_influence=0.0, lr=0.0)
    f = moving_square_file(tmp_path / "t.h5", duration_ms=30, split="test")
    with Dataset(f) as ds:
        s0, s1 = ds.segment(0), ds.segment(1)
        tracker.init(s0, s0.box, ds.width, ds.height)
        r = tracker.model.response_size()

        def peaked(cached, x):  # the best score one cell right of and one below the centre, a 20 x 10 px box
            cls = torch.full((1, 1, r, r), -10.0)
            cls[0, 0, r // 2 + 1, r // 2 + 1] = 10.0
            dist = torch.tensor([10.0, 5.0, 10.0, 5.0]).view(1, 4, 1, 1).expand(1, 4, r, r).clone()
            return dist, cls, cls.clone()

        monkeypatch.setattr(tracker.model, "track", peaked)
        centre, size = tracker.centre.copy(), tracker.size.copy()
        from benchmarks.trackers.siamfc.crops import exemplar_extent

        scale = 255 / (exemplar_extent(size) * 255 / 127)
        box = tracker.update(s1)
    np.testing.assert_allclose(box[:2] + box[2:] / 2, centre + 8 / scale, rtol=1e-5)  # one cell = 8 crop px
    np.testing.assert_allclose(box[2:], size, rtol=1e-6)  # lr 0: the size stays


@pytest.mark.filterwarnings("ignore:.*no weights_sha256 digest")  # the hand-made files state no digest
@pytest.mark.parametrize("name, build, other", [("ocean", Ocean, "automatch"), ("automatch", AutoMatch, "ocean")])
def test_bad_checkpoints_are_refused_in_one_line(tmp_path, name, build, other):
    from benchmarks.trackers import get_tracker

    good = save_checkpoint(tmp_path / "good.pt", build(), {}, kind=name)
    with pytest.raises(UserError, match=rf"good\.pt: holds an? {name} model, not an {other} one"):
        get_tracker(other, checkpoint=str(good))
    blob = torch.load(good, weights_only=True)
    del blob["state_dict"]["head.reg_pred.weight"]
    del blob["meta"]["weights_sha256"]
    torch.save(blob, tmp_path / "missing.pt")
    blob = torch.load(good, weights_only=True)
    blob["state_dict"]["head.cls_pred.bias"][0] = float("nan")
    del blob["meta"]["weights_sha256"]
    torch.save(blob, tmp_path / "nan.pt")
    blob = torch.load(good, weights_only=True)
    blob["config"]["search_size"] = 63  # smaller than the template: no response map
    torch.save(blob, tmp_path / "size.pt")
    for bad, says in (("missing.pt", "head.reg_pred.weight"), ("nan.pt", "non-finite"), ("size.pt", "give no")):
        with pytest.raises(UserError) as err:
            get_tracker(name, checkpoint=str(tmp_path / bad))
        text = str(err.value)
        assert "\n" not in text and bad in text and says in text, text


def test_a_frame_the_network_cannot_take_is_refused(tmp_path):
    from benchmarks.trackers import get_tracker
    from dvsot.dataset import Dataset

    tracker = get_tracker("ocean", checkpoint=str(save_checkpoint(tmp_path / "o.pt", Ocean(), {}, kind="ocean")))
    f = moving_square_file(tmp_path / "t.h5", duration_ms=20, split="test")
    with Dataset(f) as ds, pytest.raises(UserError, match="a 0x48 px frame is no frame"):
        tracker.init(ds.segment(0), ds.segment(0).box, 0, 48)


def test_train_and_bench_commands(data, tmp_path, capsys, monkeypatch):
    import json

    from benchmarks.trackers import trained_here
    from dvsot.cli import main

    (tmp_path / "shipped").mkdir()  # no checkpoint there, whatever ships with the package
    monkeypatch.setattr(trained_here, "CHECKPOINT_DIR", tmp_path / "shipped")

    out = tmp_path / "ocean.pt"
    assert main(["train", "--model", "ocean", "--data", str(data), "-o", str(out), "--epochs", "1",
                 "--segments-per-epoch", "2", "--batch-segments", "1", "--threads", "1", "--quiet"]) == 0
    meta = json.loads(out.with_suffix(".json").read_text())
    assert meta["model"] == "ocean" and meta["config"]["channels"] == [24, 32, 64, 64, 64]
    test = moving_square_file(tmp_path / "test.h5", width=64, height=48, size=12, duration_ms=60, split="test")
    capsys.readouterr()
    assert main(["bench", "--tracker", "ocean", "--checkpoint", str(out), "--data", str(test), "--out",
                 str(tmp_path / "b"), "--no-energy", "--quiet"]) == 0
    result = json.loads((tmp_path / "b" / "results.json").read_text())
    assert "ocean" in json.dumps(result)
    capsys.readouterr()
    assert main(["bench", "--tracker", "automatch", "--data", str(test), "--out", str(tmp_path / "c"),
                 "--no-energy", "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "automatch: no shipped checkpoint exists" in err and \
        "train one with `dvsot train --model automatch" in err and not (tmp_path / "c").exists()


def test_automatch_paper_size_count():
    from benchmarks.trackers.reference_nets import AutoMatch as PaperAutoMatch
    from benchmarks.trackers.reference_nets import count_siamese

    with torch.device("meta"):
        net = PaperAutoMatch()
    with torch.no_grad():
        out = net(torch.zeros(1, 3, 128, 128, device="meta"), torch.zeros(1, 3, 256, 256, device="meta"))
    assert [tuple(t.shape) for t in out] == [(1, 4, 31, 31), (1, 1, 31, 31), (1, 1, 31, 31)]
    frame = count_siamese(net)["per_frame"]["by_layer"]
    cells, search = 7 * 7, 31 * 31
    assert frame["AutoMatch.reg_match.ops.0"] == search * cells * 256  # pairwise relation's dot products
    assert frame["AutoMatch.reg_match.ops.0.w"] == search * cells * 256  # its 1x1 map, 49 -> 256 channels
    assert frame["AutoMatch.cls_match.ops.1"] == search * cells * 256 + search * cells  # attention, mask carried
    assert frame["AutoMatch.reg_pred"] == search * 9 * 256 * 4
