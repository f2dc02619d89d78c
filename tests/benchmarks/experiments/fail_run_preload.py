"""A Dask worker preload for tests: benchmarks.experiments.ablation.run_one fails for the (row, seed) that the file
named by DVSOT_TEST_FAIL_RUN holds ("ROW SEED always" or "ROW SEED once": then only its first attempt on any worker),
and every row's tracker fine-tunes once at initialisation instead of the preset's 10 times: the tests that load it are
about scheduling and retries, and the fine-tuning was most of a run's CPU time."""

import os
from pathlib import Path

import benchmarks.experiments.ablation as _ablation

if not getattr(_ablation.run_one, "injected", False):  # a preload may run more than once per process
    _real = _ablation.run_one
    # only the tracker options change, so training_key (which compares training and network settings) is unchanged
    _ablation.ROWS = {row: (train_kw, net_kw, {**track_kw, "finetune_iters": 1})
                      for row, (train_kw, net_kw, track_kw) in _ablation.ROWS.items()}

    def run_one(row, seed, *args, **kwargs):
        control = Path(os.environ["DVSOT_TEST_FAIL_RUN"])
        words = control.read_text().split() if control.is_file() else []
        if words[:2] == [row, str(seed)]:
            if words[2:] == ["always"]:
                raise RuntimeError("injected failure")
            if words[2:] == ["once"]:
                control.write_text("")  # the retry (on the other worker) runs
                raise RuntimeError("injected failure")
        return _real(row, seed, *args, **kwargs)

    run_one.injected = True
    _ablation.run_one = run_one
