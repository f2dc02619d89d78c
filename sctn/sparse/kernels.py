"""Compiled kernels of sctn/sparse/evaluate.py: the input and the three spiking convolutions of SCTN per candidate,
over the events and spikes that exist (see that module for the method and why it is exact).

Spikes of a layer are kept as channel bits per (cell, step) (an int64 mask), so a convolution adds
exactly the weight rows of the spikes in each window, lowest channel first, in the order torch's CPU
convolution sums them. Rows are added as one 16- or 8-lane vector (_vadd: numba leaves such short
loops scalar), the steps of a cell interleaved (independent sums that overlap), and C-LIF runs over
all of a layer's cells side by side (per cell its 8 or 16 channels would not vectorise)."""

from __future__ import annotations

import numba
import numpy as np
from llvmlite import ir
from numba import types
from numba.extending import intrinsic


@intrinsic
def _vadd(typingctx, cur, at, w, src, lanes):
    """cur[at:at + lanes] += w[src:src + lanes] as one vector operation of `lanes` (8 or 16, a literal) float32
    lanes: lane by lane the same IEEE additions as a loop (numba leaves such short loops scalar). No bounds
    check: callers keep the indices in range."""
    if not isinstance(lanes, types.IntegerLiteral):
        return None
    n = lanes.literal_value

    def codegen(context, builder, sig, args):
        vec = ir.VectorType(ir.FloatType(), n).as_pointer()
        a_cur = context.make_array(sig.args[0])(context, builder, args[0])
        a_w = context.make_array(sig.args[2])(context, builder, args[2])
        p_cur = builder.bitcast(builder.gep(a_cur.data, [args[1]]), vec)
        p_w = builder.bitcast(builder.gep(a_w.data, [args[3]]), vec)
        builder.store(builder.fadd(builder.load(p_cur, align=4), builder.load(p_w, align=4)), p_cur, align=4)
        return context.get_dummy_value()
    return types.void(cur, at, w, src, lanes), codegen


@intrinsic
def _load_u64(typingctx, arr, at):
    """The 8 bytes arr[at:at + 8] of a byte array as one little-endian uint64 (no bounds check)."""
    def codegen(context, builder, sig, args):
        a = context.make_array(sig.args[0])(context, builder, args[0])
        ptr = builder.bitcast(builder.gep(a.data, [args[1]]), ir.IntType(64).as_pointer())
        return builder.load(ptr, align=1)
    return types.uint64(arr, at), codegen


@intrinsic
def _ctz(typingctx, x):
    """The index of the lowest set bit of an int64 (x != 0)."""
    def codegen(context, builder, sig, args):
        return builder.cttz(args[0], ir.Constant(ir.IntType(1), 1))
    return types.int64(types.int64), codegen


@intrinsic
def _popcount(typingctx, x):
    """The number of set bits of an int64."""
    def codegen(context, builder, sig, args):
        return builder.ctpop(args[0])
    return types.int64(types.int64), codegen


@numba.njit(cache=True, inline="always")
def _add_row(cur: np.ndarray, at: int, w: np.ndarray, row: int, ch: int) -> None:  # pragma: no cover - compiled
    """cur[at:at + ch] += w[row * ch:(row + 1) * ch], by vectors of 16 and 8 lanes, the rest lane by lane."""
    src = row * ch
    if ch == 16:  # the usual widths, without the loops
        _vadd(cur, at, w, src, 16)
        return
    if ch == 8:
        _vadd(cur, at, w, src, 8)
        return
    o = 0
    while o + 16 <= ch:
        _vadd(cur, at + o, w, src + o, 16)
        o += 16
    while o + 8 <= ch:
        _vadd(cur, at + o, w, src + o, 8)
        o += 8
    while o < ch:
        cur[at + o] += w[src + o]
        o += 1


