"""Per-candidate SCTN evaluation (the paper's method) driven by the events and spikes that exist.

The dense path encodes each candidate box on its own 107 x 107 canvas (sctn.encoding.encode_boxes)
and runs the whole network on it: almost all of that input is zeros. Without biases a neuron that
never receives current stays at V = 0 and never fires, so only what events reach needs computing:

- input -> conv1: conv1's kernel equals its stride (4 x 4, stride 4), so each canvas pixel feeds one
  conv1 cell. The segment's events are first merged per sensor pixel (bits 2 step + polarity: repeats
  fall together, as on the binary canvas); each candidate's pixels (inside its box) set bits of a
  32-bit mask per (cell, step), one bit per (row, column, polarity) of the kernel. Only the cells that
  got a bit run their C-LIF neurons.
- conv2, conv3: only cells whose window holds a spike of the layer below run; their current is the sum
  of the weight vectors of the spikes in the window (additions only).
- fc1, fc2, out: the model's own layers on conv3's spikes, fc1 only on the (candidate, step) rows in
  which conv3 fired (a silent row's current is 0).

Outputs equal the dense path's bit for bit, not just to rounding: each current is summed in the
order torch's CPU convolution sums it (oneDNN: by blocks of input channels, 16 with AVX-512 and 8
with AVX2, then kernel row, column, channel; for some shapes, e.g. 32 input channels with AVX-512, each
block on its own and the blocks' sums added in order; summation_blocks finds the order on this machine by
reproducing a convolution of the dense path's shape), the neurons repeat
sctn.neurons._clif_steps's arithmetic, and the fully connected layers are torch's (a row's result
does not depend on the other rows of a batch of 16 or more; fewer are summed as the dense path's
own batch). A model for which this cannot hold (a nonzero bias, an overlapping first kernel, more
than 64 channels, a summation order not reproduced here) is refused by `exact_blocker`'s reason;
SCTNTracker then runs the dense path.
"""

from __future__ import annotations

import functools
import threading

import numpy as np
import torch

from dvsot.events import EventBatch
from sctn.encoding import box_canvas, encode_boxes
from sctn.energy import LAYER_NAMES, conv_fanout, count_synaptic_ops
from sctn.network import SCTN
from sctn.sparse.kernels import conv_layers


def exact_blocker(model: SCTN) -> str | None:
    """Why sparse evaluation cannot reproduce `model`'s dense per-candidate outputs exactly, or None if it can."""
    cfg = model.cfg
    for name, layer in zip(("conv1", "conv2", "conv3", "fc1", "fc2", "fc3"), list(model.convs) + list(model.fcs)):
        if layer.bias is not None and bool(torch.count_nonzero(layer.bias.detach())):
            return f"{name} has a nonzero bias (neurons without events can fire)"
    if cfg.kernels[0] != cfg.strides[0] or 2 * cfg.kernels[0] ** 2 > 32:
        return "conv1's kernel must equal its stride and hold at most 32 inputs (2 x k x k)"
    if max(cfg.channels) > MAX_CHANNELS:
        return f"more than {MAX_CHANNELS} channels in a convolution (a cell's spikes are the bits of an int64)"
    if cfg.steps > 31:
        return "more than 31 time steps with events (a pixel's events are kept as 2 bits per step of an int64)"
    blocks = summation_blocks(model)
    if isinstance(blocks, str):
        return blocks
    return None


def summation_blocks(model: SCTN) -> tuple[int, int, int] | str:
    """Per convolution, the input-channel block by which this machine's torch sums a window (by block, then kernel
    row, column, channel: oneDNN's order, the block set by the CPU's vector width), found by reproducing a
    convolution of the dense path's shape bit for bit; or why no order reproduced here matches (a string).
    fc1..fc3 are checked too: their row sums must not depend on which other rows share the batch."""
    cfg = model.cfg
    steps = cfg.steps + cfg.tail_steps
    batch = steps * DENSE_CHUNK
    sizes = [cfg.input_size] + cfg.conv_sizes()
    blocks = []
    for k, conv in enumerate(model.convs):
        blk = _conv_block(conv.in_channels, conv.out_channels, conv.kernel_size[0], conv.stride[0], sizes[k],
                          conv.bias is not None, batch, torch.get_num_threads())
        if blk is None or (k == 0 and blk != conv.in_channels):
            return f"conv{k + 1}: torch sums its windows in an order not reproduced here"
        blocks.append(blk)
    for k, fc in enumerate(model.fcs):
        if not _rows_independent(fc.in_features, fc.out_features, fc.bias is not None, batch, torch.get_num_threads()):
            return f"fc{k + 1}: torch's sums of a row depend on the other rows of the batch"
    return tuple(blocks)


