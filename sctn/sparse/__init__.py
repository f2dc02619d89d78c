"""SCTN evaluated over the events and spikes that exist: per-candidate evaluation and its operation counts
(evaluate) and their compiled kernels (kernels)."""