@numba.njit(cache=True)
def _clif_flat(cur: np.ndarray, width: int, m: int, steps: int, consts: np.ndarray, theta: np.float32,
               fired: np.ndarray, state: np.ndarray) -> None:  # pragma: no cover - compiled
    """C-LIF of neurons 0..m-1 over currents cur (steps x width, flat) into fired (same layout), exactly as
    sctn.neurons._clif_steps computes it; consts (3, >= m) d_m, d_s, V0 per neuron, state (3, >= m) scratch.
    Neurons innermost and contiguous, so the loop vectorises (per cell it would not: 8 or 16 channels)."""
    u, w, reset = state[0], state[1], state[2]
    d_m, d_s, v0 = consts[0], consts[1], consts[2]
    for j in range(m):
        u[j] = 0
        w[j] = 0
        reset[j] = 0
    for t in range(steps):
        c = cur[t * width:t * width + m]
        f = fired[t * width:t * width + m]
        for j in range(m):
            x = c[j] * v0[j]
            un = (u[j] + x - reset[j]) * d_m[j]
            wn = (w[j] + x) * d_s[j]
            u[j] = un
            w[j] = wn
            spike = un - wn >= theta
            f[j] = spike
            reset[j] = theta * spike


@numba.njit(cache=True)
def _spike_masks(fired: np.ndarray, width: int, n: int, ch: int, steps: int, masks: np.ndarray,
                 alive: np.ndarray) -> int:  # pragma: no cover - compiled
    """The spikes of n cells (fired: steps x width flat bytes, cell-major channels) as channel bits: masks[j *
    steps + t] bit c is cell j's channel c at step t; alive[j] whether cell j fired at all. Returns the spikes.
    Eight channels' bytes (0 or 1) are read as one word and packed into a byte of bits by a multiply."""
    total = 0
    pack = np.uint64(0x0102040810204080)
    for j in range(n):
        seen = 0
        for t in range(steps):
            at = t * width + j * ch
            m = 0
            for g in range(0, ch, 8):
                word = _load_u64(fired, at + g)
                if ch - g < 8:
                    word &= (np.uint64(1) << np.uint64(8 * (ch - g))) - np.uint64(1)
                m |= np.int64((word * pack) >> np.uint64(56)) << g
            masks[j * steps + t] = m
            seen |= m
            total += _popcount(m)
        alive[j] = seen != 0
    return total


@numba.njit(cache=True)
def _window_currents(cells_out, n_out, slot_in, masks_in, s_in, s_out, k, st, w, ch, blk, steps, width,
                     cur) -> None:  # pragma: no cover - compiled
    """The currents of output cells cells_out[:n_out] into cur (steps x width flat, cell j at columns j ch ..):
    the weight rows of the spikes in each window (see _conv_cells), in torch's order per (cell, step); the
    steps are independent sums, interleaved so that their additions overlap. blk > 0: one running sum over the
    input-channel blocks of blk; blk < 0: each block of -blk channels summed from zero on its own, the blocks' sums
    then added to the cell's current in block order."""
    c_in = w.shape[0] // (k * k * ch)
    partial = blk < 0
    b = -blk if partial else blk
    acc = np.zeros(steps * ch if partial else 1, np.float32)  # one block's sums (partial order)
    for t in range(steps):
        cur[t * width:t * width + n_out * ch] = 0
    for j in range(n_out):
        cell = cells_out[j]
        oy, ox = cell // s_out, cell % s_out
        col = j * ch
        for c0 in range(0, c_in, b):
            keep = ((1 << min(b, c_in - c0)) - 1) << c0
            if partial:
                acc[:] = 0
            for ky in range(k):
                for kx in range(k):
                    src = slot_in[(oy * st + ky) * s_in + ox * st + kx]
                    if src < 0:
                        continue
                    base = (ky * k + kx) * c_in
                    for t in range(steps):
                        m = masks_in[src * steps + t] & keep
                        while m:
                            if partial:
                                _add_row(acc, t * ch, w, base + _ctz(m), ch)
                            else:
                                _add_row(cur, t * width + col, w, base + _ctz(m), ch)
                            m &= m - 1
            if partial:
                for t in range(steps):
                    _add_row(cur, t * width + col, acc, t, ch)


