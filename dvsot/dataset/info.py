"""What a dataset file holds: resolution, duration, events, rate, each object's share, segments, box coverage,
parameters (`dvsot info`)."""

from __future__ import annotations

import os

import numpy as np

from dvsot.dataset import Dataset
from dvsot.events.batch import NOISE_KINDS


def dataset_info(path: str | os.PathLike) -> dict:
    """A dict summary of one dataset file (times in seconds, sizes in pixels); every event is read and checked."""
    with Dataset(path) as ds:
        n_pos, n_noise, has_signal = 0, 0, False
        kinds = None  # events of each noise kind, when the file has /events/noise_kind
        # chunked (files may hold hundreds of millions of events), and every chunk is checked on the way:
        # info is where a damaged file should show up, so it reads all of it
        for batch in ds.chunks():
            n_pos += int(np.count_nonzero(batch.p))
            if batch.signal is not None:
                has_signal = True
                n_noise += int(np.count_nonzero(~batch.signal))
            if batch.noise_kind is not None:
                counts = np.bincount(batch.noise_kind, minlength=len(NOISE_KINDS))
                kinds = counts if kinds is None else kinds + counts
        n_noise = n_noise if has_signal else None
        ds.verify_masks()
        seg = ds.segment_boxes()
        have = ~np.isnan(seg).any(axis=1)
        duration = ds.duration_us / 1e6
        out = {
            "file": str(ds.path), "name": ds.name, "split": ds.split, "format_version": ds.format_version,
            "resolution": [ds.width, ds.height], "duration_s": duration, "events": ds.num_events,
            "event_rate_per_s": ds.num_events / duration if duration else 0.0,
            "positive_fraction": n_pos / ds.num_events if ds.num_events else None,
            "noise_events": n_noise, "segment_ms": ds.segment_us / 1000, "segments": ds.num_segments,
            "segments_with_box": int(have.sum()),
            "box_coverage": float(have.mean()) if ds.num_segments else 0.0,
            "box_samples": int(len(ds.boxes().t)),
            "t_offset_us": ds.t_offset_us,
            "ground_truth": "annotations" if ds.annotated else "rendered",
        }
        counts = ds.object_counts()
        if counts is not None:  # per-event labels (dvsot.events.labels): each object's share of the events
            out["objects"] = [dict(row, events=counts[row["id"]],
                                   share=counts[row["id"]] / ds.num_events if ds.num_events else 0.0)
                              for row in ds.objects]
        absent = ds.segment_absent()
        if absent is not None:  # rendered: how much of the target is seen (docs/dataset-files.md)
            vis = ds.segment_visibility()
            out["segments_absent"] = int(absent.sum())
            out["visibility_median"] = float(np.nanmedian(vis)) if np.isfinite(vis).any() else None
        trunc = ds.segment_truncation()
        if trunc is not None:  # the share of the target off the sensor (docs/dataset-files.md)
            out["segments_truncated"] = int(np.count_nonzero(trunc > 0))
        if ds.has_masks:
            out["mask_samples"] = int(len(ds.boxes().t))
        if ds.object_track() is not None:
            out["per_object_truth"] = True
        if ds.annotated:  # a recording: segments scored against an annotation (docs/benchmarks.md)
            out["segments_matched_to_annotation"] = int(ds.segment_scored().sum())
        if have.any():
            w, h = seg[have, 2], seg[have, 3]
            out["box_width_px"] = [float(w.min()), float(np.median(w)), float(w.max())]
            out["box_height_px"] = [float(h.min()), float(np.median(h)), float(h.max())]
        if kinds is not None:
            out["noise_events_by_kind"] = {k: int(n) for k, n in zip(NOISE_KINDS[1:], kinds[1:])}
        for key in ("sensor_counts", "simulator", "seed", "generator", "versions"):
            if key in ds.attrs:
                out[key] = ds.attrs[key]
    return out
