"""Experiments run as modules: SCTN's ablations (`python -m benchmarks.experiments.ablation`) and the CI metric
regression (`python -m benchmarks.experiments.regression`)."""
