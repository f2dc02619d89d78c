"""A benchmark run's outputs in one directory: tables, per-sequence files, pictures, videos, energy table, manifest.

Everything is written as temp files renamed into place together, then the manifest (run.json: the
run's id and each file's SHA-256, dvsot.runtime.outputs), so an interrupted run never leaves a table
half-written, nor new tables beside old pictures. The directory holds one run's files: the files of the
previous run there that this one does not write go in the same commit.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from benchmarks.evaluation.protocol import SequenceResult

MANIFEST = "run.json"  # written last: the run's id and each output's size and SHA-256 (dvsot.runtime.outputs)
VIDEO_SEGMENTS = 300  # frames of a video preview, one per segment
OPE_FILES = ("ope.json", "ope.md", "success_plot.png", "precision_plot.png")
ATTRIBUTE_FILES = ("attributes.md", "attributes.json", "attributes.png")  # attribute_tables.write_attributes


def video_name(sequence: str) -> str:
    """The report's file for a sequence's video: the name made safe as a file name (no '/', '..', control chars)."""
    from benchmarks.evaluation.safe_names import file_stem

    return file_stem(sequence) + ".gif"


def report_files(protocol: str = "ar", plots: bool = False, videos: Sequence[str] = (),
                 energy: bool = False, scale_plot: bool = False) -> dict[str, str]:
    """{file name in the report directory: what asks for it ('tables', 'manifest', 'plots', 'video', 'energy')};
    scale_plot: a streaming run's plot of score against latency scale (scaled latencies ran)."""
    from benchmarks.analysis.tables import TABLE_FILES

    if protocol == "stream":
        from benchmarks.analysis.stream_tables import SCALE_PLOT, STREAM_FILES

        names = {n: "tables" for n in (*STREAM_FILES, *((SCALE_PLOT,) if scale_plot else ()))}
    else:
        names = {n: "tables" for n in (*(OPE_FILES if protocol == "ope" else TABLE_FILES.values()), *ATTRIBUTE_FILES)}
    names[MANIFEST] = "manifest"
    if plots:
        names["iou_over_time.png"] = "plots"
    for seq in videos:
        names[video_name(seq)] = "video"
    if energy:
        names["energy.json"] = names["firing_rate.png"] = "energy"
    return names


def write_report(out_dir: str | Path, summary, results: list[SequenceResult], *, protocol: str = "ar",
                 plots: bool = False, videos: Mapping[str, str | Path] | None = None,
                 energy: dict | None = None) -> dict[str, Path | str]:
    """Write a run's report into out_dir, all files together, then the manifest; the paths by kind.

    summary: `summarise(results)` (protocol "ar"), `summarise_ope(results)` ("ope") or `summarise_stream(results)`
    ("stream": its tables, call files and plots, no attributes or videos); videos:
    {sequence: its dataset file} for a GIF of event frames with every tracker's boxes; energy: the
    energy table (benchmarks.analysis.energy_table.energy_table) or None.
    """
    from dvsot.runtime.outputs import run_outputs

    out = Path(out_dir)
    # all files of the run renamed into place together, or none; the previous run's other files removed with them
    with run_outputs(out / MANIFEST, whole=True) as run:
        paths = _write_all(out, summary, results, protocol, plots, dict(videos or {}), energy)
    paths["manifest"] = run.manifest
    return paths


def _write_all(out: Path, summary, results: list[SequenceResult], protocol: str, plots: bool,
               videos: dict[str, str | Path], energy: dict | None) -> dict[str, Path | str]:
    from benchmarks.analysis.sequence_files import write_sequence_files
    from benchmarks.analysis.tables import write_tables, write_text_atomic

    if protocol == "stream":
        return _write_stream(out, summary, results, plots, energy)
    if protocol == "ope":
        from benchmarks.analysis.ope_tables import write_ope

        paths: dict[str, Path | str] = {f"ope:{x.name}": x for x in write_ope(summary, out)}
    else:
        paths = dict(write_tables(summary, out))
    from benchmarks.analysis.attribute_tables import write_attributes

    paths.update({f"attributes:{x.name}": x for x in write_attributes(results, out, protocol)})
    files = write_sequence_files(results, out, vot=protocol != "ope")
    if files:
        paths["per-sequence"] = f"{out}/<tracker>/ ({len(files)} files)"
    if plots:
        from benchmarks.analysis.pictures import plot_iou_over_time

        per: dict = {}
        for r in results:
            per.setdefault(r.tracker, {})[r.sequence] = r.iou
        paths["png"] = plot_iou_over_time(per, out / "iou_over_time.png")
    for seq, path in videos.items():
        from dvsot.dataset.preview import write_preview

        chosen = {r.tracker: r.predictions for r in results if r.sequence == seq}
        paths[f"gif:{seq}"] = write_preview(path, out / video_name(seq), chosen, max_segments=VIDEO_SEGMENTS)
    if energy is not None:
        from benchmarks.analysis.energy_table import plot_firing_rates

        paths["energy"] = write_text_atomic(out / "energy.json", json.dumps(energy, indent=2))
        paths["firing"] = plot_firing_rates(energy["firing"], out / "firing_rate.png")
    return paths


def _write_stream(out: Path, summary: dict, results: list, plots: bool, energy: dict | None) -> dict[str, Path | str]:
    """A streaming run's files: its tables and scale plot, call files, IoU per query (plots) and energy table."""
    from benchmarks.analysis.stream_tables import write_stream, write_stream_files
    from benchmarks.analysis.tables import write_text_atomic

    paths: dict[str, Path | str] = {f"stream:{x.name}": x for x in write_stream(summary, out)}
    files = write_stream_files(results, out)
    if files:
        paths["per-sequence"] = f"{out}/<tracker>/stream/ ({len(files)} files)"
    per: dict = {}
    step_ms = 1.0
    if plots:
        for r in results:
            if r.error is None:
                run = next(iter(v for k, v in r.runs.items() if k != "free"))
                step_ms = float(np.median(np.diff(run.query_us))) / 1000 if len(run.query_us) > 1 else 1.0
                per.setdefault(f"{r.tracker} [{run.latency}]", {})[r.sequence] = run.iou
    if per:  # IoU per query of each tracker's first latency model (a run that failed everywhere has none)
        from benchmarks.analysis.pictures import plot_iou_over_time

        paths["png"] = plot_iou_over_time(per, out / "iou_over_time.png", segment_ms=step_ms,
                                          title="IoU per ground-truth query")
    if energy is not None:
        from benchmarks.analysis.energy_table import plot_firing_rates

        paths["energy"] = write_text_atomic(out / "energy.json", json.dumps(energy, indent=2))
        paths["firing"] = plot_firing_rates(energy["firing"], out / "firing_rate.png")
    return paths
