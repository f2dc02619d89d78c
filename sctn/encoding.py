"""Events of a segment -> SCTN input: T one-millisecond steps x 2 polarities on a 107 x 107 canvas per box.

For each box, the canvas is centred on the box centre at the sensor's own scale, and only events
inside the box are placed on it (the paper: "for bounding boxes smaller than 107 x 107, only the
neurons corresponding to the events within the bounding box will emit spikes"). A box larger than
the canvas is scaled down by size / max(w, h) (aspect kept), so several events may land on one
canvas pixel; a pixel spikes once per step however many events it got. Channel 0 is OFF, 1 is ON.
"""

from __future__ import annotations

import numpy as np
import torch

from dvsot.events import EventBatch
from sctn.network import NetworkConfig

PRESET = NetworkConfig()  # the paper's canvas and time steps, when no network config is given


def encode_boxes(events: EventBatch, t0_us: int, boxes_xywh: np.ndarray, cfg: NetworkConfig = PRESET) -> torch.Tensor:
    """Binary input tensor (N, steps, 2, size, size) float32 for N boxes (xywh pixels) of one segment; the canvas
    size, steps and step length (us) are the network config's."""
    size, steps, step_us = cfg.input_size, cfg.steps, cfg.step_us
    boxes = np.asarray(boxes_xywh, np.float32).reshape(-1, 4)
    n = len(boxes)
    out = torch.zeros((n, steps, 2, size, size), dtype=torch.float32)
    if n == 0 or len(events) == 0:
        return out
    step = (np.asarray(events.t, np.int64) - int(t0_us)) // step_us
    keep = (step >= 0) & (step < steps)
    ex = events.x[keep].astype(np.float32) + 0.5  # pixel centres
    ey = events.y[keep].astype(np.float32) + 0.5
    ep = events.p[keep].astype(np.int64)
    es = step[keep]
    if ex.size == 0:
        return out
    x0, x1, y0, y1, cx, cy, scale = box_canvas(boxes, size).T[:, :, None]
    inside = (ex >= x0) & (ex < x1) & (ey >= y0) & (ey < y1)  # (N, E)
    bi, ei = np.nonzero(inside)
    if bi.size == 0:
        return out
    cx, cy, scale = cx[:, 0], cy[:, 0], scale[:, 0]
    u = np.floor((ex[ei] - cx[bi]) * scale[bi] + np.float32(size / 2)).astype(np.int64)
    v = np.floor((ey[ei] - cy[bi]) * scale[bi] + np.float32(size / 2)).astype(np.int64)
    ok = (u >= 0) & (u < size) & (v >= 0) & (v < size)
    flat = (((bi[ok] * steps + es[ei][ok]) * 2 + ep[ei][ok]) * size + v[ok]) * size + u[ok]
    out.view(-1).index_fill_(0, torch.from_numpy(flat), 1.0)  # repeats set the same 1
    return out


def box_canvas(boxes_xywh: np.ndarray, size: int = 107) -> np.ndarray:
    """Per box (N, 7) float32: left, right, top, bottom edge and centre x, y (pixels), canvas scale (canvas px
    per px). An event (pixel centre ex, ey) is inside when left <= ex < right and top <= ey < bottom, and lands
    on canvas pixel floor((ex - centre) * scale + size / 2); every step rounds to float32 (sctn.sparse.evaluate
    repeats this arithmetic)."""
    boxes = np.asarray(boxes_xywh, np.float32).reshape(-1, 4)
    scale = np.minimum(np.float32(1.0), np.float32(size) / np.maximum(boxes[:, 2], boxes[:, 3]))
    half = np.float32(2.0)
    return np.stack([boxes[:, 0], boxes[:, 0] + boxes[:, 2], boxes[:, 1], boxes[:, 1] + boxes[:, 3],
                     boxes[:, 0] + boxes[:, 2] / half, boxes[:, 1] + boxes[:, 3] / half, scale], axis=1)


