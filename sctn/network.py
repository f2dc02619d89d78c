"""SCTN: three convolutional and three fully connected layers of C-LIF neurons, two output neurons.

Input: the events of one 10 ms segment as T = 10 one-millisecond steps x 2 polarity channels on a
107 x 107 canvas (see sctn/encoding.py). Output: the voltages of the two output neurons
(0 = background, 1 = target) at every step. Each convolution runs once over all T steps as one
(T * B) batch (it is linear); only the neurons' recurrence loops over time. `tail_steps` extra steps
without input let late events reach their kernel's peak.

Default widths (chosen for speed on a CPU): conv 2->8 (4x4, stride 4) -> 16 (3x3, stride 2) ->
16 (3x3, stride 1); fully connected 1600 -> 64 -> 32 -> 2.
"""

from __future__ import annotations

import torch
from pydantic import BaseModel, ConfigDict
from torch import nn

from sctn.neurons import CLIF


class NetworkConfig(BaseModel):
    """Sizes of SCTN: canvas (px), steps, conv channels/kernels/strides, fully connected widths."""

    model_config = ConfigDict(extra="forbid")

    input_size: int = 107
    steps: int = 10
    step_us: int = 1000
    tail_steps: int = 2
    channels: tuple[int, int, int] = (8, 16, 16)
    kernels: tuple[int, int, int] = (4, 3, 3)
    strides: tuple[int, int, int] = (4, 2, 1)
    fc: tuple[int, int] = (64, 32)
    alpha_m: float = 4.0
    alpha_s: float = 1.5
    surrogate_width: float = 1.0

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
        self.convs = nn.ModuleList(nn.Conv2d(chans[i], chans[i + 1], cfg.kernels[i], cfg.strides[i])
                                   for i in range(3))
        flat = cfg.channels[-1] * cfg.conv_sizes()[-1] ** 2
        widths = (flat,) + tuple(cfg.fc) + (2,)
        self.fcs = nn.ModuleList(nn.Linear(widths[i], widths[i + 1]) for i in range(3))
        sizes = list(cfg.channels) + list(cfg.fc) + [2]
        self.neurons = nn.ModuleList(CLIF(n, cfg.alpha_m, cfg.alpha_s, surrogate_width=cfg.surrogate_width)
                                     for n in sizes)
        self._init_weights()

    def _init_weights(self) -> None:
        for layer in list(self.convs) + list(self.fcs):
            nn.init.kaiming_uniform_(layer.weight, a=0.0)
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
                layer.bias.mul_(f)
                factors.append(f)
            else:
                factors.append(1.0)
        return factors

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
        return v.transpose(0, 1), spikes

    def receptive_field(self) -> tuple[int, int]:
        """(total stride, receptive-field size) of the last convolution's cells, in input pixels."""
        stride, rf = 1, 1
        for k, st in zip(self.cfg.kernels, self.cfg.strides):
            rf += (k - 1) * stride
            stride *= st
        return stride, rf

    def forward_search(self, region: torch.Tensor, origins: torch.Tensor, boxes: torch.Tensor,
                       record: bool = False) -> torch.Tensor | tuple[torch.Tensor, list[torch.Tensor]]:
        """Fast mode: convolutions once over a search region, then per candidate a crop into the FC layers.

        region (1, T, 2, Hs, Ws) input spikes of all events in the region (not masked per box);
        origins (N, 2) each candidate canvas's top-left corner in region pixels (x, y);
        boxes (N, 4) each candidate box in region pixels (xywh). The crop of the last convolution's
        spikes is bilinear at sub-cell offsets; cells whose receptive-field centre lies outside the
        candidate box are zeroed, standing in for the per-box masking of the input.
        Returns voltages (N, T + tail, 2); with record=True also the region's input and conv spikes
        (each (T, 1, C, H, W)), the crops fed to fc1 (T, N, fc1 inputs) and the fc spikes (T, N, width).
        """
        cfg = self.cfg
        x = region
        if cfg.tail_steps:
            x = torch.cat([x, x.new_zeros((1, cfg.tail_steps) + x.shape[2:])], dim=1)
        t = x.shape[1]
        h = x.transpose(0, 1)
        recorded = [h]
        for conv, neuron in zip(self.convs, self.neurons[:3]):
            cur = conv(h.reshape((t,) + h.shape[2:]))
            h, _ = neuron(cur.view((t, 1) + cur.shape[1:]))
            recorded.append(h)
        feat = h[:, 0]  # (T, C, fh, fw)
        c, fh, fw = feat.shape[1:]
        n_cells = cfg.conv_sizes()[-1]
        stride, rf = self.receptive_field()
        n = origins.shape[0]
        cell = torch.arange(n_cells, dtype=torch.float32)
        # feature-map coordinates of each candidate's cells; grid_sample wants [-1, 1] (align_corners=True)
        gx = (origins[:, 0:1] / stride + cell) / max(fw - 1, 1) * 2 - 1  # (N, n_cells)
        gy = (origins[:, 1:2] / stride + cell) / max(fh - 1, 1) * 2 - 1
        centre_x = origins[:, 0:1] + stride * cell + rf / 2  # region px of each cell's receptive-field centre
        centre_y = origins[:, 1:2] + stride * cell + rf / 2
        in_x = (centre_x >= boxes[:, 0:1]) & (centre_x < boxes[:, 0:1] + boxes[:, 2:3])
        in_y = (centre_y >= boxes[:, 1:2]) & (centre_y < boxes[:, 1:2] + boxes[:, 3:4])
        # masked cells sample far outside the map, where zero padding gives exactly 0: masking for free
        gx = torch.where(in_x, gx, torch.full_like(gx, -4.0))
        gy = torch.where(in_y, gy, torch.full_like(gy, -4.0))
        grid = torch.stack([gx[:, None, :].expand(n, n_cells, n_cells), gy[:, :, None].expand(n, n_cells, n_cells)],
                           dim=-1).reshape(1, n * n_cells, n_cells, 2)
        # one sampling pass per step with the candidates stacked along the rows: the output is already
        # time-major, (T, C, N * rows, cols), so only a cheap (C, N) swap precedes the product
        crops = nn.functional.grid_sample(feat, grid.expand(t, -1, -1, -1), mode="bilinear", padding_mode="zeros",
                                          align_corners=True)
        h = crops.view(t, c, n, n_cells * n_cells).transpose(1, 2).reshape(t, n, -1)
        recorded.append(h)
        for fc, neuron in zip(self.fcs, self.neurons[3:]):
            h, v = neuron(fc(h))
            recorded.append(h)
        return (v.transpose(0, 1), recorded) if record else v.transpose(0, 1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """Output voltages (B, T + tail, 2) for input spikes x (B, T, 2, H, W); index 1 is the target neuron."""
        return self._run(x, record=False)[0]

    def forward_record(self, x: torch.Tensor) -> tuple[torch.Tensor, list[torch.Tensor]]:
        """Voltages and every layer's spikes (input first, each (T, B, ...)), for energy accounting."""
        return self._run(x, record=True)
