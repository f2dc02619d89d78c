"""The fast mode (SCTN.forward_search) against per-candidate evaluation: masks, nearest and bilinear crops, the
search region's extent, and the event-driven fc1 sums against the dense product."""

import numpy as np
import torch

from dvsot.events import EventBatch
from sctn.encoding import encode_region
from sctn.network import SCTN, NetworkConfig

torch.set_num_threads(1)


def test_fast_search_matches_per_candidate_evaluation_on_aligned_full_boxes():
    torch.manual_seed(1)
    net = SCTN()
    region = (torch.rand(1, 10, 2, 107 + 16, 107 + 16) < 0.05).float()
    net.calibrate(region[:, :, :, :107, :107])
    origins = torch.tensor([[0.0, 0.0], [8.0, 16.0]])
    boxes = torch.tensor([[0.0, 0.0, 107.0, 107.0], [8.0, 16.0, 107.0, 107.0]])
    fast = net.forward_search(region, origins, boxes)
    crops = torch.cat([region[:, :, :, 0:107, 0:107], region[:, :, :, 16:123, 8:115]])
    slow = net(crops)
    np.testing.assert_allclose(fast.detach(), slow.detach(), atol=1e-4)


def _search_reference(net: SCTN, feat: torch.Tensor, origins: torch.Tensor, boxes: torch.Tensor) -> tuple:
    """fc1 inputs and output voltages of candidates whose canvases start at the nearest cell, computed one by one."""
    n_cells = net.cfg.conv_sizes()[-1]
    stride, rf = net.receptive_field()
    inputs = []
    for (ox, oy), (bx, by, bw, bh) in zip(origins.tolist(), boxes.tolist()):
        cx, cy = round(ox / stride), round(oy / stride)
        crop = feat[:, :, cy:cy + n_cells, cx:cx + n_cells].clone()
        centre = torch.arange(n_cells) * stride + rf / 2
        keep_x = (ox + centre >= bx) & (ox + centre < bx + bw)
        keep_y = (oy + centre >= by) & (oy + centre < by + bh)
        crop *= (keep_y[:, None] & keep_x[None, :]).float()
        inputs.append(crop.flatten(1))
    h = torch.stack(inputs, dim=1)  # (T, N, C * cells * cells): the full fc1 input, masked per box
    with torch.no_grad():
        for fc, neuron in zip(net.fcs, net.neurons[3:]):
            h, v = neuron(fc(h))
    return torch.stack(inputs, dim=1), v.transpose(0, 1)


def _small_calibrated_net(seed: int) -> tuple[SCTN, torch.Tensor]:
    torch.manual_seed(seed)
    net = SCTN(NetworkConfig(channels=(4, 8, 4), fc=(16, 8)))
    region = (torch.rand(1, 10, 2, 107 + 16, 107 + 16) < 0.08).float()
    net.calibrate(region[:, :, :, :107, :107])
    with torch.no_grad():  # masked crops get less input than the calibration's full canvas
        for fc in net.fcs:
            fc.weight.mul_(4.0)
    return net, region


def test_fast_search_masks_cells_outside_each_box_and_leaves_out_cells_no_box_keeps():
    net, region = _small_calibrated_net(2)
    # aligned canvases (integer cells), boxes of different sizes: different masks, none the full canvas
    origins = torch.tensor([[0.0, 0.0], [8.0, 16.0], [16.0, 8.0]])
    boxes = torch.tensor(
        [[30.0, 35.0, 40.0, 30.0], [8 + 20.0, 16 + 25.0, 60.0, 50.0], [16 + 40.0, 8 + 40.0, 20.0, 20.0]]
    )
    for crop in ("nearest", "bilinear"):  # aligned: both crops are the same cells
        with torch.no_grad():
            v_fast, rec = net.forward_search(region, origins, boxes, record=True, crop=crop)
        inputs, v = _search_reference(net, rec["conv3"][:, 0], origins, boxes)
        assert float(v.abs().max()) > 0.05  # the output neurons do receive input
        np.testing.assert_allclose(v_fast, v, atol=1e-5)
        assert rec["crops"].shape[2] < net.cfg.channels[-1] * net.cfg.conv_sizes()[-1] ** 2  # masked for all: out
        assert torch.equal(rec["crops"].sum(dim=2), inputs.sum(dim=2))


def test_nearest_crops_snap_to_the_cell_and_evaluate_each_distinct_crop_once():
    net, region = _small_calibrated_net(3)
    gen = torch.Generator().manual_seed(0)
    origins = torch.rand(40, 2, generator=gen) * 16  # sub-cell offsets: several candidates share a cell
    sizes = 40 + 30 * torch.rand(40, 2, generator=gen)
    boxes = torch.cat([origins + 53.5 - sizes / 2, sizes], dim=1)
    with torch.no_grad():
        v_fast, rec = net.forward_search(region, origins, boxes, record=True, crop="nearest")
        v_bilinear = net.forward_search(region, origins, boxes, crop="bilinear")
    _, v = _search_reference(net, rec["conv3"][:, 0], origins, boxes)
    np.testing.assert_allclose(v_fast, v, atol=1e-5)
    assert rec["crops"].shape[1] < 40  # fewer distinct crops than candidates were evaluated
    assert not torch.allclose(v_bilinear, v_fast, atol=1e-3)  # bilinear crops are a different sampling


