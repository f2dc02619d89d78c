"""GOTURN, SiamRPN and SiamMask as built here: output shapes, SiamRPN's anchors and decoding in closed form,
GOTURN's box parametrisation, SiamMask's box from its mask, a three-step training of each, and their refusals of
checkpoints and frames they cannot use (one line naming the file or the size)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from dvsot.core.errors import UserError

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
sys.path.insert(0, str(Path(__file__).resolve().parent))
from synthetic import moving_square_file  # noqa: E402
from trained_here_data import disc_file  # noqa: E402

torch.set_num_threads(1)
SMOKE = {"epochs": 1, "segments_per_epoch": 3, "batch_segments": 1, "val_segments": 2}


@pytest.fixture(scope="module")
def square(tmp_path_factory) -> Path:
    return moving_square_file(tmp_path_factory.mktemp("sq") / "sq.h5", width=64, height=48, size=12,
                              duration_ms=80, velocity_px_s=(100.0, 40.0), start=(10.0, 10.0))


@pytest.fixture(scope="module")
def disc(tmp_path_factory) -> Path:
    return disc_file(tmp_path_factory.mktemp("disc") / "disc.h5")


# ---- shapes ----------------------------------------------------------------------------------------------------

def test_each_network_gives_its_papers_outputs_at_its_crop_sizes():
    from benchmarks.trackers.goturn.model import GOTURN
    from benchmarks.trackers.siammask.model import SiamMask
    from benchmarks.trackers.siamrpn.model import SiamRPN

    z, x = torch.zeros(2, 1, 127, 127), torch.zeros(2, 1, 255, 255)
    scores, offsets = SiamRPN().eval()(z, x)
    assert scores.shape == (2, 2, 5, 17, 17) and offsets.shape == (2, 4, 5, 17, 17)
    scores, offsets, masks = SiamMask().eval()(z, x)
    assert scores.shape == (2, 2, 5, 17, 17) and offsets.shape == (2, 4, 5, 17, 17) and masks.shape == (2, 31, 31,
                                                                                                         17, 17)
    g = GOTURN().eval()
    crops = torch.zeros(2, 1, 227, 227)
    out = g(crops, crops)
    assert out.shape == (2, 4)
    np.testing.assert_allclose(out[0].detach().numpy(), [2.5, 2.5, 7.5, 7.5], atol=0.1)  # starts near "no motion"


def test_each_narrowing_is_measured_against_the_paper_size_network():
    from benchmarks.trackers.goturn.model import narrowing as goturn
    from benchmarks.trackers.siammask.model import narrowing as siammask
    from benchmarks.trackers.siamrpn.model import narrowing as siamrpn

    rpn = siamrpn()
    for measure in (goturn(), rpn, siammask()):
        assert measure["narrowing"] and 0 < measure["params_ratio"] < 0.2 and 0 < measure["frame_macs_ratio"] < 0.2
    assert rpn["frame_macs_reference"] == pytest.approx(4.82e9, rel=0.01)  # the paper's Table 3 at 255 px


# ---- SiamRPN: anchors and decoding -----------------------------------------------------------------------------

def test_anchors_in_closed_form():
    from benchmarks.trackers.siamrpn.anchors import anchor_shapes, make_anchors

    # area (8 x 8)^2 = 4096; w = int(sqrt(4096 / r)), h = int(w r)
    np.testing.assert_array_equal(anchor_shapes(8), [[111, 36], [90, 45], [64, 64], [45, 90], [36, 108]])
    a = make_anchors(17, 8)
    assert a.shape == (4, 5, 17, 17)
    np.testing.assert_array_equal(a[:, 2, 8, 8], [0, 0, 64, 64])  # the centre cell at the crop's centre
    np.testing.assert_array_equal(a[:2, 0, 0, 16], [64, -64])  # column 16, row 0: 8 cells right, 8 up
    np.testing.assert_array_equal(a[:, 4, 3, 5], [-24, -40, 36, 108])


def test_offsets_encode_and_decode_in_closed_form():
    from benchmarks.trackers.siamrpn.anchors import decode, encode

    anchor = np.array([8.0, 0.0, 64.0, 64.0])
    box = np.array([10.0, -5.0, 128.0, 32.0])
    d = encode(box, anchor)
    np.testing.assert_allclose(d, [2 / 64, -5 / 64, np.log(2), np.log(0.5)])
    np.testing.assert_allclose(decode(d, anchor), box)


def test_targets_make_the_matching_anchor_positive_with_zero_offsets():
    from benchmarks.trackers.siamrpn.anchors import make_anchors, targets

    a = make_anchors(17, 8)
    labels, offsets = targets(a, a[:, 2, 8, 10], np.random.default_rng(0))
    assert labels[2, 8, 10] == 1
    np.testing.assert_allclose(offsets[:, 2, 8, 10], 0, atol=1e-6)
    assert 1 <= (labels == 1).sum() <= 16 and (labels >= 0).sum() <= 64


def _segment():
    """A segment without events."""
    from dvsot.dataset import Segment
    from dvsot.events import EventBatch

    return Segment(0, 0, 10_000, EventBatch.empty(), np.array([20.0, 14.0, 12.0, 12.0], np.float32))


def test_siamrpn_moves_to_the_best_anchors_refined_box():
    """With no window, no penalty and lr 1, the new box is the best anchor's decoded box scaled to the sensor."""
    from benchmarks.trackers.siamrpn.anchors import encode, make_anchors
    from benchmarks.trackers.siamrpn.model import SiamRPN
    from benchmarks.trackers.siamrpn.tracker import SiamRPNTracker

    t = SiamRPNTracker.from_model(SiamRPN().eval(), window_influence=0.0, penalty_k=0.0, lr=1.0)
    t.wh, t.centre, t.size = (640, 480), np.array([300.0, 200.0]), np.array([40.0, 40.0])
    scale = 2.0  # crop px per sensor px
    a = make_anchors(17, 8)
    scores = torch.zeros(1, 2, 5, 17, 17)
    scores[0, 1, 3, 6, 11] = 10.0  # anchor 3 (ratio 2) at row 6, column 11
    want = np.array([30.0, -12.0, 50.0, 90.0])  # crop px from the centre
    offsets = torch.from_numpy(np.broadcast_to(encode(want.reshape(4, 1, 1, 1), a), (4, 5, 17, 17)).copy())[None]
    best = t.step(scores, offsets.float(), scale)
    assert best == np.ravel_multi_index((3, 6, 11), (5, 17, 17))
    np.testing.assert_allclose(t.centre, [300 + 15, 200 - 6], atol=1e-3)
    np.testing.assert_allclose(t.size, [25, 45], atol=1e-3)