DENSE_CHUNK = 64  # candidates per batch of the dense path
MAX_CHANNELS = 64  # a convolution's channels: one bit each in a cell's int64 spike mask per step


@functools.lru_cache(maxsize=64)
def _conv_block(c_in: int, c_out: int, k: int, stride: int, size: int, bias: bool, batch: int,
                threads: int) -> int | None:
    """The input-channel block of torch's window sums for a convolution of this shape on a batch of `batch`: blk for
    one running sum through the blocks, -blk for each block summed on its own and the blocks' sums added in order;
    or None."""
    gen = torch.Generator().manual_seed(12)
    w = torch.randn(c_out, c_in, k, k, generator=gen)
    x = (torch.rand(batch, c_in, size, size, generator=gen) < 0.4).float()
    with torch.no_grad():
        ref = torch.nn.functional.conv2d(x, w, torch.zeros(c_out) if bias else None, stride)[:8, 0].numpy()
    xs, w0 = x[:8].numpy(), w[0].numpy()
    out = ref.shape[-1]

    def block_sum(c0: int, blk: int, acc: np.ndarray) -> np.ndarray:
        for ky in range(k):
            for kx in range(k):
                for c in range(c0, min(c0 + blk, c_in)):
                    window = xs[:, c, ky:ky + stride * (out - 1) + 1:stride, kx:kx + stride * (out - 1) + 1:stride]
                    acc = acc + window * w0[c, ky, kx]
        return acc

    for blk in sorted({c_in, 16, 8, 4, 2, 1} - {b for b in (16, 8, 4, 2, 1) if b > c_in}, reverse=True):
        acc = np.zeros_like(ref)
        for c0 in range(0, c_in, blk):  # one running sum through the blocks
            acc = block_sum(c0, blk, acc)
        if np.array_equal(acc, ref):
            return blk
        if blk < c_in:  # each block summed on its own, then the blocks' sums in order (oneDNN, 32 channels on AVX-512)
            acc = np.zeros_like(ref)
            for c0 in range(0, c_in, blk):
                acc = acc + block_sum(c0, blk, np.zeros_like(ref))
            if np.array_equal(acc, ref):
                return -blk
    return None


@functools.lru_cache(maxsize=64)
def _rows_independent(n_in: int, n_out: int, bias: bool, batch: int, threads: int) -> bool:
    """Whether torch's linear layer of this shape gives each row the same sums in any batch of MIN_ROWS rows or more
    (MKL takes another path for fewer: 1-15 rows differ in the last bit here)."""
    gen = torch.Generator().manual_seed(13)
    layer = torch.nn.Linear(n_in, n_out, bias=bias)
    with torch.no_grad():
        layer.weight.copy_(torch.randn(n_out, n_in, generator=gen))
        if bias:
            layer.bias.zero_()
        x = (torch.rand(4 * batch, n_in, generator=gen) < 0.1).float()
        ref = layer(x[:batch])
        return torch.equal(layer(x)[:batch], ref) and all(
            torch.equal(layer(x[:m]), ref[:m]) for m in (MIN_ROWS, MIN_ROWS + 1, 31, 64, 100, 257) if m <= batch)


MIN_ROWS = 16  # fc1 runs on at least this many rows (silent ones added), as the dense path's batches have


def dense_candidate_voltages(model: SCTN, events: EventBatch, t0_us: int, boxes_xywh: np.ndarray,
                             chunk: int = DENSE_CHUNK) -> torch.Tensor:
    """Output voltages (N, T + tail, 2) of N candidate boxes the dense way: encode_boxes and the whole network,
    `chunk` candidates at a time (the reference candidate_voltages reproduces; any model)."""
    cfg = model.cfg
    boxes = np.asarray(boxes_xywh, np.float32).reshape(-1, 4)
    with torch.no_grad():
        parts = [model(encode_boxes(events, t0_us, boxes[i:i + chunk], cfg))
                 for i in range(0, len(boxes), chunk)]
    return torch.cat(parts) if parts else torch.zeros(0, cfg.steps + cfg.tail_steps, 2)