def encode_region(events: EventBatch, t0_us: int, region_xywh: np.ndarray, scale: float, size_hw: tuple[int, int],
                  cfg: NetworkConfig = PRESET) -> torch.Tensor:
    """Binary input (1, steps + tail_steps, 2, H, W) of every event inside a sensor region, scaled by `scale`
    (canvas px per px); the tail steps stay empty; steps, step length (us) and tail steps are the config's."""
    steps, step_us, tail_steps = cfg.steps, cfg.step_us, cfg.tail_steps
    hgt, wid = size_hw
    out = torch.zeros((1, steps + tail_steps, 2, hgt, wid), dtype=torch.float32)
    if len(events) == 0:
        return out
    step = (np.asarray(events.t, np.int64) - int(t0_us)) // step_us
    rx, ry = float(region_xywh[0]), float(region_xywh[1])
    u = np.floor((events.x.astype(np.float32) + 0.5 - rx) * scale).astype(np.int64)
    v = np.floor((events.y.astype(np.float32) + 0.5 - ry) * scale).astype(np.int64)
    ok = (step >= 0) & (step < steps) & (u >= 0) & (u < wid) & (v >= 0) & (v < hgt)
    flat = ((step[ok] * 2 + events.p[ok].astype(np.int64)) * hgt + v[ok]) * wid + u[ok]
    out.view(-1).index_fill_(0, torch.from_numpy(flat), 1.0)  # repeats set the same 1: no unique (a sort) needed
    return out


def encode_search(events: EventBatch, t0_us: int, boxes_xywh: np.ndarray, ref_box_xywh: np.ndarray,
                  cfg: NetworkConfig = PRESET) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Fast-mode input: one region for all candidates, at the reference box's canvas scale.

    The network config gives the canvas size, the steps and conv3's receptive field (total stride,
    receptive-field size: NetworkConfig.receptive_field). Returns the region's input spikes
    (1, steps + tail_steps, 2, H, W), each candidate canvas's top-left corner in region pixels (N, 2) and each
    candidate box in region pixels (N, 4). The region covers what the cells kept by some candidate see (a cell is
    kept when its receptive field's centre lies in the box): the candidate boxes plus half a receptive field, not
    the whole canvases. Its corner lies on one lattice of the total stride (the sensor lattice at scale 1,
    moved by whole cells), so every candidate shares one convolution grid.
    """
    stride, rf = cfg.receptive_field()
    size = cfg.input_size
    boxes = np.asarray(boxes_xywh, np.float64).reshape(-1, 4)
    scale = min(1.0, size / float(max(ref_box_xywh[2], ref_box_xywh[3])))
    centres = boxes[:, :2] + boxes[:, 2:] / 2
    half = size / 2 / scale  # sensor px from a canvas centre to its edge
    corner = np.floor((centres.min(axis=0) - half) / stride) * stride  # all canvases' top-left, on the lattice
    # whole cells of that region that no kept cell sees are dropped (region px = sensor px x scale)
    # (one cell more on each side: a bilinear crop also reads the neighbouring cell)
    skip = np.maximum(0.0, np.floor(((boxes[:, :2] - corner).min(axis=0) * scale - rf / 2 - stride) / stride))
    corner = corner + skip * stride / scale
    far = (boxes[:, :2] + boxes[:, 2:] - corner).max(axis=0) * scale + rf / 2 + stride
    wid, hgt = (int(np.ceil(v)) + stride for v in far)
    region = encode_region(events, t0_us, corner, scale, (hgt, wid), cfg)
    origins = ((centres - corner) * scale - size / 2).astype(np.float32)
    rboxes = np.concatenate([(boxes[:, :2] - corner) * scale, boxes[:, 2:] * scale], axis=1).astype(np.float32)
    return region, torch.from_numpy(origins), torch.from_numpy(rboxes)