# ---- GOTURN: box parametrisation -------------------------------------------------------------------------------

def test_goturn_box_parametrisation_round_trips():
    from benchmarks.trackers.goturn.crops import decode, encode, region

    rng = np.random.default_rng(3)
    for _ in range(20):
        prev = np.concatenate([rng.uniform(0, 200, 2), rng.uniform(5, 80, 2)])
        box = np.concatenate([rng.uniform(0, 200, 2), rng.uniform(5, 80, 2)])
        np.testing.assert_allclose(decode(encode(box, region(prev)), region(prev)), box, atol=1e-9)
    prev = np.array([10.0, 20.0, 30.0, 16.0])
    np.testing.assert_allclose(encode(prev, region(prev)), [2.5, 2.5, 7.5, 7.5])  # the middle half of the crop
    np.testing.assert_allclose(region(prev), [-5, 12, 60, 32])


def test_goturn_crop_places_a_pixel_where_the_region_says():
    from benchmarks.trackers.goturn.crops import crop_region

    frame = np.zeros((48, 64), np.float32)
    frame[20:24, 30:34] = 1.0  # a 4x4 block
    out = crop_region(frame, np.array([30.0, 20.0, 8.0, 8.0]), 16)  # 2 crop px per sensor px
    # crop px u samples sensor x = 30 + (u + 0.5) / 2 bilinearly (pixel centres at i + 0.5)
    assert out[1:7, 1:7].min() == 1 and out[9:, :].max() == 0 and out[:, 9:].max() == 0
    assert out[0, 4] == out[7, 4] == 0.75 and out[8, 4] == 0.25


def test_goturn_motion_augmentation_follows_its_laplace_scales():
    from benchmarks.trackers.goturn.crops import shifted_box

    rng = np.random.default_rng(0)
    box = np.array([0.0, 0.0, 10.0, 20.0])
    boxes = np.array([shifted_box(box, rng) for _ in range(4000)])
    dx = (boxes[:, 0] + boxes[:, 2] / 2 - 5) / 10
    assert np.median(np.abs(dx)) == pytest.approx(np.log(2) / 5, rel=0.1)  # Laplace(0, 1/5): median |d| = ln 2 b
    assert boxes[:, 2].min() >= 6 - 1e-9 and boxes[:, 2].max() <= 14 + 1e-9  # scale within 1 +- 0.4


# ---- SiamMask: box from mask -----------------------------------------------------------------------------------