def per_candidate_voltages(model: SCTN, events: EventBatch, t0_us: int, boxes_xywh: np.ndarray
                           ) -> tuple[torch.Tensor, str]:
    """The paper's per-candidate voltages (N, T + tail, 2) and how they were computed: "sparse" (candidate_voltages)
    when that is exact for the model, else "dense (<reason>)" (dense_candidate_voltages)."""
    reason = exact_blocker(model)
    if reason is None:
        return candidate_voltages(model, events, t0_us, boxes_xywh), "sparse"
    return dense_candidate_voltages(model, events, t0_us, boxes_xywh), f"dense ({reason})"


def candidate_voltages(model: SCTN, events: EventBatch, t0_us: int, boxes_xywh: np.ndarray) -> torch.Tensor:
    """Output voltages (N, T + tail, 2) of N candidate boxes (xywh px) of the segment starting at t0_us, each
    on its own masked canvas: `model(encode_boxes(events, t0_us, boxes))` computed from the events alone."""
    return _evaluate(model, events, t0_us, boxes_xywh, record=False)[0]


def candidate_record(model: SCTN, events: EventBatch, t0_us: int, boxes_xywh: np.ndarray
                     ) -> tuple[torch.Tensor, dict[str, np.ndarray]]:
    """Voltages as candidate_voltages and, per layer of sctn.energy.LAYER_NAMES, each candidate's spike count and
    the AC operations they drive (spikes x fan-out, as sctn.energy.layer_ops counts them): "spikes" and "ac_ops",
    each {layer: (N,) float64}; "maps": the spikes of conv3 (flattened as fc1 reads them), fc1, fc2 and the
    output layer (its neurons that exist), each (T + tail, N, width) as forward_record gives them."""
    return _evaluate(model, events, t0_us, boxes_xywh, record=True)


def candidate_ops(model: SCTN, events, t0_us: int, boxes_xywh, batch: int = 64) -> float:
    """AC operations of evaluating each candidate box on its own masked input (the paper's tracking), summed over the
    boxes: event-driven (candidate_record) where that is exact, else densely (sctn.energy.count_synaptic_ops)."""
    if exact_blocker(model) is None:
        _, rec = candidate_record(model, events, t0_us, boxes_xywh)
        return float(sum(float(v.sum()) for v in rec["ac_ops"].values()))
    cfg, total = model.cfg, 0.0
    for i in range(0, len(boxes_xywh), batch):
        x = encode_boxes(events, t0_us, boxes_xywh[i:i + batch], cfg)
        total += count_synaptic_ops(model, x)["ac_ops_per_sample"] * len(x)
    return total


