"""Benchmark suite: trackers behind one interface, the A/R/ARscore protocol, tables, performance scripts.

Public names (each imported on first use): `benchmark` (trackers x dataset files -> `SequenceResult`s),
`run_sequence`, the tracker registry (`get_tracker`, `register`, `available_trackers`, `Tracker`), the
metrics (`scores`, `pooled`, `ar_score`, `Scores`), `summarise` (results -> a typed `Summary` of `Cell`s,
the tables' data; `summarise_ope` for one-pass runs), `write_report` (a run's tables,
per-sequence files, pictures and manifest, written together; Table 3 from
`benchmarks.energy_table.energy_table`), `find_sequences` (the files to run on) and
`load_sctn_checkpoint`.
"""

from dvsot.lazy import lazy_attributes

_API = {
    "benchmark": "benchmarks.runner",
    "run_one": "benchmarks.runner",
    "SequenceResult": "benchmarks.protocol",
    "run_sequence": "benchmarks.protocol",
    "get_tracker": "benchmarks.trackers",
    "register": "benchmarks.trackers",
    "available_trackers": "benchmarks.trackers",
    "Tracker": "benchmarks.trackers.base",
    "scores": "benchmarks.metrics",
    "pooled": "benchmarks.metrics",
    "ar_score": "benchmarks.metrics",
    "Scores": "benchmarks.metrics",
    "summarise": "benchmarks.tables",
    "Summary": "benchmarks.tables",
    "Cell": "benchmarks.tables",
    "summarise_ope": "benchmarks.ope",
    "write_report": "benchmarks.report",
    "find_sequences": "benchmarks.runner",
    "load_sctn_checkpoint": "benchmarks.models",
}
__all__ = list(_API)
__getattr__, __dir__ = lazy_attributes(__name__, _API)
