"""How a run runs: outputs written atomically (outputs, staging), signals (interrupts), background threads
(threads), the task runner on Dask (dask_tasks) and its local worker processes (local_workers)."""