def _evaluate(model: SCTN, events: EventBatch, t0_us: int, boxes_xywh: np.ndarray, record: bool):
    reason = exact_blocker(model)
    if reason is not None:
        raise ValueError(f"sparse per-candidate evaluation is not exact for this model: {reason}")
    blocks = summation_blocks(model)
    cfg = model.cfg
    size, steps = cfg.input_size, cfg.steps
    total = steps + cfg.tail_steps
    boxes = np.asarray(boxes_xywh, np.float32).reshape(-1, 4)
    n = len(boxes)
    if n == 0:
        maps = {"conv3": torch.zeros(total, 0, cfg.channels[2] * cfg.conv_sizes()[2] ** 2),
                "fc1": torch.zeros(total, 0, cfg.fc[0]), "fc2": torch.zeros(total, 0, cfg.fc[1]),
                "output": torch.zeros(total, 0, model.fcs[2].out_features)}
        none = {name: np.zeros(0) for name in LAYER_NAMES}
        return torch.zeros(0, total, 2), {"spikes": none, "ac_ops": dict(none), "maps": maps} if record else None
    geom = np.ascontiguousarray(box_canvas(boxes, size))
    ex, ey, occ, tile_start, tiles = _segment_events(events, t0_us, geom, steps, cfg.step_us)
    sizes = [size] + cfg.conv_sizes()
    c3 = cfg.channels[2]
    rows3 = _scratch_rows(max(n * total, MIN_ROWS), c3 * sizes[3] ** 2)  # conv3's rows that spike
    row_of = np.full(n * total, -1, np.int64)  # (candidate, step) -> its row of rows3
    counts = np.zeros((n, 4, 2), np.float64)  # per layer input .. conv3: spikes, ACs
    weights, consts, fans = _kernel_arrays(model)
    used = conv_layers(ex, ey, occ, tile_start, tiles, geom, np.float32(size / 2), size, *sizes[1:], *cfg.kernels,
                        *weights, *cfg.channels, cfg.strides[1], cfg.strides[2], *blocks[1:], *consts,
                        np.float32(model.neurons[0].theta), total, record, *fans, rows3, row_of,
                       counts)
    last = n % DENSE_CHUNK
    if n > DENSE_CHUNK and 0 < last * total < MIN_ROWS:  # the dense path's last batch is that small: so is ours
        parts = [_fc_layers(model, rows3, row_of[:(n - last) * total], used, total),
                 _fc_layers(model, rows3, row_of[(n - last) * total:], used, total)]
        fc_spikes = [torch.cat([p[k] for p in parts], dim=1) for k in range(2)]
        out, v = torch.cat([p[3] for p in parts], dim=1), torch.cat([p[4] for p in parts], dim=1)
    else:
        *fc_spikes, out, v = _fc_layers(model, rows3, row_of, used, total)
    volts = v.transpose(0, 1)
    if not record:
        return volts, None
    spikes = {name: counts[:, k, 0].copy() for k, name in enumerate(LAYER_NAMES[:4])}
    ops = {name: counts[:, k, 1].copy() for k, name in enumerate(LAYER_NAMES[:3])}
    ops["conv3"] = spikes["conv3"] * model.fcs[0].out_features
    for k, (name, s) in enumerate(zip(LAYER_NAMES[4:], fc_spikes + [out])):
        spikes[name] = s.sum(dim=(0, 2)).double().numpy()
        ops[name] = spikes[name] * (model.fcs[k + 1].out_features if k < 2 else 0)
    conv3 = torch.zeros(n * total, rows3.shape[1])
    if used:
        conv3[torch.from_numpy(np.flatnonzero(row_of >= 0))] = torch.from_numpy(rows3[row_of[row_of >= 0]])
    maps = {"conv3": conv3.view(n, total, -1).transpose(0, 1), "fc1": fc_spikes[0], "fc2": fc_spikes[1], "output": out}
    return volts, {"spikes": spikes, "ac_ops": ops, "maps": maps}


def _scratch_rows(rows: int, width: int) -> np.ndarray:
    """A float32 (rows, width) buffer for conv3's spike rows, kept per thread between calls: a new one per segment
    (16 MB for 256 candidates) cost a page fault per 4 kB page touched."""
    buf = getattr(_SCRATCH, "rows3", None)
    if buf is None or buf.shape[0] < rows or buf.shape[1] != width:
        buf = _SCRATCH.rows3 = np.empty((rows, width), np.float32)
    return buf[:rows]


_SCRATCH = threading.local()


def _kernel_arrays(model: SCTN) -> tuple[list[np.ndarray], list[np.ndarray], list[np.ndarray]]:
    """The convolutions' weights, neuron constants and fan-outs as conv_layers reads them, cached on the model until
    a parameter changes (fine-tuning updates them in place)."""
    params = list(model.convs.parameters()) + list(model.neurons[:3].parameters())
    key = tuple((p.data_ptr(), p._version) for p in params)
    cached = getattr(model, "_sparse_arrays", None)
    if cached is not None and cached[0] == key:
        return cached[1]
    sizes = [model.cfg.input_size] + model.cfg.conv_sizes()
    with torch.no_grad():
        # (kernel row, column, input channel) x output channel: the order torch's convolution sums a window in
        weights = [np.ascontiguousarray(c.weight.detach().permute(2, 3, 1, 0).reshape(-1).numpy(), np.float32)
                   for c in model.convs]
        # d_m, d_s, V0 per neuron of a layer's cells side by side (cell-major, channel-minor)
        consts = [np.ascontiguousarray(np.tile(np.stack(model.neurons[k]._inference_constants()),
                                               (1, sizes[k + 1] ** 2))) for k in range(3)]
        fans = [np.ascontiguousarray(conv_fanout(model.convs[k], (sizes[k], sizes[k])).numpy().reshape(-1), np.float64)
                for k in range(3)]
    model._sparse_arrays = (key, (weights, consts, fans))
    return weights, consts, fans


