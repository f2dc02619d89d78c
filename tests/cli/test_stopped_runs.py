"""A run on Dask stopped as a user stops it (Ctrl-C to the process group, SIGTERM to the command): one line, 128 +
signal, and no worker of that run commits anything afterwards (old outputs kept, no temp left behind)."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from processes import children, dvsot, group_alive, names, wait_for  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
QUICKSTART = ROOT / "blender_scenes" / "quickstart.yaml"
TINY_RENDER = ["--resolution", "160x120", "--duration", "0.2", "--quiet"]


def scenes(tmp_path: Path, *names_: str) -> list[Path]:
    text = QUICKSTART.read_text()
    out = []
    for name in names_:
        s = tmp_path / f"{name}.yaml"
        s.write_text(text.replace("name: quickstart", f"name: {name}"))
        out.append(s)
    return out


@pytest.mark.blender
@pytest.mark.parametrize("how", ["ctrl-c", "sigterm"])
@pytest.mark.parametrize("flag", [["--scheduler", "local:2"], ["--jobs", "2"]], ids=["scheduler", "jobs"])
def test_a_stopped_dask_run_commits_nothing_afterwards(tmp_path, how, flag):
    d = tmp_path / "out"
    d.mkdir()
    for name in ("qa", "qb"):
        (d / f"{name}.h5").write_bytes(b"old " + name.encode())
    p = subprocess.Popen(dvsot("generate", *scenes(tmp_path, "qa", "qb"), "--out-dir", d, *flag, *TINY_RENDER),
                         stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        wait_for(lambda: any(n.startswith((".qa.h5.tmp", ".qb.h5.tmp")) for n in names(d)) or p.poll() is not None)
        if how == "ctrl-c":
            os.killpg(p.pid, signal.SIGINT)  # what a terminal's Ctrl-C does: the whole foreground group
        else:
            p.send_signal(signal.SIGTERM)
        _, err = p.communicate(timeout=120)
        wait_for(lambda: not group_alive(p.pid), timeout=60, step=0.05)  # every worker has ended
        time.sleep(1.5)  # a worker that went on would have replaced its output by now
    finally:
        if group_alive(p.pid):
            os.killpg(p.pid, signal.SIGKILL)
    sig = signal.SIGINT if how == "ctrl-c" else signal.SIGTERM
    assert p.returncode == 128 + sig, err
    assert err.strip().splitlines() == [f"dvsot generate: interrupted ({sig.name})"], err
    assert (d / "qa.h5").read_bytes() == b"old qa" and (d / "qb.h5").read_bytes() == b"old qb"
    assert [n for n in names(d) if n not in ("qa.h5", "qb.h5", "manifest.json")] == [], names(d)


def test_a_revoked_lease_stops_a_task_and_its_commit(tmp_path):
    """The mechanism alone: a task checks its run's lease at each step and before its renames."""
    from dvsot.runtime import interrupts
    from dvsot.runtime.outputs import replacing
    from dvsot.runtime.staging import LeaseGuard, RunLease

    lease = RunLease(tmp_path)
    guard = LeaseGuard(lease.path)
    out = tmp_path / "x.txt"
    out.write_text("old")
    with interrupts.guarded(guard):
        interrupts.check()  # live
        with pytest.raises(interrupts.Interrupted, match="stopped"):
            with replacing(out) as tmp:
                tmp.write_text("new")
                lease.revoke()
        with pytest.raises(interrupts.Interrupted):
            interrupts.check()
    guard.close()
    assert out.read_text() == "old" and names(tmp_path) == ["x.txt"]


@pytest.mark.parametrize("delay", [0.2, 1.0])
def test_ctrl_c_on_bench_with_a_scheduler_is_one_line(tmp_path, delay):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from synthetic import moving_square_file

    data = tmp_path / "data"
    data.mkdir()
    for k in range(2):
        moving_square_file(data / f"s{k}.h5", width=64, height=48, size=12, duration_ms=100, split="test", seed=k)
    out = tmp_path / "b"
    p = subprocess.Popen(dvsot("bench", "--tracker", "rct", "--tracker", "kcf", "--data", data, "--out", out,
                               "--scheduler", "local:2", "--quiet"),
                         stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        wait_for(lambda: len(children(p.pid)) >= 2 or p.poll() is not None, timeout=120)
        time.sleep(delay)  # the workers start up, or run their first tasks
        os.killpg(p.pid, signal.SIGINT)
        _, err = p.communicate(timeout=120)
        wait_for(lambda: not group_alive(p.pid), timeout=60, step=0.05)
    finally:
        if group_alive(p.pid):
            os.killpg(p.pid, signal.SIGKILL)
    if p.returncode == 0:
        pytest.skip("the run ended before the signal")
    assert p.returncode == 130 and err.strip().splitlines() == ["dvsot bench: interrupted (SIGINT)"], err
    assert not out.exists() or not any(out.iterdir())


def test_a_signal_while_tasks_run_after_a_manifest_commit_stops_the_run(tmp_path):
    """A manifest written before or between tasks is the run's progress, not its end: no signal is taken as late."""
    from dvsot.runtime import interrupts
    from dvsot.runtime.dask_tasks import TaskRunner
    from dvsot.runtime.outputs import replacing

    def manifest() -> None:
        with replacing(tmp_path / "manifest.json") as tmp:
            tmp.write_text("{}")

    saved = interrupts.install()
    try:
        manifest()
        assert interrupts.committed()
        os.kill(os.getpid(), signal.SIGINT)  # after the manifest, before the tasks: late so far
        with pytest.raises(interrupts.Interrupted):
            with TaskRunner(None):  # starting the tasks is more work: the signal stops the run here
                pytest.fail("the run went on")
        manifest()
        with TaskRunner(None) as runner:
            with pytest.raises(interrupts.Interrupted):
                runner.run(manifest, [(), ()])  # each task rewrites the manifest; then the signal
                assert not interrupts.committed()
                os.kill(os.getpid(), signal.SIGINT)
                pytest.fail("the signal was taken as late")
        assert interrupts.late() is None
    finally:
        interrupts.restore(saved)
