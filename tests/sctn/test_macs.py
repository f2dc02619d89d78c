"""The MAC counter against each layer kind's closed form, and its per-module attribution."""

import pytest
import torch
from torch import nn
from torch.nn import functional as F

from sctn.macs import MacCounter, count_macs


def test_conv_with_stride_padding_dilation_and_groups():
    conv = nn.Conv2d(6, 9, (3, 5), stride=(2, 1), padding=(1, 2), dilation=(2, 1), groups=3)
    # H: (11 + 2 - 2 * 2 - 1) // 2 + 1 = 5, W: (13 + 4 - 4 - 1) // 1 + 1 = 13; each output sums 6 / 3 channels x 15 taps
    m = count_macs(conv, torch.zeros(2, 6, 11, 13))
    assert m["mac_ops"] == 2 * 5 * 13 * 9 * (6 // 3) * 3 * 5 == m["by_layer"]["Conv2d"] == m["by_kind"]["conv"]
    assert count_macs(nn.Conv1d(4, 5, 3, stride=2), torch.zeros(1, 4, 9))["mac_ops"] == 4 * 5 * 4 * 3  # 4 outputs
    assert count_macs(nn.Conv3d(2, 3, 2), torch.zeros(1, 2, 3, 3, 3))["mac_ops"] == 8 * 3 * 2 * 8


def test_linear_on_batched_sequences():
    assert count_macs(nn.Linear(7, 3), torch.zeros(4, 5, 7))["mac_ops"] == 4 * 5 * 7 * 3
    assert count_macs(nn.Linear(7, 3), torch.zeros(7))["mac_ops"] == 7 * 3  # a vector: matrix-vector product


def test_conv_transpose_counts_each_input_against_its_group_kernels():
    deconv = nn.ConvTranspose2d(4, 6, 3, stride=2, padding=1, output_padding=1, groups=2)
    m = count_macs(deconv, torch.zeros(2, 4, 5, 5))
    assert m["mac_ops"] == 2 * 5 * 5 * 4 * (6 // 2) * 3 * 3 and m["by_kind"] == {"conv_transpose": m["mac_ops"]}


def test_grouped_and_depthwise_cross_correlation():
    from benchmarks.trackers.reference_nets import depthwise_xcorr, up_channel_xcorr

    x, k = torch.zeros(2, 8, 10, 10), torch.zeros(2, 3 * 8, 4, 4)
    up = count_macs(lambda a, b: up_channel_xcorr(a, b, 3), x, k)
    assert up["mac_ops"] == 2 * 3 * 7 * 7 * 8 * 4 * 4 and up["by_layer"] == {"functional": up["mac_ops"]}
    dw = count_macs(depthwise_xcorr, x, torch.zeros(2, 8, 4, 4))
    assert dw["mac_ops"] == 2 * 8 * 7 * 7 * 4 * 4


def test_batched_and_vector_products():
    a, b = torch.zeros(3, 5, 4), torch.zeros(3, 4, 2)
    for fn in (torch.bmm, torch.matmul, lambda p, q: torch.einsum("bij,bjk->bik", p, q),
               lambda p, q: torch.baddbmm(torch.zeros(3, 5, 2), p, q)):
        assert count_macs(fn, a, b)["mac_ops"] == 3 * 5 * 4 * 2
    assert count_macs(lambda p, q: torch.addbmm(torch.zeros(5, 2), p, q), a, b)["mac_ops"] == 3 * 5 * 4 * 2
    assert count_macs(torch.mv, torch.zeros(5, 4), torch.zeros(4))["mac_ops"] == 20
    assert count_macs(torch.dot, torch.zeros(6), torch.zeros(6))["mac_ops"] == 6
    assert count_macs(nn.Bilinear(5, 6, 7), torch.zeros(3, 5), torch.zeros(3, 6))["mac_ops"] == 3 * 7 * 5 * 6


def test_non_mac_operations_count_nothing():
    net = nn.Sequential(nn.BatchNorm2d(3), nn.ReLU(), nn.MaxPool2d(2), nn.Upsample(scale_factor=2))
    assert count_macs(net, torch.zeros(1, 3, 8, 8))["mac_ops"] == 0


class Siamese(nn.Module):
    def __init__(self):
        super().__init__()
        self.trunk = nn.Sequential(nn.Conv2d(1, 2, 3), nn.ReLU(), nn.Conv2d(2, 4, 3))

    def forward(self, z, x):
        return F.conv2d(self.trunk(x), self.trunk(z))  # the correlation is the parent's own operation


def test_each_operation_goes_to_the_innermost_module_running_it():
    m = count_macs(Siamese(), torch.zeros(1, 1, 7, 7), torch.zeros(1, 1, 12, 12))
    conv0 = (10 * 10 + 5 * 5) * 2 * 9
    conv2 = (8 * 8 + 3 * 3) * 4 * 2 * 9
    corr = 6 * 6 * 4 * 3 * 3  # a 3x3x4 kernel making one output channel over 6x6 positions
    assert m["by_layer"] == {"Siamese.trunk.0": conv0, "Siamese.trunk.2": conv2, "Siamese": corr}
    assert m["mac_ops"] == conv0 + conv2 + corr


def test_two_roots_of_one_class_are_kept_apart():
    first, second, third = (nn.Sequential(nn.Linear(i, o)) for i, o in ((4, 4), (4, 8), (8, 2)))
    m = count_macs(lambda x: third(second(first(x))), torch.zeros(1, 4))
    assert m["by_layer"] == {"Sequential.0": 16, "Sequential#2.0": 32, "Sequential#3.0": 16}


def test_meta_tensors_count_like_real_ones_and_the_counter_leaves_no_hooks():
    def build():
        torch.manual_seed(0)
        return Siamese()

    real = count_macs(build(), torch.zeros(1, 1, 7, 7), torch.zeros(1, 1, 12, 12))
    with torch.device("meta"):
        net, z, x = build(), torch.zeros(1, 1, 7, 7), torch.zeros(1, 1, 12, 12)
    assert count_macs(net, z, x) == real
    counter = MacCounter()
    with counter:
        pass
    from torch.nn.modules import module

    assert not module._global_forward_hooks and not module._global_forward_pre_hooks


def test_the_energy_module_keeps_its_entry_point():
    from sctn.energy import count_macs as energy_count

    assert energy_count(nn.Linear(5, 3), torch.zeros(2, 5))["mac_ops"] == pytest.approx(2 * 5 * 3)