def _fc_layers(model: SCTN, rows3: np.ndarray, row_of: np.ndarray, used: int, total: int) -> list[torch.Tensor]:
    """fc1, fc2 and the output layer, by the model's own layers, for the candidates of row_of (their (candidate,
    step) -> row of conv3's spikes rows3, or -1 where conv3 is silent): spikes of fc1, fc2, the output, and the
    output voltages, each (T, N, width)."""
    n = len(row_of) // total
    fc1 = model.fcs[0]
    mine = row_of >= 0
    with torch.no_grad():
        if n * total < MIN_ROWS:  # the dense path's batch exactly: MKL sums a batch this small in another order
            conv3 = np.zeros((n * total, rows3.shape[1]), np.float32)
            conv3[mine] = rows3[row_of[mine]]
            current = fc1(torch.from_numpy(conv3))
        else:
            # a row's sums do not depend on the other rows of a batch of MIN_ROWS or more (summation_blocks checks
            # it), so only the rows in which conv3 fired are run; the others' current is 0
            current = torch.zeros(n * total, fc1.out_features)
            if mine.any():
                rows3[used:MIN_ROWS] = 0
                sums = fc1(torch.from_numpy(rows3[:max(used, MIN_ROWS)]))
                current[torch.from_numpy(np.flatnonzero(mine))] = sums[torch.from_numpy(row_of[mine])]
        h1, _ = model.neurons[3](current.view(n, total, -1).transpose(0, 1))  # (T, N, width), as the dense path
        h2, _ = model.neurons[4](model.fcs[1](h1))
        out, v = model.neurons[5](model.fcs[2](h2))
    return [h1, h2, out, model.with_background(v)]


def _segment_events(events: EventBatch, t0_us: int, geom: np.ndarray, steps: int, step_us: int):
    """The segment's active pixels inside some box, grouped by sensor tile of TILE x TILE px: pixel centres x, y
    (float32, as encode_boxes forms them), the pixel's events as bits 2 step + polarity (int64: repeats fall
    together, as on the binary canvas), the tiles' CSR starts and, per box, the first and last tile column and
    row that can hold its pixels and the tile columns (N, 5)."""
    step = (np.asarray(events.t, np.int64) - int(t0_us)) // step_us
    ex = events.x.astype(np.float32) + np.float32(0.5)
    ey = events.y.astype(np.float32) + np.float32(0.5)
    keep = ((step >= 0) & (step < steps) & (ex >= geom[:, 0].min(initial=np.inf)) & (ex < geom[:, 1].max(initial=0))
            & (ey >= geom[:, 2].min(initial=np.inf)) & (ey < geom[:, 3].max(initial=0)))
    x, y = events.x[keep].astype(np.int64), events.y[keep].astype(np.int64)
    cols = int(x.max(initial=0)) // TILE + 1
    rows = int(y.max(initial=0)) // TILE + 1
    # one entry per pixel, sorted by tile then pixel: its (step, polarity) bits OR-ed together
    key = (y // TILE * cols + x // TILE) * TILE * TILE + (y % TILE) * TILE + x % TILE
    bit = np.left_shift(np.int64(1), step[keep] * 2 + events.p[keep].astype(np.int64))
    order = np.argsort(key, kind="stable")
    key, bit = key[order], bit[order]
    first = np.flatnonzero(np.concatenate([[True], key[1:] != key[:-1]])) if len(key) else np.zeros(0, np.int64)
    occ = np.bitwise_or.reduceat(bit, first) if len(key) else np.zeros(0, np.int64)
    key = key[first]
    tile = key // (TILE * TILE)
    px = (tile % cols) * TILE + key % TILE
    py = (tile // cols) * TILE + key // TILE % TILE
    tile_start = np.searchsorted(tile, np.arange(rows * cols + 1))
    # pixel x holds events with centre x + 0.5 in [left, right): tiles floor((left - 0.5) / TILE) ..
    # floor((right - 0.5) / TILE), clipped (the kernel tests each pixel exactly)
    edges = np.floor((geom[:, :4].astype(np.float64) - 0.5) / TILE).astype(np.int64)
    limit = np.array([cols, cols, rows, rows]) - 1
    tiles = np.stack([np.clip(edges[:, k], 0, limit[k]) for k in range(4)] + [np.full(len(geom), cols)], axis=1)
    empty = (edges[:, 1] < 0) | (edges[:, 3] < 0) | (edges[:, 0] > limit[0]) | (edges[:, 2] > limit[2])
    tiles[empty, 1] = tiles[empty, 0] - 1  # no tile at all
    return (np.ascontiguousarray(px.astype(np.float32) + np.float32(0.5)),
            np.ascontiguousarray(py.astype(np.float32) + np.float32(0.5)), np.ascontiguousarray(occ, np.int64),
            tile_start.astype(np.int64), np.ascontiguousarray(tiles))


TILE = 8
