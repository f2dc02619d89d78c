"""Each worker process on a machine gets its own share of the CPUs, and renders with as many threads."""

import os

from dvsot.runtime import cpu_shares
from dvsot.runtime.cpu_shares import cpu_share


def test_each_worker_on_a_machine_gets_its_own_share_of_the_cpus():
    assert [cpu_share([0, 1], k, 2) for k in range(2)] == [{0}, {1}]
    assert [cpu_share([4, 5, 6, 7, 8], k, 2) for k in range(2)] == [{4, 5}, {6, 7}]
    assert cpu_share([0, 1], 0, 1) is None  # one worker has them all
    assert cpu_share([0, 1], 2, 3) is None  # more workers than CPUs: not bound
    assert cpu_share([0, 1, 2, 3], 5, 2) is None


def test_a_bound_worker_renders_with_its_bound_cpus(monkeypatch):
    monkeypatch.setattr(cpu_shares, "BOUND", [4, 5])  # as warm_up leaves a worker bound to two CPUs of four
    assert cpu_shares.threads_for_this_worker({"tcp://127.0.0.1": 2}) == 2
    monkeypatch.setattr(cpu_shares, "BOUND", [])
    assert cpu_shares.threads_for_this_worker({}) == len(os.sched_getaffinity(0))  # outside a worker: every CPU