@numba.njit(cache=True)
def _conv_cells(cells_in, n_in, slot_in, masks_in, alive_in, s_in, s_out, k, st, w, ch, blk, consts, theta, steps,
                width, cur, fired, state, slot_out, cells_out, masks_out, alive_out) -> int:  # pragma: no cover
    """One spiking convolution, on the output cells whose window holds a spike of the layer below.

    Input: cells_in[:n_in] (map cell indices), slot_in (map cell -> its index j, or -1, for the cells of
    the layer below that fired) and their spikes (masks_in, alive_in; see _spike_masks). w (k k C_in x
    C_out, flat) rows in (kernel row, column, input channel) order. A window's spikes are added per step
    in the order torch sums it: by blocks of blk input channels, within a block by kernel row, column,
    channel (blk >= C_in: one block; blk < 0: blocks of -blk, each its own sum, see _window_currents). Output
    likewise (cells_out, slot_out, masks_out, alive_out);
    returns their number."""
    n_out = 0
    for j in range(n_in):
        cell = cells_in[j]
        if not alive_in[j]:
            slot_in[cell] = -1  # silent: not read below (and left clean)
            continue
        y, x = cell // s_in, cell % s_in
        for oy in range(max(0, -((k - 1 - y) // st)), min(s_out - 1, y // st) + 1):
            for ox in range(max(0, -((k - 1 - x) // st)), min(s_out - 1, x // st) + 1):
                if slot_out[oy * s_out + ox] < 0:
                    slot_out[oy * s_out + ox] = n_out
                    cells_out[n_out] = oy * s_out + ox
                    n_out += 1
    _window_currents(cells_out, n_out, slot_in, masks_in, s_in, s_out, k, st, w, ch, blk, steps, width, cur)
    _clif_flat(cur, width, n_out * ch, steps, consts, theta, fired, state)
    _spike_masks(fired, width, n_out, ch, steps, masks_out, alive_out)
    return n_out


@numba.njit(cache=True)
def conv_layers(ex, ey, occ, tile_start, tiles, geom, half, size, s1, s2, s3, k1, k2, k3, w1, w2, w3, ch1, ch2,
                ch3, st2, st3, blk2, blk3, c1, c2, c3, theta, steps, record, fan0, fan1, fan2, rows3,
                row_of, counts) -> int:  # pragma: no cover - compiled
    """Input and the three spiking convolutions of every candidate (see the module docstring).

    ex, ey, occ (E,): active pixels' centres and their events as bits 2 step + polarity, grouped by sensor
    tile (tile_start: CSR starts; tiles (N, 5): per box the first and last tile column and row to read, and
    the tile columns);
    geom (N, 7) from box_canvas; s1..s3 the conv maps' sizes, k1..k3 their kernels, ch1..ch3 their
    channels; w1, w2, w3 flat (k k C_in x C_out) in (kernel row, column, input channel; polarity for w1)
    x output channel order; blk2, blk3 the input-channel blocks of conv2's and conv3's sums (see _conv_cells);
    c1..c3 (3, cells x C) d_m, d_s, V0 per neuron of a layer's cells side by
    side. Writes conv3's spikes of each (candidate, step) that holds any to a row of rows3 (torch's
    flatten order) and that row's index to row_of[candidate * steps + step]; returns the rows used.
    With record, per candidate and layer (input .. conv3) the spike count and (input .. conv2) the ACs
    they drive (fan0..fan2: fan-out per pixel of the layer's map) go to counts (N, 4, 2).
    """
    cover = s1 * k1  # canvas pixels conv1 reads
    width = max(s1 * s1 * ch1, s2 * s2 * ch2, s3 * s3 * ch3)
    slot1 = np.full(s1 * s1, -1, np.int64)
    slot2 = np.full(s2 * s2, -1, np.int64)
    slot3 = np.full(s3 * s3, -1, np.int64)
    cells1 = np.empty(s1 * s1, np.int64)
    cells2 = np.empty(s2 * s2, np.int64)
    cells3 = np.empty(s3 * s3, np.int64)
    spikes1 = np.empty(s1 * s1 * steps, np.int64)  # per cell and step: its channels that fired, as bits
    spikes2 = np.empty(s2 * s2 * steps, np.int64)
    spikes3 = np.empty(s3 * s3 * steps, np.int64)
    alive1 = np.empty(s1 * s1, np.bool_)
    alive2 = np.empty(s2 * s2, np.bool_)
    alive3 = np.empty(s3 * s3, np.bool_)
    masks1 = np.zeros((s1 * s1, steps), np.int64)  # per touched conv1 cell and step: its input pixels as bits
    stamp = np.zeros(steps * 2 * size * size if record else 1, np.int64)  # dedups input pixels conv1 does not read
    cur = np.zeros(steps * width, np.float32)
    fired = np.zeros(steps * width + 8, np.uint8)  # + 8: _spike_masks reads whole words
    state = np.zeros((3, width), np.float32)
    steps_in = min(steps, 31)  # steps that can hold events (occ's bits); the tail steps stay empty
    pow2 = k1 & (k1 - 1) == 0
    log_k1 = _ctz(k1)
    used = 0  # rows of rows3 filled
    for i in range(geom.shape[0]):
        x0, x1, y0, y1, cx, cy, sc = geom[i, 0], geom[i, 1], geom[i, 2], geom[i, 3], geom[i, 4], geom[i, 5], geom[i, 6]
        n1 = 0
        for ty in range(tiles[i, 2], tiles[i, 3] + 1):
            for e in range(tile_start[ty * tiles[i, 4] + tiles[i, 0]], tile_start[ty * tiles[i, 4] + tiles[i, 1] + 1]):
                fx, fy = ex[e], ey[e]
                if not (fx >= x0 and fx < x1 and fy >= y0 and fy < y1):
                    continue
                u = (fx - cx) * sc + half
                v = (fy - cy) * sc + half
                if u < 0 or v < 0:  # off the canvas; for u, v >= 0 truncation is floor (and needs no libm call)
                    continue
                px, py = int(u), int(v)
                if px >= size or py >= size:
                    continue
                o = occ[e]
                if px < cover and py < cover:
                    if pow2:  # px, py >= 0: shifts and masks (a division by a variable is slow)
                        qx, rx, qy, ry = px >> log_k1, px & (k1 - 1), py >> log_k1, py & (k1 - 1)
                    else:
                        qx, rx, qy, ry = px // k1, px % k1, py // k1, py % k1
                    cell = qy * s1 + qx
                    j = slot1[cell]
                    if j < 0:
                        j = n1
                        slot1[cell] = j
                        cells1[j] = cell
                        masks1[j, :] = 0
                        n1 += 1
                    shift = (ry * k1 + rx) * 2
                    for t in range(steps_in):
                        masks1[j, t] |= ((o >> (2 * t)) & 3) << shift
                elif record:
                    for t in range(steps_in):
                        for p in range(2):
                            if (o >> (2 * t + p)) & 1:
                                idx = ((t * 2 + p) * size + py) * size + px
                                if stamp[idx] != i + 1:  # two sensor pixels can meet on a scaled-down canvas
                                    stamp[idx] = i + 1
                                    counts[i, 0, 0] += 1  # fan-out 0: conv1 does not read it
        # conv1 on the cells that got events: a cell's pixels in (row, column, polarity) order per step
        for t in range(steps):
            cur[t * width:t * width + n1 * ch1] = 0
        for j in range(n1):
            for t in range(steps):
                m = masks1[j, t]
                while m:
                    _add_row(cur, t * width + j * ch1, w1, _ctz(m), ch1)
                    m &= m - 1
        _clif_flat(cur, width, n1 * ch1, steps, c1, theta, fired, state)
        _spike_masks(fired, width, n1, ch1, steps, spikes1, alive1)
        if record:  # before _conv_cells clears the slots of silent cells
            for j in range(n1):
                cell = cells1[j]
                c = 0
                for t in range(steps):
                    c += _popcount(masks1[j, t])
                counts[i, 0, 0] += c
                counts[i, 0, 1] += c * fan0[(cell // s1) * k1 * size + (cell % s1) * k1]
                c = 0
                for t in range(steps):
                    c += _popcount(spikes1[j * steps + t])
                counts[i, 1, 0] += c
                counts[i, 1, 1] += c * fan1[cell]
        n2 = _conv_cells(cells1, n1, slot1, spikes1, alive1, s1, s2, k2, st2, w2, ch2, blk2, c2, theta, steps, width,
                         cur, fired, state, slot2, cells2, spikes2, alive2)
        n3 = _conv_cells(cells2, n2, slot2, spikes2, alive2, s2, s3, k3, st3, w3, ch3, blk3, c3, theta, steps, width,
                         cur, fired, state, slot3, cells3, spikes3, alive3)
        for j in range(n3):
            if not alive3[j]:
                continue
            cell = cells3[j]
            for t in range(steps):
                m = spikes3[j * steps + t]
                if m == 0:
                    continue
                row = row_of[i * steps + t]
                if row < 0:
                    row = used
                    row_of[i * steps + t] = used
                    rows3[row, :] = 0
                    used += 1
                while m:
                    rows3[row, _ctz(m) * s3 * s3 + cell] = 1.0
                    m &= m - 1
        if record:
            for j in range(n2):
                c = 0
                for t in range(steps):
                    c += _popcount(spikes2[j * steps + t])
                counts[i, 2, 0] += c
                counts[i, 2, 1] += c * fan2[cells2[j]]
            c = 0
            for j in range(n3 * steps):
                c += _popcount(spikes3[j])
            counts[i, 3, 0] = c
        # leave the scratch maps clean for the next candidate (silent cells of conv1, conv2 already are)
        for j in range(n1):
            slot1[cells1[j]] = -1
        for j in range(n2):
            slot2[cells2[j]] = -1
        for j in range(n3):
            slot3[cells3[j]] = -1
    return used


def window_currents(spikes: np.ndarray, weight: np.ndarray, stride: int, blk: int) -> np.ndarray:
    """A convolution of binary spikes (T, C_in, H, W) with weight (C_out, C_in, k, k), no bias, summed as the
    event-driven path sums it (input-channel blocks of blk; blk < 0: each block its own sum, see _window_currents):
    currents (T, C_out, H', W') float32."""
    steps, c_in, size, _ = spikes.shape
    c_out, k = weight.shape[0], weight.shape[2]
    out = (size - k) // stride + 1
    on = np.ascontiguousarray(spikes.transpose(2, 3, 0, 1)) != 0  # (H, W, T, C_in)
    masks = (on.astype(np.int64) << np.arange(c_in, dtype=np.int64)).sum(axis=3).reshape(-1)  # per cell, step
    width = out * out * c_out
    cur = np.zeros(steps * width, np.float32)
    w = np.ascontiguousarray(weight.transpose(2, 3, 1, 0).reshape(-1), np.float32)
    _window_currents(np.arange(out * out, dtype=np.int64), out * out, np.arange(size * size, dtype=np.int64), masks,
                     size, out, k, stride, w, c_out, blk, steps, width, cur)
    return cur.reshape(steps, out, out, c_out).transpose(0, 3, 1, 2)