def test_box_from_mask_axis_and_minimum_area_rectangle():
    import cv2

    from benchmarks.trackers.siammask.masks import mask_box

    p = np.zeros((40, 40), np.float32)
    p[3:8, 2:10] = 0.9
    np.testing.assert_array_equal(mask_box(p, 0.35), [2, 3, 8, 5])
    np.testing.assert_allclose(mask_box(p, 0.35, "minarea"), [2, 3, 8, 5], atol=1e-4)
    assert np.isnan(mask_box(p, 0.95)).all()
    # a thin bar at 45 degrees: both rectangles are made upright around it, neither is smaller than its extent
    bar = np.zeros((40, 40), np.uint8)
    cv2.line(bar, (5, 5), (30, 30), 1, 3)
    axis, mbr = mask_box(bar, 0.5), mask_box(bar, 0.5, "minarea")
    assert axis[2] == pytest.approx(mbr[2], abs=1.5) and axis[0] == pytest.approx(mbr[0], abs=1.5)


def test_mask_targets_cut_each_cells_response_window():
    from benchmarks.trackers.siammask.masks import mask_targets

    crop = np.zeros((255, 255), np.float32)
    crop[96:160, 96:160] = 1.0  # a 64 px square at the crop's centre
    t = mask_targets(crop, np.array([[8, 8], [8, 16]]), 17, 8, 127, 31)
    assert t.shape == (2, 31, 31)
    assert t[0, 15, 15] == 1 and t[0, 0, 0] == 0 and t[0].sum() == pytest.approx(64 ** 2 * (31 / 127) ** 2, rel=0.1)
    assert t[1, 15, 15] == 0  # 64 px right: the window's centre is off the square


def test_siammask_reports_the_rectangle_of_its_mask():
    """The mask logits of the best cell are +10 on a rectangle of the window: the box is that rectangle in sensor
    pixels."""
    from benchmarks.trackers.siammask.model import SiamMask
    from benchmarks.trackers.siammask.tracker import SiamMaskTracker

    model = SiamMask().eval()
    t = SiamMaskTracker.from_model(model, window_influence=0.0, penalty_k=0.0, lr=0.0)
    t.wh, t.centre, t.size, t.cached = (640, 480), np.array([300.0, 200.0]), np.array([40.0, 40.0]), ()
    scores, offsets = torch.zeros(1, 2, 5, 17, 17), torch.zeros(1, 4, 5, 17, 17)
    scores[0, 1, 2, 8, 8] = 10.0
    masks = torch.full((1, 31, 31, 17, 17), -10.0)
    masks[0, 10:20, 5:25, 8, 8] = 10.0
    model.track = lambda cached, x: (scores, offsets, masks)
    t.search = lambda segment: (torch.zeros(1, 1, 255, 255), 2.0)  # 2 crop px per sensor px
    box = t.update(None)
    cell = 127 / 31  # window px per mask cell; the window is centred on the crop's centre = the tracker's centre
    want = np.array([300 + (5 * cell - 63.5) / 2, 200 + (10 * cell - 63.5) / 2, 20 * cell / 2, 10 * cell / 2])
    np.testing.assert_allclose(box, want, atol=2.5)


# ---- training --------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("model", ["goturn", "siamrpn", "siammask"])
def test_three_training_steps_run_and_validate(square, disc, model):
    from benchmarks.training.registry import configure, model_settings, resolve, trainer

    cfg = configure(model, model_settings(model, SMOKE))
    files = [disc] if model == "siammask" else [square]
    _, history = resolve(trainer(model).train)(files, cfg, progress=False)
    assert history["steps"] == 3 and len(history["train_loss"]) == 3 and np.isfinite(history["train_loss"]).all()
    assert history["val"] and np.isfinite(history["val"][-1]["loss"])
    if model == "siammask":
        assert history["mask_sources"] == {str(disc): "file"}  # trained on the file's instance masks


def test_siammask_masks_come_from_the_file_or_else_the_box(square, disc):
    from benchmarks.trackers.siammask.train import load_masked

    m = load_masked(disc, 4.0)
    assert m.source == "file"
    k = 2
    mask, box = m.mask(k), m.frames.boxes[k]
    assert 150 < mask.sum() < 0.9 * box[2] * box[3]  # a disc: fewer pixels than its box
    b = load_masked(square, 4.0)
    assert b.source == "box" and b.mask(0).sum() == pytest.approx(np.prod(np.ceil(b.frames.boxes[0][2:] + 1)),
                                                                  abs=2 * 13)


