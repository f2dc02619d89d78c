"""How a run runs: outputs written atomically (outputs, staging), signals (interrupts), background threads
(threads), worker processes and Dask tasks (worker_pool, dask_tasks)."""