def test_bilinear_crops_equal_grid_sampling_of_the_spike_map():
    net, region = _small_calibrated_net(4)
    gen = torch.Generator().manual_seed(1)
    origins = torch.rand(30, 2, generator=gen) * 16
    sizes = 40 + 50 * torch.rand(30, 2, generator=gen)
    boxes = torch.cat([origins + 53.5 - sizes / 2, sizes], dim=1)
    with torch.no_grad():
        v_fast, rec = net.forward_search(region, origins, boxes, record=True, crop="bilinear")
        feat = rec["conv3"][:, 0]  # (T, C, fh, fw)
        n_cells = net.cfg.conv_sizes()[-1]
        stride, rf = net.receptive_field()
        fh, fw = feat.shape[2:]
        cell = torch.arange(n_cells, dtype=torch.float32)
        gx = (origins[:, 0:1] / stride + cell) / (fw - 1) * 2 - 1
        gy = (origins[:, 1:2] / stride + cell) / (fh - 1) * 2 - 1
        centre = stride * cell + rf / 2
        keep_x = (origins[:, 0:1] + centre >= boxes[:, 0:1]) & (
            origins[:, 0:1] + centre < boxes[:, 0:1] + boxes[:, 2:3]
        )
        keep_y = (origins[:, 1:2] + centre >= boxes[:, 1:2]) & (
            origins[:, 1:2] + centre < boxes[:, 1:2] + boxes[:, 3:4]
        )
        grid = torch.stack(
            [gx[:, None, :].expand(30, n_cells, n_cells), gy[:, :, None].expand(30, n_cells, n_cells)], -1
        )
        sampled = torch.stack([torch.nn.functional.grid_sample(f[None].expand(30, -1, -1, -1), grid, align_corners=True)
                               for f in feat])  # (T, N, C, cells, cells)
        h = (sampled * (keep_y[:, :, None] & keep_x[:, None, :])[None, :, None]).flatten(2)
        for fc, neuron in zip(net.fcs, net.neurons[3:]):
            h, v = neuron(fc(h))
    np.testing.assert_allclose(v_fast, v.transpose(0, 1), atol=1e-4)
    assert rec["mix_macs"] > 0


def test_search_region_covers_what_the_kept_cells_see():
    from sctn.encoding import encode_search
    from sctn.samples import TRACK, propose

    net, _ = _small_calibrated_net(5)
    rng = np.random.default_rng(0)
    n_ev = 4000
    ev = EventBatch(rng.integers(0, 320, n_ev).astype(np.uint16), rng.integers(0, 240, n_ev).astype(np.uint16),
                    np.sort(rng.integers(0, 10_000, n_ev)), rng.integers(0, 2, n_ev).astype(np.uint8))
    for ref in (np.array([140.0, 100.0, 30.0, 40.0]), np.array([100.0, 60.0, 150.0, 120.0])):  # scale 1 and < 1
        boxes = propose(rng, ref, 64, "gaussian", TRACK.trans, TRACK.scale, (320, 240))
        tail2 = net.cfg.model_copy(update={"tail_steps": 2})
        region, origins, rboxes = encode_search(ev, 0, boxes, ref, tail2)
        scale = min(1.0, 107 / ref[2:].max())
        corner = boxes[0, :2] - rboxes[0, :2].numpy() / scale
        canvases = (np.ptp(boxes[:, 0]) * scale + 107) * (np.ptp(boxes[:, 1]) * scale + 107)
        if ref[2] < 50:  # a small box: its region is well inside the union of the canvases
            assert region.shape[-1] * region.shape[-2] < 0.85 * canvases
        # the same search on a region 3 cells larger on every side (the whole canvases and more)
        pad = 3 * 8
        big = encode_region(
            ev, 0, corner - pad / scale, scale, (region.shape[-2] + 2 * pad, region.shape[-1] + 2 * pad), tail2
        )
        for crop in ("nearest", "bilinear"):
            with torch.no_grad():
                v = net.forward_search(region, origins, rboxes, crop=crop)
                v_big = net.forward_search(big, origins + pad, rboxes + torch.tensor([pad, pad, 0, 0]), crop=crop)
            np.testing.assert_allclose(v, v_big, atol=1e-5)


def test_event_driven_fc1_sums_equal_the_dense_product():
    net, region = _small_calibrated_net(6)
    gen = torch.Generator().manual_seed(2)
    origins = torch.rand(50, 2, generator=gen) * 16 - 4  # some canvases start left of / above the region
    sizes = 30 + 60 * torch.rand(50, 2, generator=gen)
    boxes = torch.cat([origins + 53.5 - sizes / 2, sizes], dim=1)
    for crop in ("nearest", "bilinear"):
        with torch.no_grad():
            v_sparse = net.forward_search(region, origins, boxes, crop=crop)  # inference: spike_sums
            v_dense, _ = net.forward_search(region, origins, boxes, crop=crop, record=True)  # gathered crops x W
        assert float(v_dense.abs().max()) > 0.05
        np.testing.assert_allclose(v_sparse, v_dense, atol=1e-5)