# ---- refusals --------------------------------------------------------------------------------------------------

def _save(net, path: Path, kind: str) -> Path:
    from sctn.checkpoint import save_checkpoint

    return save_checkpoint(path, net, {"note": "untrained, for a test"}, kind=kind)


def _resave(path: Path, edit) -> Path:
    from sctn.checkpoint import DIGEST_KEY, weights_digest

    blob = torch.load(path, weights_only=True)
    edit(blob["state_dict"])
    blob["meta"][DIGEST_KEY] = weights_digest(blob["state_dict"])
    torch.save(blob, path)
    path.with_suffix(".json").unlink()
    return path


def test_checkpoints_of_another_model_or_with_bad_weights_are_refused_in_one_line(tmp_path):
    from benchmarks.trackers import get_tracker
    from benchmarks.trackers.siamrpn.model import SiamRPN, SiamRPNConfig

    rpn = _save(SiamRPN(), tmp_path / "rpn.pt", "siamrpn")
    assert get_tracker("siamrpn", checkpoint=str(rpn)).model.cfg == SiamRPNConfig()
    for other in ("goturn", "siammask"):
        with pytest.raises(UserError) as err:
            get_tracker(other, checkpoint=str(rpn))
        assert str(err.value) == (f"{rpn}: holds a siamrpn model, not a {other} one "
                                  "(a checkpoint of the siamrpn tracker)")
    nan = _resave(_save(SiamRPN(), tmp_path / "nan.pt", "siamrpn"),
                  lambda s: s["cls_x.weight"].view(-1).__setitem__(0, float("nan")))
    missing = _resave(_save(SiamRPN(), tmp_path / "missing.pt", "siamrpn"), lambda s: s.pop("adjust.bias"))
    for path, words in ((nan, "NaN"), (missing, "adjust.bias")):
        with pytest.raises(UserError) as err:
            get_tracker("siamrpn", checkpoint=str(path))
        text = str(err.value)
        assert "\n" not in text and text.startswith(f"{path}: ") and words in text, text


def test_a_network_whose_crops_give_no_output_and_a_frame_too_small_are_refused(tmp_path):
    from benchmarks.trackers import get_tracker
    from benchmarks.trackers.goturn.model import GOTURN

    small = GOTURN()
    small.cfg = small.cfg.model_copy(update={"size": 40})  # its weights, a crop size that gives no pool5 map
    path = _save(small, tmp_path / "g.pt", "goturn")
    with pytest.raises(UserError) as err:
        get_tracker("goturn", checkpoint=str(path))
    assert str(err.value).startswith(f"{path}: not a usable goturn checkpoint") and "40 px" in str(err.value)
    tracker = get_tracker("goturn", checkpoint=str(_save(GOTURN(), tmp_path / "ok.pt", "goturn")))
    with pytest.raises(UserError, match="goturn: a 6x48 px frame is smaller than"):
        tracker.init(_segment(), np.array([1.0, 1.0, 3.0, 3.0]), 6, 48)


@pytest.mark.parametrize("name", ["goturn", "siamrpn", "siammask", "ocean", "automatch"])
def test_without_a_checkpoint_each_says_none_ships_and_how_to_train_one(name, tmp_path, monkeypatch):
    from benchmarks.trackers import get_tracker, trained_here

    monkeypatch.setattr(trained_here, "CHECKPOINT_DIR", tmp_path)  # empty, whatever ships with the package
    with pytest.raises(UserError) as err:
        get_tracker(name)
    text = str(err.value)
    assert "\n" not in text and text.startswith(f"{name}: no shipped checkpoint exists") and \
        f"dvsot train --model {name}" in text


@pytest.mark.parametrize("name", ["goturn", "siamrpn", "siammask", "ocean", "automatch"])
def test_a_checkpoint_at_the_shipped_path_is_used_without_checkpoint(name, tmp_path, monkeypatch):
    from benchmarks.perf.bench_trained_here import TRACKERS
    from benchmarks.trackers import get_tracker, trained_here
    from benchmarks.training.registry import resolve
    from sctn.checkpoint import save_checkpoint

    monkeypatch.setattr(trained_here, "CHECKPOINT_DIR", tmp_path)
    torch.manual_seed(0)
    net = resolve(TRACKERS[name])()
    save_checkpoint(trained_here.default_path(name), net, {}, kind=name)
    assert trained_here.default_path(name) == tmp_path / f"{name}_dvsot21.pt"
    loaded = get_tracker(name).model
    assert all(torch.equal(a, b) for a, b in zip(net.state_dict().values(), loaded.state_dict().values()))
