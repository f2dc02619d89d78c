"""Benchmark suite: trackers behind one interface, the A/R/ARscore protocol, tables, performance scripts.

Public names (each imported on first use): `run_benchmark` (`dvsot bench`: every input checked by
`plan_benchmark`, the runs, the tables written), `benchmark` (trackers x dataset files -> `SequenceResult`s),
`run_sequence`, the tracker registry (`get_tracker`, `register`, `available_trackers`, `Tracker`), the
metrics (`scores`, `pooled`, `ar_score`, `Scores`), `summarise` (results -> a typed `Summary` of `Cell`s,
the tables' data; `summarise_ope` for one-pass runs), `write_report` (a run's tables,
per-sequence files, pictures and manifest, written together), `energy_table` (the paper's Table 3) and
`find_sequences` (the files to run on), and training: `train_model` (any registered model to a checkpoint),
`train_siamfc`, and the training registry (`TRAINERS`, `register_trainer`, `Trainer`). Checkpoints load
through `sctn.load_checkpoint`.
"""

from dvsot.core.lazy import lazy_attributes

_API = {
    "run_benchmark": "benchmarks.bench.plan",
    "plan_benchmark": "benchmarks.bench.plan",
    "benchmark": "benchmarks.evaluation.runner",
    "run_one": "benchmarks.evaluation.runner",
    "SequenceResult": "benchmarks.evaluation.protocol",
    "run_sequence": "benchmarks.evaluation.protocol",
    "get_tracker": "benchmarks.trackers",
    "register": "benchmarks.trackers",
    "available_trackers": "benchmarks.trackers",
    "Tracker": "benchmarks.trackers.base",
    "scores": "benchmarks.evaluation.metrics",
    "pooled": "benchmarks.evaluation.metrics",
    "ar_score": "benchmarks.evaluation.metrics",
    "Scores": "benchmarks.evaluation.metrics",
    "summarise": "benchmarks.analysis.tables",
    "Summary": "benchmarks.analysis.tables",
    "Cell": "benchmarks.analysis.tables",
    "summarise_ope": "benchmarks.evaluation.ope",
    "write_report": "benchmarks.analysis.report",
    "find_sequences": "benchmarks.evaluation.runner",
    "energy_table": "benchmarks.analysis.energy_table",
    "train_model": "benchmarks.training.run",
    "train_siamfc": "benchmarks.trackers.siamfc.train",
    "TRAINERS": "benchmarks.training.registry",
    "register_trainer": "benchmarks.training.registry",
    "Trainer": "benchmarks.training.registry",
}
__all__ = list(_API)
__getattr__, __dir__ = lazy_attributes(__name__, _API)
