"""TaskRunner(None): calls run in this process, in order, under the cluster runner's failure and retry rules."""

import pytest

from dvsot.core.errors import RunError, UserError
from dvsot.runtime.dask_tasks import Failure, TaskRunner, map_tasks


def flaky(k: int, fails: dict) -> int:
    if fails.get(k, 0) > 0:
        fails[k] -= 1
        raise ValueError(f"call {k} failed")
    return k * 10


def test_a_failed_call_is_retried_here_and_recorded_until_its_last_attempt():
    fails = {1: 1, 2: 5}
    seen, failures = [], []
    with TaskRunner(None) as runner:
        assert runner.client is None and runner.hosts() is None
        out = runner.run(flaky, [(k, fails) for k in range(3)], retries=1,
                         on_result=lambda k, r: seen.append((k, r)),
                         on_failure=lambda k, f, final: failures.append((k, f.error, final)))
    assert out[:2] == [0, 10] and isinstance(out[2], Failure) and out[2].error == "ValueError: call 2 failed"
    assert seen == [(0, 0), (1, 10)]
    assert failures == [(1, "ValueError: call 1 failed", False), (2, "ValueError: call 2 failed", False),
                        (2, "ValueError: call 2 failed", True)]


def test_map_tasks_here_stops_at_the_first_failure_as_one_line():
    def bad_input(k):
        raise UserError(f"scene {k}: bad")

    with pytest.raises(UserError, match="^scene 0: bad$"):
        map_tasks(None, bad_input, [(0,), (1,)])
    with pytest.raises(RunError, match=r"^task 2 of 2 failed here: ValueError: call 1 failed$"):
        map_tasks(None, flaky, [(0, {}), (1, {1: 1})])
    assert map_tasks(None, flaky, [(0, {}), (3, {})]) == [0, 30]
