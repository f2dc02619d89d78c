"""SCTN: three convolutional and three fully connected layers of C-LIF neurons, two output neurons.

Input: the events of one 10 ms segment as T = 10 one-millisecond steps x 2 polarity channels on a
107 x 107 canvas (see sctn/encoding.py). Output: the voltages of the two output neurons
(0 = background, 1 = target) at every step. Each convolution runs once over all T steps as one
(T * B) batch (it is linear); only the neurons' recurrence loops over time.

The paper's two output neurons are both there by default; `background_neuron=False` (a named deviation, the
ablation row `no_background_neuron`) leaves the background neuron out of the network and so out of its operation
counts (fc2's spikes then drive one output synapse, not two): the target neuron's weights are drawn as the
preset draws them (the background's row dropped), and the output voltages keep their (..., 2) layout with a
constant 0 where the background neuron was, so every reader of index 1 (the target) runs unchanged.

The defaults are the paper's preset: T = 10 steps of 1 ms and no more, and layers without biases, so
a neuron that no event reaches stays silent (the paper: "only the neurons corresponding to the events
within the bounding box will emit spikes"). `tail_steps` (extra empty steps that let late events reach
their kernel's peak) and `bias` are named deviations for ablations and for checkpoints of the older
layout (biases and two tail steps), which load as such.

Default widths (chosen for speed on a CPU): conv 2->8 (4x4, stride 4) -> 16 (3x3, stride 2) ->
16 (3x3, stride 1); fully connected 1600 -> 64 -> 32 -> 2.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
import torch
from pydantic import BaseModel, ConfigDict, Field
from torch import nn
from torch.nn import functional as F

from sctn.neurons import ALPHA_M, ALPHA_S, CLIF
from sctn.params import CROPS
from sctn.spike_sums import mix_corners, window_sums


class NetworkConfig(BaseModel):
    """Sizes of SCTN: canvas (px), steps, conv channels/kernels/strides, fully connected widths."""

    model_config = ConfigDict(extra="forbid")

    input_size: int = 107
    steps: int = Field(10, ge=1)  # the time steps of one sample: none would score nothing
    step_us: int = Field(1000, ge=1)
    tail_steps: int = Field(0, ge=0)
    bias: bool = False
    channels: tuple[int, int, int] = (8, 16, 16)
    kernels: tuple[int, int, int] = (4, 3, 3)
    strides: tuple[int, int, int] = (4, 2, 1)
    fc: tuple[int, int] = (64, 32)
    alpha_m: float = ALPHA_M
    alpha_s: float = ALPHA_S
    surrogate_width: float = 1.0
    background_neuron: bool = True  # the paper's background output neuron; False: left out (a named deviation)

    def outputs(self) -> int:
        """Output neurons that exist: background and target (2), or the target alone (1)."""
        return 2 if self.background_neuron else 1

    def receptive_field(self) -> tuple[int, int]:
        """(total stride, receptive-field size) of the last convolution's cells, in input pixels."""
        stride, rf = 1, 1
        for k, st in zip(self.kernels, self.strides):
            rf += (k - 1) * stride
            stride *= st
        return stride, rf

    def conv_sizes(self) -> list[int]:
        """Spatial size after each convolution."""
        sizes, s = [], self.input_size
        for k, st in zip(self.kernels, self.strides):
            s = (s - k) // st + 1
            sizes.append(s)
        return sizes


