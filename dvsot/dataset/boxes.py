"""Box geometry in pixels (xywh, top-left corner and size): IoU, boxes fitted to binary masks, and the check of
the boxes a file or a recording holds."""

from __future__ import annotations

import numpy as np

from dvsot.core.bounds import MIN_BOX_SIDE_PX


def iou_xywh(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Intersection over union of xywh boxes (pixels), broadcasting over leading axes; NaN boxes give 0."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    ax0, ay0, aw, ah = a[..., 0], a[..., 1], a[..., 2], a[..., 3]
    bx0, by0, bw, bh = b[..., 0], b[..., 1], b[..., 2], b[..., 3]
    iw = np.clip(np.minimum(ax0 + aw, bx0 + bw) - np.maximum(ax0, bx0), 0.0, None)
    ih = np.clip(np.minimum(ay0 + ah, by0 + bh) - np.maximum(ay0, by0), 0.0, None)
    inter = iw * ih
    union = np.clip(aw, 0, None) * np.clip(ah, 0, None) + np.clip(bw, 0, None) * np.clip(bh, 0, None) - inter
    with np.errstate(invalid="ignore", divide="ignore"):
        out = np.where(union > 0, inter / union, 0.0)
    return np.nan_to_num(out, nan=0.0)


def interpolate_boxes(t_samples: np.ndarray, xywh: np.ndarray, t_query: np.ndarray) -> np.ndarray:
    """Boxes (pixels) at query times (us), linear per coordinate between samples; NaN if a neighbour is NaN or outside
    the track."""
    ts = np.asarray(t_samples, dtype=np.float64)
    boxes = np.asarray(xywh, dtype=np.float64).reshape(-1, 4)
    tq = np.atleast_1d(np.asarray(t_query, dtype=np.float64))
    out = np.full((tq.size, 4), np.nan)
    if ts.size == 0:
        return out
    hi = np.searchsorted(ts, tq, side="left")  # first sample with t >= query
    inside = (tq >= ts[0]) & (tq <= ts[-1])
    hi = np.clip(hi, 0, ts.size - 1)
    lo = np.where(ts[hi] == tq, hi, np.maximum(hi - 1, 0))
    span = ts[hi] - ts[lo]
    w = np.divide(tq - ts[lo], span, out=np.zeros_like(tq), where=span > 0)[:, None]
    # NaN in either neighbour propagates through the blend, as it should (target out of view).
    blend = boxes[lo] * (1.0 - w) + boxes[hi] * w
    exact = (span == 0)[:, None]
    blend = np.where(exact, boxes[lo], blend)
    out[inside] = blend[inside]
    return out


def mask_visibility(amodal: np.ndarray, visible: np.ndarray) -> float:
    """Visible target pixels over amodal target pixels (both on the sensor), clipped to 0..1; 0 where there are none.

    The amodal mask is rasterised at pixel centres, the visible one comes from the render's index pass, whose
    pixel filter may place a visible pixel just outside it: the ratio is clipped, not a count of the overlap.
    """
    n_amodal = int(np.count_nonzero(amodal))
    return min(1.0, int(np.count_nonzero(visible)) / n_amodal) if n_amodal else 0.0


def box_from_mask(mask: np.ndarray, threshold: float = 0.5) -> np.ndarray:
    """The upright rectangle circumscribing every contour of mask > threshold, xywh float32 pixels; NaN if empty."""
    import cv2

    m = np.asarray(mask)
    if m.ndim == 3 and m.shape[2] == 1:
        m = m[:, :, 0]
    if m.ndim != 2:
        raise ValueError(f"box_from_mask needs a 2-D mask (alpha), got shape {m.shape}")
    binary = (m > threshold).astype(np.uint8)  # NaN alpha compares False: background
    # RETR_EXTERNAL: holes do not matter for the circumscribed rectangle; all outer contours do, so a
    # target split by an occluder (or made of several parts) still gets one amodal box.
    contours, _ = cv2.findContours(binary, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    if not contours:
        return np.full(4, np.nan, np.float32)
    x, y, w, h = cv2.boundingRect(np.concatenate(contours))
    return np.array([x, y, w, h], np.float32)


def clip_box(xywh: np.ndarray, width: int, height: int) -> np.ndarray:
    """The part of box(es) (..., 4) xywh inside a width x height image, float32 pixels; NaN where nothing remains."""
    b = np.asarray(xywh, dtype=np.float32)
    x0, y0 = np.clip(b[..., 0], 0, width), np.clip(b[..., 1], 0, height)
    x1, y1 = np.clip(b[..., 0] + b[..., 2], 0, width), np.clip(b[..., 1] + b[..., 3], 0, height)
    out = np.stack([x0, y0, x1 - x0, y1 - y0], axis=-1).astype(np.float32)
    empty = ~((x1 > x0) & (y1 > y0))  # also True for NaN input
    out[empty] = np.nan
    return out


def match_annotations(t_annotations: np.ndarray, segment_us: int, num_segments: int) -> np.ndarray:
    """Per segment, the row of the annotation it is scored against, or -1: the nearest one within segment_us / 2.

    Segment i ends at (i + 1) * segment_us (microseconds). An annotation at time t belongs to the segment
    whose end is nearest to it (a tie goes to the later end), if that end lies within half a segment;
    when two annotations land on one segment the nearer one wins (the earlier on a tie). Nothing is
    interpolated: a matched segment's ground truth is that annotation's box as written.
    """
    t = np.asarray(t_annotations, np.int64)
    seg = (2 * t + segment_us) // (2 * segment_us) - 1  # round(t / segment_us) - 1, ties to the later end
    dist = np.abs((seg + 1) * segment_us - t)
    ok = (seg >= 0) & (seg < num_segments) & (2 * dist <= segment_us)
    rows = np.flatnonzero(ok)
    # nearest first, then earliest: the first row written for each segment after this sort wins
    order = rows[np.lexsort((rows, dist[rows]))]
    out = np.full(num_segments, -1, np.int64)
    segs, first = np.unique(seg[order], return_index=True)
    out[segs] = order[first]
    return out


def box_problem(xywh: np.ndarray, width: int, height: int, row_name=lambda i: f"row {i}") -> str | None:
    """What is wrong with (N, 4) boxes (xywh pixels) on a width x height sensor, or None.

    A box is four NaNs (no target) or finite with w, h >= MIN_BOX_SIDE_PX, inside the sensor widened by its
    own size on every side ([-width, 2 width] x [-height, 2 height]): further out, nothing of it can be seen.
    """
    b = np.asarray(xywh, np.float64).reshape(-1, 4)
    absent = np.isnan(b).all(axis=1)
    with np.errstate(invalid="ignore"):
        bad = ~absent & (~np.isfinite(b).all(axis=1) | (b[:, 2] < MIN_BOX_SIDE_PX) | (b[:, 3] < MIN_BOX_SIDE_PX)
                         | (b[:, 0] < -width) | (b[:, 1] < -height)
                         | (b[:, 0] + b[:, 2] > 2 * width) | (b[:, 1] + b[:, 3] > 2 * height))
    if not bad.any():
        return None
    i = int(np.flatnonzero(bad)[0])
    x, y, w, h = (f"{v:g}" for v in b[i])
    return (f"{row_name(i)} is x={x} y={y} w={w} h={h}; a box is finite with w, h >= {MIN_BOX_SIDE_PX:g} px and inside "
            f"[{-width}, {2 * width}] x [{-height}, {2 * height}] px (the {width}x{height} sensor and its own size "
            f"around it), or four NaNs for no target")


def truncation_share(on_sensor_px: float, whole_px: float) -> float:
    """The share (0..1) of a silhouette's area (pixels) that lies off the sensor; 1 where it has none (nothing of it
    in front of the camera, or too small to cover a pixel centre)."""
    if whole_px <= 0:
        return 1.0
    return float(min(1.0, max(0.0, 1.0 - on_sensor_px / whole_px)))


def label_boxes(index_image: np.ndarray, ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(boxes (K, 4) float32 xywh pixels, counts (K,) int64): the upright box around each id's pixels in an object
    index image (u1, height x width) and its pixel count; a NaN box where an id has no pixel.

    The box is box_from_mask's of the id's mask (every pixel's bounding rectangle), for every id in one pass.
    """
    img = np.asarray(index_image)
    H, W = img.shape
    ids = np.asarray(ids, np.int64)
    flat = img.astype(np.intp, copy=False)
    counts = np.bincount(flat.ravel(), minlength=256)
    cols = np.zeros((256, W), bool)
    rows = np.zeros((256, H), bool)
    cols[flat, np.arange(W)[None, :]] = True
    rows[flat, np.arange(H)[:, None]] = True
    c, r = cols[ids], rows[ids]
    found = c.any(axis=1)
    x0, x1 = c.argmax(axis=1), W - 1 - c[:, ::-1].argmax(axis=1)
    y0, y1 = r.argmax(axis=1), H - 1 - r[:, ::-1].argmax(axis=1)
    boxes = np.stack([x0, y0, x1 - x0 + 1, y1 - y0 + 1], axis=1).astype(np.float32)
    boxes[~found] = np.nan
    return boxes, counts[ids].astype(np.int64)


def object_rows(index_image: np.ndarray, ids: np.ndarray,
                amodal: dict[int, tuple[np.ndarray, float, float]]) -> dict[str, np.ndarray]:
    """Every object's ground truth at one sample, one row per id of the object table (ids (K,)), as /objects stores it.

    index_image: the render's object index pass (u1 height x width, occluders kept); amodal: per id with geometry,
    (its amodal mask on the sensor (bool height x width), its silhouette's area on the sensor and in all (pixels,
    dvsot.render.raster.silhouette_coverage)). Returns boxes_amodal, boxes_visible (K, 4) float32 xywh pixels (NaN =
    none), px_amodal, px_visible (K,) uint32, visibility (K,) float32 (as mask_visibility: visible over amodal pixels
    on the sensor, 0 where none) and truncation (K,) float32 (truncation_share); ids without geometry (background,
    noise) get NaN amodal boxes, visibility and truncation, and px_amodal 0.
    """
    ids = np.asarray(ids, np.int64)
    boxes_visible, px_visible = label_boxes(index_image, ids)
    k = len(ids)
    boxes_amodal = np.full((k, 4), np.nan, np.float32)
    px_amodal = np.zeros(k, np.uint32)
    visibility = np.full(k, np.nan, np.float32)
    truncation = np.full(k, np.nan, np.float32)
    for j, i in enumerate(ids):
        if int(i) not in amodal:
            continue
        mask, on, whole = amodal[int(i)]
        n = int(np.count_nonzero(mask))
        boxes_amodal[j] = box_from_mask(mask)
        px_amodal[j] = n
        visibility[j] = min(1.0, px_visible[j] / n) if n else 0.0
        truncation[j] = truncation_share(on, whole)
    return {"boxes_amodal": boxes_amodal, "boxes_visible": boxes_visible, "px_amodal": px_amodal,
            "px_visible": px_visible.astype(np.uint32), "visibility": visibility, "truncation": truncation}
