"""SCTN evaluated over the events and spikes that exist: per-candidate evaluation (evaluate), its compiled
kernels (kernels) and event-driven weighted sums of spike maps (spike_sums)."""
