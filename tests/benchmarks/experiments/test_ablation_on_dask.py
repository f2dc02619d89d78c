"""benchmarks.experiments.ablation --scheduler: each (row, seed) a Dask task on a real LocalCluster of two
single-threaded workers (one cluster for the module, reached at its tcp:// address), on the two tiny CI scenes (--ci)
and on two synthetic squares. The workers' trackers fine-tune once (fail_run_preload.py): these tests are about
scheduling."""

import json
import logging
import os

import dask
import pytest
from synthetic import moving_square_file

from benchmarks.experiments.ablation import cli

pytestmark = pytest.mark.blender

PRELOAD = os.path.join(os.path.dirname(__file__), "fail_run_preload.py")
QUICK = ["--rows", "paper", "fast_nearest", "--seeds", "2", "--epochs", "1", "--segments-per-epoch", "2",
         "--batch-segments", "1", "--candidates", "8", "--max-segments", "3", "--retries", "1"]


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    """A LocalCluster of 2 single-threaded worker processes whose run_one fails as the control file says."""
    from distributed import Client, LocalCluster

    control = tmp_path_factory.mktemp("control") / "fail"
    os.environ["DVSOT_TEST_FAIL_RUN"] = str(control)  # read in the workers, which inherit it at their start
    try:
        with dask.config.set({"distributed.worker.preload": [PRELOAD]}):
            lc = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                              silence_logs=logging.CRITICAL)
        with lc, Client(lc) as client:
            yield client.scheduler.address, control
    finally:
        del os.environ["DVSOT_TEST_FAIL_RUN"]


@pytest.fixture(scope="module")
def squares(tmp_path_factory) -> list[str]:
    """--train and --test arguments: two small synthetic squares, written in a fraction of a CI scene's render."""
    d = tmp_path_factory.mktemp("squares")
    train = moving_square_file(d / "train.h5", width=96, height=72, size=16, duration_ms=60)
    test = moving_square_file(d / "test.h5", width=96, height=72, size=16, duration_ms=60,
                              velocity_px_s=(-120.0, 50.0), start=(60.0, 20.0), split="test", seed=1)
    return ["--train", str(train), "--test", str(test)]


def records(out):
    return [json.loads(line) for line in (out / "runs.jsonl").read_text().splitlines()]


def test_seeds_run_as_tasks_and_a_failed_attempt_is_retried_on_the_other_worker(cluster, tmp_path, capsys):
    address, control = cluster
    control.write_text("paper 1 once")
    out = tmp_path / "abl"
    assert cli(QUICK + ["--ci", "--scheduler", address, "--out", str(out)]) == 0
    recs = records(out)
    results = {(r["row"], r["seed"]): r for r in recs if "error" not in r}
    assert set(results) == {("paper", 0), ("paper", 1), ("fast_nearest", 0), ("fast_nearest", 1)}
    for r in results.values():
        assert 0 <= r["ARscore"] <= 1 and r["segments"] > 0
    # the tracker-only rows ran after, on the networks the paper rows trained (the same checkpoints)
    assert sorted(p.name for p in out.glob("*.pt")) == ["paper_seed0.pt", "paper_seed1.pt"]
    assert [i for i, r in enumerate(recs) if r["row"] == "fast_nearest"] == [len(recs) - 2, len(recs) - 1]
    (bad,) = [r for r in recs if "error" in r]
    assert (bad["row"], bad["seed"], bad["attempt"], bad["final"]) == ("paper", 1, 1, False)
    assert bad["error"] == "RuntimeError: injected failure" and bad["worker"].startswith("tcp://127.0.0.1:")
    cap = capsys.readouterr()
    assert "ablation: paper seed 1 failed on tcp://127.0.0.1:" in cap.err and "retrying" in cap.err
    assert "| paper |" in cap.out and "| fast_nearest |" in cap.out
    # a rerun has every result: nothing runs, not even a cluster
    assert cli(QUICK + ["--ci", "--scheduler", "local:2", "--out", str(out)]) == 0
    assert records(out) == recs


def test_a_run_that_keeps_failing_is_recorded_and_the_others_finish(cluster, squares, tmp_path, capsys):
    address, control = cluster
    control.write_text("paper 0 always")
    out = tmp_path / "abl"
    assert cli(QUICK + squares + ["--scheduler", address, "--out", str(out)]) == 1
    recs = records(out)
    assert {(r["row"], r["seed"]) for r in recs if "error" not in r} == {("paper", 1), ("fast_nearest", 1)}
    fails = [r for r in recs if "error" in r]
    assert [(r["row"], r["seed"], r["attempt"], r["final"]) for r in fails] == [
        ("paper", 0, 1, False), ("paper", 0, 2, True), ("fast_nearest", 0, 1, True)]
    assert fails[0]["worker"] != fails[1]["worker"]  # retried on the other worker
    assert fails[2]["error"] == "its network's training run (paper, seed 0) failed"
    err = capsys.readouterr().err
    assert "ablation: 2 run(s) failed: paper seed 0, fast_nearest seed 0" in err
    assert not (out / "paper_seed0.pt").exists()
