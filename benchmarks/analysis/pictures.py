"""Pictures of a benchmark run: IoU over time per sequence and tracker.

`plot_iou_over_time` takes the simplest form of the per-segment results: {tracker: {sequence: IoU
array}}, one value per segment, NaN for segments that do not count (initialisation segments, segments
without ground truth). Tracking videos (event frames with the
ground-truth and predicted boxes) are `dvsot.dataset.preview.write_preview`, which `dvsot bench --video` calls.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from benchmarks.evaluation.metrics import FAILURE_IOU  # the protocol's failure threshold, drawn as a reference line
from benchmarks.evaluation.safe_names import plot_text  # names are free text: no mathtext, one line
from dvsot.core.defaults import SEGMENT_US


def plot_iou_over_time(results: Mapping[str, Mapping[str, np.ndarray]], out_png: str | os.PathLike,
                       segment_ms: float = SEGMENT_US / 1000, sequences: list[str] | None = None,
                       title: str | None = None) -> Path:
    """Write a PNG with one panel per sequence: IoU per segment (time in s) for each tracker; returns the path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    trackers = list(results)
    if sequences is None:
        sequences = []
        for per_seq in results.values():
            sequences.extend(name for name in per_seq if name not in sequences)
    if not trackers or not sequences:
        raise ValueError("plot_iou_over_time: no trackers or no sequences to plot")
    out = Path(out_png)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig, axes = plt.subplots(len(sequences), 1, figsize=(10, 2.2 * len(sequences) + 0.6), squeeze=False,
                             sharex=False)
    colors = plt.get_cmap("tab10")
    for row, seq in enumerate(sequences):
        ax = axes[row, 0]
        for k, name in enumerate(trackers):
            iou = results[name].get(seq)
            if iou is None:
                continue
            iou = np.asarray(iou, dtype=float).reshape(-1)
            t_s = (np.arange(len(iou)) + 1) * segment_ms / 1000.0   # a segment's IoU belongs to its end time
            counted = np.isfinite(iou)
            mean = float(np.mean(iou[counted])) if counted.any() else float("nan")
            # NaN breaks the line, so uncounted segments show as gaps
            ax.plot(t_s, iou, lw=1.0, color=colors(k % 10), label=f"{plot_text(name)} (mean {mean:.3f})")
            fails = counted & (iou < FAILURE_IOU)
            ax.plot(t_s[fails], iou[fails], "x", ms=3, color=colors(k % 10))
        ax.axhline(FAILURE_IOU, color="grey", lw=0.8, ls="--")
        ax.set_ylim(-0.02, 1.02)
        ax.set_ylabel("IoU")
        ax.set_title(plot_text(seq), fontsize=10, loc="left")
        ax.legend(fontsize=8, loc="lower right", ncol=min(4, len(trackers)))
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel("time (s); x = failure (IoU < 0.5), gaps = segments that do not count")
    if title:
        fig.suptitle(plot_text(title))
    fig.tight_layout()
    save_figure(fig, out, dpi=110)
    return out


def save_figure(fig, out_png: str | os.PathLike, dpi: int, bbox_inches: str | None = None) -> Path:
    """Save a figure as PNG (dpi dots per inch; bbox_inches "tight" crops it to what is drawn) via a temp file and
    a rename (a picture is never half-written); closes the figure."""
    import matplotlib.pyplot as plt

    from dvsot.runtime.outputs import replacing

    try:
        with replacing(out_png) as tmp:
            fig.savefig(tmp, dpi=dpi, format="png", bbox_inches=bbox_inches)
    finally:
        plt.close(fig)
    return Path(out_png)


def plot_segment_side_by_side(files: Mapping[str, str | os.PathLike], segment: int, out_png: str | os.PathLike,
                              background: str = "white", title: str | None = None) -> Path:
    """Write a PNG with one panel per dataset file: the events of one segment (ON red, OFF blue, the pixel's
    last event) with its ground-truth box (green), titled with the label, the events and the segment's span in
    ms; the files must share the sensor size. Returns the path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from dvsot.dataset import Dataset
    from dvsot.dataset.preview import GT_COLOUR, draw_box, event_frame

    if not files:
        raise ValueError("plot_segment_side_by_side: no files to draw")
    panels, size = [], None
    for label, path in files.items():
        with Dataset(path) as ds:
            if size is not None and (ds.width, ds.height) != size:
                raise ValueError(f"{path}: {ds.width}x{ds.height} sensor, but the first file's is {size[0]}x{size[1]}")
            size = (ds.width, ds.height)
            if not 0 <= segment < ds.num_segments:
                raise ValueError(f"{path}: segment {segment} out of range 0..{ds.num_segments - 1}")
            seg = ds.segment(segment)
        img = event_frame(seg.events, size[0], size[1], background)
        draw_box(img, seg.box, GT_COLOUR)
        on = int(np.count_nonzero(seg.events.p > 0)) if len(seg.events) else 0
        panels.append((label, img, len(seg.events), on, seg.t0_us, seg.t1_us))
    width, height = size
    fig, axes = plt.subplots(1, len(panels), figsize=(3.6 * len(panels), 3.6 * height / width + 0.7), squeeze=False)
    for ax, (label, img, n, on, t0, t1) in zip(axes[0], panels):
        ax.imshow(img, interpolation="nearest")
        ax.set_title(f"{plot_text(label)}: {n:,} events ({on:,} ON)\n{t0 / 1000:g}-{t1 / 1000:g} ms", fontsize=9)
        ax.set_xticks([])
        ax.set_yticks([])
    if title:
        fig.suptitle(plot_text(title), fontsize=10)
    fig.tight_layout()
    Path(out_png).parent.mkdir(parents=True, exist_ok=True)
    return save_figure(fig, out_png, dpi=110)
