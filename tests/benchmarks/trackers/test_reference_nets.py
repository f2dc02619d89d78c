"""The published trackers' networks: output shapes at their papers' sizes and MAC counts against closed forms."""

import pytest
import torch

from benchmarks.trackers.reference_nets import GOTURN, Ocean, SiamMask, SiamRPN, count_siamese


def meta(cls, *args):
    """The network built on the meta device: shapes without weights."""
    with torch.device("meta"):
        return cls(*args)


def meta_run(net, zs: int, xs: int):
    with torch.no_grad():
        return net(torch.zeros(1, 3, zs, zs, device="meta"), torch.zeros(1, 3, xs, xs, device="meta"))


@pytest.mark.parametrize("search, side", [(255, 17), (271, 19)])
def test_siamrpn_maps(search, side):
    cls, reg = meta_run(meta(SiamRPN, search), 127, search)
    assert cls.shape == (1, 10, side, side) and reg.shape == (1, 20, side, side)


def siamrpn_search_by_hand(s: int) -> int:
    """SiamRPN's per-frame MACs: unpadded AlexNet on an s x s crop, the two 3x3 search convs, the correlation."""
    c1 = (s - 11) // 2 + 1
    c2 = (c1 - 3) // 2 + 1 - 4
    c3 = (c2 - 3) // 2 + 1 - 2
    c4, c5, r = c3 - 2, c3 - 4, c3 - 6
    trunk = (c1 ** 2 * 121 * 3 * 96 + c2 ** 2 * 25 * 96 * 256 + c3 ** 2 * 9 * 256 * 384 + c4 ** 2 * 9 * 384 * 384
             + c5 ** 2 * 9 * 384 * 256)
    return trunk + 2 * r ** 2 * 9 * 256 * 256 + (r - 3) ** 2 * (10 + 20) * 256 * 16


def test_siamrpn_count_is_the_closed_form_and_the_papers_figure():
    c = count_siamese(meta(SiamRPN, 255))
    assert c["per_frame"]["mac_ops"] == siamrpn_search_by_hand(255)
    assert c["per_frame"]["mac_ops"] == pytest.approx(4.82e9, rel=0.005)  # the paper's Table 3
    template = siamrpn_search_by_hand(127) - 2 * 4 ** 2 * 9 * 256 * 256 - 1 * (10 + 20) * 256 * 16
    assert c["init"]["mac_ops"] == template + 4 ** 2 * 9 * 256 * 256 * (10 + 20)
    assert c["template_and_search"]["mac_ops"] == c["per_frame"]["mac_ops"] + c["init"]["mac_ops"]
    assert count_siamese(meta(SiamRPN, 271))["per_frame"]["mac_ops"] == siamrpn_search_by_hand(271)


def test_siammask_maps_and_count():
    net = meta(SiamMask)
    with torch.no_grad():
        assert net.template(torch.zeros(1, 3, 127, 127, device="meta")).shape == (1, 256, 15, 15)
        assert net.backbone(torch.zeros(1, 3, 255, 255, device="meta")).shape == (1, 256, 31, 31)
    score, box, mask = meta_run(meta(SiamMask), 127, 255)
    assert score.shape == (1, 10, 17, 17) and box.shape == (1, 20, 17, 17) and mask.shape == (1, 63 * 63, 17, 17)
    c = count_siamese(meta(SiamMask))
    frame = c["per_frame"]["by_layer"]
    assert frame["SiamMask.backbone.conv1.0"] == 125 ** 2 * 49 * 3 * 64
    assert frame["SiamMask.mask.conv6"] == 17 ** 2 * 256 * 63 * 63
    assert frame["functional"] == 17 ** 2 * 256 * 15 ** 2  # depth-wise correlation
    # conv4_x: six bottlenecks at 31x31 (1x1 in, dilated 3x3, 1x1 out) and the first one's 512 -> 1024 projection
    conv4 = sum(v for k, v in frame.items() if ".conv4_x." in k)
    assert conv4 == 31 ** 2 * (6 * (256 * 9 * 256 + 256 * 1024) + 512 * 256 + 5 * 1024 * 256 + 512 * 1024)
    both = c["template_and_search"]["mac_ops"]
    assert both == pytest.approx(1.26e10, rel=0.10) and both == c["per_frame"]["mac_ops"] + c["init"]["mac_ops"]


def test_goturn_runs_both_crops_every_frame():
    assert meta_run(meta(GOTURN), 227, 227).shape == (1, 4)
    c = count_siamese(meta(GOTURN))
    assert c["init"]["mac_ops"] == 0
    fc = 2 * 9216 * 4096 + 2 * 4096 * 4096 + 4096 * 4
    conv = 2 * (55 ** 2 * 121 * 3 * 96 + 27 ** 2 * 25 * 48 * 256 + 13 ** 2 * 9 * (256 * 384 + 192 * 384 + 192 * 256))
    assert c["per_frame"]["mac_ops"] == fc + conv


def test_ocean_maps_and_head_count():
    reg, cls, aware = meta_run(meta(Ocean), 127, 255)
    assert reg.shape == (1, 4, 25, 25) and cls.shape == aware.shape == (1, 1, 25, 25)
    c = count_siamese(meta(Ocean))
    frame = c["per_frame"]["by_layer"]
    # per branch, the three dilated 3x3 search convolutions: 31x31 -> 29x29, 29x27, 27x29
    search = 256 * 256 * 9 * (29 * 29 + 2 * 29 * 27)
    assert sum(v for k, v in frame.items() if ".reg_combine.search." in k) == search
    assert frame["functional"] == 2 * 25 * 25 * 256 * (5 * 5 + 2 * 5 * 3)  # three correlations per branch
    towers = 9 * 25 * 25 * 256 * 256 * 9  # 2 x 4 tower layers and the alignment convolution
    assert sum(v for k, v in frame.items() if "_tower." in k or ".align." in k) == towers
