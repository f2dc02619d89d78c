"""Performance scripts: each prints its figures as JSON (run with `python -m benchmarks.perf.<name>`)."""