class SCTN(nn.Module):
    """The spiking convolutional tracking network."""

    def __init__(self, cfg: NetworkConfig | None = None) -> None:
        super().__init__()
        self.cfg = cfg = cfg or NetworkConfig()
        chans = (2,) + tuple(cfg.channels)
        self.convs = nn.ModuleList(nn.Conv2d(chans[i], chans[i + 1], cfg.kernels[i], cfg.strides[i], bias=cfg.bias)
                                   for i in range(3))
        flat = cfg.channels[-1] * cfg.conv_sizes()[-1] ** 2
        widths = (flat,) + tuple(cfg.fc) + (2,)
        self.fcs = nn.ModuleList(nn.Linear(widths[i], widths[i + 1], bias=cfg.bias) for i in range(3))
        sizes = list(cfg.channels) + list(cfg.fc) + [cfg.outputs()]
        self.neurons = nn.ModuleList(CLIF(n, cfg.alpha_m, cfg.alpha_s, surrogate_width=cfg.surrogate_width)
                                     for n in sizes)
        self._init_weights()
        if not cfg.background_neuron:
            drop_background(self.fcs[2])

    def _init_weights(self) -> None:
        for layer in list(self.convs) + list(self.fcs):
            nn.init.kaiming_uniform_(layer.weight, a=0.0)
            if layer.bias is not None:
                nn.init.zeros_(layer.bias)

    @torch.no_grad()
    def calibrate(self, x: torch.Tensor, quantile: float = 0.9, target: float = 1.0) -> list[float]:
        """Data-driven init: scale each layer's weights, first to last, so the `quantile` of its neurons'
        maximum voltages on x equals target * theta (sparse spikes need it; ANN inits leave SNNs silent
        or saturated). Returns the factors applied."""
        factors = []
        layers = list(self.convs) + list(self.fcs)
        for k, layer in enumerate(layers):
            volts = self._run(x, record=False, capture=k)[1]
            peak = volts.amax(dim=0).flatten()
            peak = peak[peak > 0][:1_000_000]  # neurons that got any input at all
            q = float(torch.quantile(peak, quantile)) if peak.numel() else 0.0
            if q > 1e-6:
                f = target * self.neurons[k].theta / q
                layer.weight.mul_(f)
                if layer.bias is not None:
                    layer.bias.mul_(f)
                factors.append(f)
            else:
                factors.append(1.0)
        return factors

    @torch.no_grad()
    def fluctuation_init(self, x: torch.Tensor, xi: float = 2.0) -> list[float]:
        """Fluctuation-driven init (Rossbroich, Gygax and Zenke 2022): each layer's weights, first to last, drawn
        from N(0, sigma_w^2) so that on x the membrane potential's standard deviation is theta / xi.

        For inputs spiking at rate nu per step, a neuron of fan-in n with zero-mean weights has Var V = n nu
        sigma_w^2 eps2, eps2 = sum over k = 1..T of the squared PSP kernel V0 (d_m^k - d_s^k) (peak 1), so
        sigma_w = theta / (xi sqrt(n nu eps2)). nu is the rate seen by the neurons that receive any input (the
        inputs under their kernel window; all of a fully connected layer's), measured on x through the layers
        already set. A layer whose input never spikes keeps its weights (nan in the list). Returns the
        sigma_w applied per layer."""
        stds = []
        layers = list(self.convs) + list(self.fcs)
        for k, layer in enumerate(layers):
            spikes = x.transpose(0, 1) if k == 0 else self._run(x, record=False, capture=k - 1)[0]
            rate = window_rate(layer, spikes)
            steps = spikes.shape[0]
            d_m, d_s, v0 = self.neurons[k]._constants((-1,))
            ks = torch.arange(1, steps + 1, dtype=d_m.dtype)[:, None]
            eps2 = float(((v0 * (d_m ** ks - d_s ** ks)) ** 2).sum(dim=0).mean())
            fan_in = layer.weight[0].numel()
            if rate > 0:
                std = self.neurons[k].theta / (xi * math.sqrt(fan_in * rate * eps2))
                nn.init.normal_(layer.weight, 0.0, std)
                if layer.bias is not None:
                    nn.init.zeros_(layer.bias)
                stds.append(std)
            else:
                stds.append(float("nan"))
        return stds

    def _run(self, x: torch.Tensor, record: bool, capture: int | None = None):
        b, t = x.shape[:2]
        if self.cfg.tail_steps:
            x = torch.cat([x, x.new_zeros((b, self.cfg.tail_steps) + x.shape[2:])], dim=1)
            t = x.shape[1]
        h = x.transpose(0, 1)  # (T, B, C, H, W)
        spikes = [h] if record else []
        for k, (conv, neuron) in enumerate(zip(self.convs, self.neurons[:3])):
            cur = conv(h.reshape((t * b,) + h.shape[2:]))
            h, v = neuron(cur.view((t, b) + cur.shape[1:]))
            if capture == k:
                return h, v
            if record:
                spikes.append(h)
        h = h.reshape(t, b, -1)
        for k, (fc, neuron) in enumerate(zip(self.fcs, self.neurons[3:])):
            h, v = neuron(fc(h))
            if capture == k + 3:
                return h, v
            if record and k < 2:
                spikes.append(h)
        if record:
            spikes.append(h)
        return self.with_background(v).transpose(0, 1), spikes

    def with_background(self, v: torch.Tensor) -> torch.Tensor:
        """The output layer's voltages (..., outputs) in the (..., 2) layout: as they are with the background neuron,
        else with a constant 0 in its place (index 0)."""
        return v if self.cfg.background_neuron else torch.cat([torch.zeros_like(v), v], dim=-1)

    def receptive_field(self) -> tuple[int, int]:
        """(total stride, receptive-field size) of the last convolution's cells, in input pixels (its config's)."""
        return self.cfg.receptive_field()

    def forward_search(self, region: torch.Tensor, origins: torch.Tensor, boxes: torch.Tensor,
                       record: bool = False, crop: str = "bilinear"
                       ) -> torch.Tensor | tuple[torch.Tensor, dict]:
        """Fast mode: convolutions once over a search region, then per candidate a crop into the FC layers.

        region (1, T, 2, Hs, Ws) input spikes of all events in the region (not masked per box), T =
        steps or steps + tail_steps (then the tail is already there, zero); origins (N, 2) each
        candidate canvas's top-left corner in region pixels (x, y); boxes (N, 4) each candidate box in
        region pixels (xywh). Each candidate reads the cells of conv3's spike map under its canvas:
        crop="nearest" snaps the canvas to the nearest cell; crop="bilinear" interpolates at its
        sub-cell offset, computed exactly as the bilinear mix of fc1's products with the (up to four)
        integer-cell crops around it, so fc1 always receives spikes. Cells whose receptive-field centre
        lies outside the candidate box are zeroed, standing in for the per-box masking of the input.
        Integer crops at the same cell with the same mask are evaluated once. Returns voltages
        (N, T + tail, 2); with record=True also a dict of what ran: "input", "conv1".."conv3" spikes
        over the region (T, 1, C, H, W), "crops" (T, U, inputs) the U distinct crops fed to fc1,
        "fc1", "fc2" spikes (T, N or U, width) and "mix_macs", the multiply-adds of the bilinear mix.
        """
        check_crop(crop)
        feat, rec = self._conv_region(region)
        in_x, in_y = self._kept_cells(origins, boxes)
        stride, _ = self.receptive_field()
        corners, weights = _crop_corners(origins / stride, crop)  # the canvases' first cells, in map coordinates
        crops = _distinct_crops(corners, weights, in_x, in_y)
        # steps in which conv3 is silent give fc1 its bias alone
        active = torch.nonzero(feat.flatten(1).amax(dim=1) > 0)[:, 0]
        if not (record or torch.is_grad_enabled()):  # inference: event-driven sums, no dense crops
            products = self._event_driven_sums(feat, crops)
        else:
            products, rec["crops"] = self._dense_sums(feat, crops, in_x, in_y, active, record)
        current, expand, rec["mix_macs"] = self._fc1_current(products, crop, crops, weights, len(active))
        return self._fc_layers(current, expand, rec, record)

    def _conv_region(self, region: torch.Tensor) -> tuple[torch.Tensor, dict]:
        """forward_search's first step: the convolutions and their neurons once over the whole region (1, T, 2, Hs,
        Ws), its empty tail added if missing. Returns conv3's spikes (T, C, fh, fw) and the record of every
        layer's spikes so far ("input", "conv1".."conv3", each (T, 1, C, H, W))."""
        cfg = self.cfg
        x = region
        if x.shape[1] == cfg.steps and cfg.tail_steps:
            x = torch.cat([x, x.new_zeros((1, cfg.tail_steps) + x.shape[2:])], dim=1)
        h = x[0]
        rec: dict = {"input": h[:, None]}
        for name, conv, neuron in zip(("conv1", "conv2", "conv3"), self.convs, self.neurons[:3]):
            h, _ = neuron(conv(h)[:, None])
            h = h[:, 0]
            rec[name] = h[:, None]
        return h, rec

    def _kept_cells(self, origins: torch.Tensor, boxes: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Per candidate, the columns and the rows (each (N, cells) bool) of its canvas's conv3 cells whose
        receptive-field centre lies inside its box (region pixels); the others are masked."""
        n_cells = self.cfg.conv_sizes()[-1]
        stride, rf = self.receptive_field()
        cell = torch.arange(n_cells, dtype=torch.float32)
        centre_x = origins[:, 0:1] + stride * cell + rf / 2  # region px of each cell's receptive-field centre
        centre_y = origins[:, 1:2] + stride * cell + rf / 2
        in_x = (centre_x >= boxes[:, 0:1]) & (centre_x < boxes[:, 0:1] + boxes[:, 2:3])  # (N, cells)
        in_y = (centre_y >= boxes[:, 1:2]) & (centre_y < boxes[:, 1:2] + boxes[:, 3:4])
        return in_x, in_y

    def _event_driven_sums(self, feat: torch.Tensor, crops: _Crops) -> torch.Tensor:
        """fc1's weighted sums (T, U, width), no bias, of the distinct crops of conv3's spikes feat (T, C, fh, fw),
        added up from the spikes inside each crop's kept window (inference: no gradient, nothing recorded)."""
        windows = torch.cat([crops.pos, crops.intervals[crops.owner]], dim=1)
        return torch.from_numpy(window_sums(feat.permute(0, 2, 3, 1).numpy(), self._fc1_cell_weights(),
                                            windows.numpy()))

    def _dense_sums(self, feat: torch.Tensor, crops: _Crops, in_x: torch.Tensor, in_y: torch.Tensor,
                    active: torch.Tensor, record: bool) -> tuple[torch.Tensor, torch.Tensor | None]:
        """fc1's weighted sums (T, U, width), no bias, of the distinct crops of conv3's spikes feat (T, C, fh, fw),
        as the gathered crops times fc1's weights (differentiable); active: the steps in which conv3 spiked.
        Returns the sums and, if record, the crops fed to fc1 (T, U, inputs), else None."""
        t, c = feat.shape[:2]
        u, ta = len(crops.pos), len(active)
        # cells masked for every candidate are zero in every crop: leave them, and their fc1 weights,
        # out (a box half the canvas wide keeps ~1/4 of the cells)
        cols = torch.nonzero(in_x.any(dim=0))[:, 0]
        rows = torch.nonzero(in_y.any(dim=0))[:, 0]
        nr, nc = len(rows), len(cols)
        w1 = self._fc1_weights_at(rows, cols)
        recorded = torch.zeros(t, u, nr * nc * c) if record else None
        if not (ta == t and nr and nc):
            products = torch.zeros(t, u, w1.shape[0])  # fc1's weighted sums, no bias yet
        if ta and nr and nc:
            selected = _gather_crops(feat[active], crops.pos, in_y[crops.owner][:, rows], in_x[crops.owner][:, cols],
                                     rows, cols)
            if ta == t:
                products = nn.functional.linear(selected, w1)
            else:
                products[active] = nn.functional.linear(selected, w1)
            if record:
                recorded[active] = selected
        return products, recorded

    def _fc1_weights_at(self, rows: torch.Tensor, cols: torch.Tensor) -> torch.Tensor:
        """fc1's weights (width, inputs) on the conv3 cells of the given rows and columns, in a gathered crop's
        (row, col, channel) order."""
        n_cells = self.cfg.conv_sizes()[-1]
        fc1 = self.fcs[0]
        w1 = fc1.weight.view(-1, self.cfg.channels[-1], n_cells, n_cells)[:, :, rows][:, :, :, cols]
        return w1.permute(0, 2, 3, 1).reshape(fc1.out_features, -1)

    def _fc1_current(self, products: torch.Tensor, crop: str, crops: _Crops, weights: torch.Tensor,
                     ta: int) -> tuple[torch.Tensor, torch.Tensor | None, float]:
        """fc1's input current from the distinct crops' weighted sums products (T, U, width): with crop="nearest"
        per distinct crop (U), with the crops' index per candidate to expand the output by at the end; bilinear,
        per candidate (N), each the mix of its corners' sums. Also the mix's multiply-adds (ta: the steps in
        which conv3 spiked)."""
        fc1 = self.fcs[0]
        if crop == "nearest":
            # the fully connected layers see U distinct inputs: run them on those, expand at the end
            return _plus_bias(products, fc1), crops.inverse, 0.0
        t = products.shape[0]
        n, k = weights.shape
        slot = torch.zeros(n * k, dtype=torch.long)
        slot[crops.used] = crops.inverse
        if products.requires_grad:
            corner_sums = torch.index_select(products, 1, slot).view(t, n, k, -1)  # (T, N, corners, width)
            mixed = (corner_sums * weights[None, :, :, None]).sum(dim=2)
        else:  # fused: no (T, N, corners, width) intermediate
            mixed = torch.from_numpy(mix_corners(products.numpy(), slot.view(n, k).numpy(), weights.numpy()))
        mixing = (weights > 0).sum(dim=1)  # a candidate on a cell (one corner) needs no mixing
        return _plus_bias(mixed, fc1), None, float(mixing[mixing > 1].sum()) * fc1.out_features * ta

    def _fc_layers(self, current: torch.Tensor, expand: torch.Tensor | None, rec: dict, record: bool
                   ) -> torch.Tensor | tuple[torch.Tensor, dict]:
        """forward_search's last step: the fully connected neurons on fc1's current (T, N or U, width), the output
        voltages expanded from distinct crops to candidates if expand is given; (N, T, 2), with rec if record."""
        h, v = self.neurons[3](current)
        rec["fc1"] = h
        h, v = self.neurons[4](self.fcs[1](h))
        rec["fc2"] = h
        _, v = self.neurons[5](self.fcs[2](h))
        v = self.with_background(v)
        if expand is not None:
            v = v[:, expand]
        return (v.transpose(0, 1), rec) if record else v.transpose(0, 1)

    def _fc1_cell_weights(self) -> np.ndarray:
        """fc1's weights as (row, col, channel, output) float32 for spike_sums.window_sums, cached until they change
        (fine-tuning updates them in place)."""
        w = self.fcs[0].weight
        key = (w.data_ptr(), w._version)
        if getattr(self, "_fc1_key", None) != key:
            n = self.cfg.conv_sizes()[-1]
            self._fc1_cells = np.ascontiguousarray(
                w.detach().view(-1, self.cfg.channels[-1], n, n).permute(2, 3, 1, 0).numpy(), np.float32)
            self._fc1_key = key
        return self._fc1_cells

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """Output voltages (B, T + tail, 2) for input spikes x (B, T, 2, H, W); index 1 is the target neuron."""
        return self._run(x, record=False)[0]

    def forward_record(self, x: torch.Tensor) -> tuple[torch.Tensor, list[torch.Tensor]]:
        """Voltages and every layer's spikes (input first, each (T, B, ...)), for energy accounting."""
        return self._run(x, record=True)


def drop_background(out: nn.Linear) -> None:
    """Keep only the target's row (index 1) of a two-output layer, in place: the background output left out."""
    with torch.no_grad():
        out.weight = nn.Parameter(out.weight[1:].clone())
        if out.bias is not None:
            out.bias = nn.Parameter(out.bias[1:].clone())
    out.out_features = 1


def window_rate(layer: nn.Module, spikes: torch.Tensor) -> float:
    """Spikes per input and step that a layer's neurons receive, over the neurons (and samples) whose input
    window holds any spike: spikes (T, B, C, H, W) into a convolution (its kernel windows) or (T, B, ...) into
    a fully connected layer (all its inputs); 0 if no window holds one."""
    counts = spikes.sum(dim=0)  # (B, ...) spikes per input over the steps
    if isinstance(layer, nn.Conv2d):
        ones = counts.new_ones((1, 1) + tuple(layer.kernel_size))
        windows = F.conv2d(counts.sum(dim=1, keepdim=True), ones, stride=layer.stride).flatten()
    else:
        windows = counts.flatten(1).sum(dim=1)
    active = windows[windows > 0]
    if not active.numel():
        return 0.0
    return float(active.mean()) / (layer.weight[0].numel() * spikes.shape[0])


def check_crop(crop: str) -> None:
    """Raise ValueError unless crop names a fast-mode crop (CROPS)."""
    if crop not in CROPS:
        raise ValueError(f"crop must be one of {', '.join(CROPS)}, got {crop!r}")


def _plus_bias(sums: torch.Tensor, layer: nn.Linear) -> torch.Tensor:
    """A linear layer's weighted sums plus its bias, if it has one (the paper preset has none)."""
    return sums if layer.bias is None else sums + layer.bias


class _Crops(NamedTuple):
    """The distinct integer crops of conv3's map a search evaluates (U of them), and how candidates use them."""

    pos: torch.Tensor  # (U, 2) int64 feature-map (x, y) of each crop's first cell
    owner: torch.Tensor  # (U,) int64 a candidate whose mask the crop has
    intervals: torch.Tensor  # (N, 4) int64 per candidate: first kept column, kept columns, first kept row, kept rows
    used: torch.Tensor  # (P,) int64 the (candidate * corners + corner) pairs of nonzero weight
    inverse: torch.Tensor  # (P,) int64 the crop each used pair reads


def _crop_corners(first: torch.Tensor, crop: str) -> tuple[torch.Tensor, torch.Tensor]:
    """The integer cells (N, K, 2) a crop reads per candidate and their weights (N, K), from each canvas's first cell
    in feature-map coordinates first (N, 2): the nearest cell (K = 1), or the four around it, weighted bilinearly."""
    n = first.shape[0]
    if crop == "nearest":
        return torch.round(first)[:, None], torch.ones(n, 1)
    base = torch.floor(first)
    fx, fy = (first - base).unbind(1)
    corners = base[:, None] + torch.tensor([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])
    weights = torch.stack([(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy], dim=1)
    return corners, weights


def _distinct_crops(corners: torch.Tensor, weights: torch.Tensor, in_x: torch.Tensor, in_y: torch.Tensor) -> _Crops:
    """One integer crop per (candidate, corner) of nonzero weight, each distinct (position, mask) once: corners
    (N, K, 2) cells, weights (N, K), in_x / in_y (N, cells) each candidate's kept columns / rows."""
    n, k = weights.shape
    n_cells = in_x.shape[1]
    # a mask is an interval of cells per axis, so (position, first kept cell, kept count) per axis
    # identifies a crop: packed into one int64 (13 + 13 + 4 x 7 bits), unique is a 1-D sort.
    if n_cells >= 128:
        raise ValueError(f"fast search packs cell indices in 7 bits; conv3 has {n_cells} cells a side")
    pos = corners.reshape(n * k, 2).long()
    (sx, nx), (sy, ny) = (_interval(m) for m in (in_x, in_y))
    masks = ((sx * 128 + nx) * 128 + sy) * 128 + ny  # 28 bits
    keys = ((pos[:, 0] + 4096) * 8192 + pos[:, 1] + 4096) * (1 << 28) + masks.repeat_interleave(k)
    used = torch.nonzero(weights.reshape(-1) > 0)[:, 0]
    _, inverse = torch.unique(keys[used], return_inverse=True)
    u = int(inverse.max()) + 1
    rep = used[torch.empty(u, dtype=torch.long).scatter_(0, inverse, torch.arange(len(used)))]
    return _Crops(pos[rep], rep // k, torch.stack([sx, nx, sy, ny], dim=1), used, inverse)


def _gather_crops(feat: torch.Tensor, pos: torch.Tensor, keep_rows: torch.Tensor, keep_cols: torch.Tensor,
                  rows: torch.Tensor, cols: torch.Tensor) -> torch.Tensor:
    """The crops (T, U, rows * cols * C) of spike maps feat (T, C, fh, fw) at the cells (pos (U, 2) + (col, row))
    of the given rows and columns, in (row, col, channel) order; a cell off the map or not kept (keep_rows (U, rows),
    keep_cols (U, cols)) reads zero."""
    ta, c, fh, fw = feat.shape
    ys = pos[:, 1:2] + rows  # (U, rows) feature-map row of each kept cell
    xs = pos[:, 0:1] + cols
    ok = (keep_rows & (ys >= 0) & (ys < fh))[:, :, None] & (keep_cols & (xs >= 0) & (xs < fw))[:, None]
    index = torch.where(ok, ys[:, :, None] * fw + xs[:, None, :], fh * fw)  # fh * fw: a zero cell
    cells = feat.permute(0, 2, 3, 1).reshape(ta, fh * fw, c)
    cells = torch.cat([cells, cells.new_zeros(ta, 1, c)], dim=1)
    # index_select, not cells[:, index]: the advanced-indexing kernel is much slower here
    return torch.index_select(cells, 1, index.view(-1)).view(ta, len(pos), -1)


def _interval(mask: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """(first True index, number of Trues) per row of a boolean (N, cells) mask whose Trues are contiguous."""
    count = mask.sum(dim=1)
    return torch.where(count > 0, mask.to(torch.uint8).argmax(dim=1), 0), count
