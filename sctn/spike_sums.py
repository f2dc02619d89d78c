"""Event-driven weighted sums of binary spike maps: fc1 of SCTN's fast search without a dense product.

conv3's spike map is sparse (a small fraction of its entries spike in a step), and fc1 reads a masked
window of it per candidate crop. Instead of gathering every crop's window (mostly zeros) and
multiplying it densely, each crop adds up fc1's weight columns of the cells that spiked: only
additions, as many as the crop's spikes times fc1's width, which is how an SNN's synaptic
operations are meant to run. The sums equal the dense product up to the order of the additions
(float32 rounding).
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def _spike_lists(spikes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:  # pragma: no cover - compiled
    """CSR lists of spiking channels per (step, row, col) of a binary (T, H, W, C) map: (start (T*H*W+1,), channels)."""
    t, h, w, c = spikes.shape
    flat = spikes.reshape(t * h * w, c)
    start = np.zeros(t * h * w + 1, np.int64)
    for i in range(t * h * w):
        n = 0
        for ch in range(c):
            n += flat[i, ch] != 0
        start[i + 1] = start[i] + n
    channels = np.empty(start[-1], np.int64)
    for i in range(t * h * w):
        k = start[i]
        for ch in range(c):
            if flat[i, ch] != 0:
                channels[k] = ch
                k += 1
    return start, channels


@numba.njit(cache=True, fastmath=True)
def _window_sums(start: np.ndarray, channels: np.ndarray, shape: np.ndarray, weights: np.ndarray,
                 crops: np.ndarray, out: np.ndarray) -> None:  # pragma: no cover - compiled
    """out[s, u] = sum of weights[r, q, ch] over spikes (s, y0 + r, x0 + q, ch) inside crop u's kept window.

    crops (U, 6) int64: x0, y0 (the crop's first cell in the map), first kept column, kept columns,
    first kept row, kept rows; cells outside the map read as silent. A local accumulator (not a view
    of out) lets the width loop vectorise.
    """
    t, h, w = shape[0], shape[1], shape[2]
    width = weights.shape[3]
    acc = np.zeros(width, np.float32)
    for u in range(crops.shape[0]):
        x0, y0, sx, nx, sy, ny = crops[u, 0], crops[u, 1], crops[u, 2], crops[u, 3], crops[u, 4], crops[u, 5]
        r0, r1 = max(sy, -y0), min(sy + ny, h - y0)  # the kept rows and columns that lie on the map
        q0, q1 = max(sx, -x0), min(sx + nx, w - x0)
        for s in range(t):
            acc[:] = 0.0
            for r in range(r0, r1):
                row = (s * h + y0 + r) * w + x0
                for q in range(q0, q1):
                    for k in range(start[row + q], start[row + q + 1]):
                        ch = channels[k]
                        for o in range(width):
                            acc[o] += weights[r, q, ch, o]
            out[s, u, :] = acc


def window_sums(spikes: np.ndarray, weights: np.ndarray, crops: np.ndarray) -> np.ndarray:
    """Weighted spike counts (T, U, width) float32 of U masked crop windows of a binary map (T, H, W, C).

    weights (cells, cells, C, width) float32: the weight of each (row, col, channel) of a crop for each
    output; crops (U, 6) int64 as in _window_sums (position, then the kept interval per axis, in cells).
    """
    t = spikes.shape[0]
    start, channels = _spike_lists(np.ascontiguousarray(spikes, np.uint8))
    out = np.zeros((t, len(crops), weights.shape[3]), np.float32)
    if len(crops) and len(channels):
        _window_sums(start, channels, np.array(spikes.shape[:3], np.int64), np.ascontiguousarray(weights, np.float32),
                     np.ascontiguousarray(crops, np.int64), out)
    return out


@numba.njit(cache=True)
def _mix(sums: np.ndarray, slots: np.ndarray, weights: np.ndarray, out: np.ndarray) -> None:  # pragma: no cover
    """out[s, n] = sum over k of weights[n, k] * sums[s, slots[n, k]], skipping zero weights."""
    for s in range(sums.shape[0]):
        for n in range(slots.shape[0]):
            acc = out[s, n]
            for k in range(slots.shape[1]):
                wk = weights[n, k]
                if wk != 0.0:
                    src = sums[s, slots[n, k]]
                    for o in range(acc.shape[0]):
                        acc[o] += wk * src[o]


def mix_corners(sums: np.ndarray, slots: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """Bilinear mix (T, N, width) float32 of the sums (T, U, width) of each candidate's corner crops
    (slots (N, K) indices into U, weights (N, K), zero for a corner not read)."""
    out = np.zeros((sums.shape[0], slots.shape[0], sums.shape[2]), np.float32)
    _mix(np.ascontiguousarray(sums, np.float32), np.ascontiguousarray(slots, np.int64),
         np.ascontiguousarray(weights, np.float32), out)
    return out
