"""A signal once a command's outputs are being put in place: the run completed, it says so and exits 0 (every command,
through the commit's mark); a signal after a commit while more work follows still stops that work; a signal while
the `dvsot` process starts or exits is one line or nothing, never a traceback."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from synthetic import moving_square_file  # noqa: E402

SHIPPED = Path(__file__).resolve().parents[2] / "sctn" / "checkpoints" / "sctn_dvsot21.pt"

# the command, whose first rename onto a final output (not a hidden temp) is followed by a pause for the test's signal
SLOW_FINAL_RENAME = """
import os, sys, time
real = os.replace
state = {"done": False}
def replace(src, dst, *a, **k):
    real(src, dst, *a, **k)
    if not state["done"] and not os.path.basename(str(dst)).startswith("."):
        state["done"] = True
        print("RENAMED", flush=True)
        time.sleep(2)
os.replace = replace
from dvsot.cli import main
sys.exit(main(sys.argv[1:]))
"""

# `dvsot` itself (argv[0] names it), whose interpreter exit takes a while as Blender's clean-up does
SLOW_EXIT = """
import atexit, sys, time
sys.argv[0] = "dvsot"
from dvsot.cli import main
def slow():
    print("EXITING", flush=True)
    time.sleep(2)
atexit.register(slow)
sys.exit(main())
"""


@pytest.fixture(scope="module")
def inputs(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("late")
    moving_square_file(d / "seq.h5", width=48, height=36, size=10, duration_ms=40, split="test")
    np.save(d / "f.npy", np.random.default_rng(0).uniform(0.1, 1, (4, 12, 16)).astype(np.float32))
    (d / "ev.txt").write_text("16 12\n0.000001 1 2 1\n0.02 3 4 0\n")
    return d


CASES = {
    "export": lambda d, o: ["export", d / "seq.h5", "-o", o / "x.csv"],
    "import": lambda d, o: ["import", d / "ev.txt", "-o", o / "x.h5"],
    "simulate": lambda d, o: ["simulate", d / "f.npy", "--fps", "100", "-o", o / "x.h5", "--quiet"],
    "export-model": lambda d, o: ["export-model", SHIPPED, "-o", o / "x.nir"],
}


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
@pytest.mark.parametrize("command", list(CASES))
def test_a_signal_during_the_final_renames_is_a_completed_run(tmp_path, inputs, command, sig):
    p = subprocess.Popen([sys.executable, "-c", SLOW_FINAL_RENAME, *map(str, CASES[command](inputs, tmp_path))],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    for line in p.stdout:
        if line.startswith("RENAMED"):
            break
    p.send_signal(sig)
    _, err = p.communicate(timeout=120)
    name = signal.Signals(sig).name
    assert p.returncode == 0, err
    lines = [ln for ln in err.strip().splitlines() if ": note: " not in ln]  # a checkpoint's note is no error
    assert lines == [f"dvsot {command}: done; {name} arrived after its outputs were written"], err
    assert not [n for n in os.listdir(tmp_path) if n.startswith(".")]  # every staged file was put in place


@pytest.mark.blender
def test_a_signal_during_generates_final_renames_is_a_completed_run(tmp_path):
    from synthetic import MINIMAL_SCENE

    scene = tmp_path / "q.yaml"
    scene.write_text(MINIMAL_SCENE.replace("duration_s: 0.1", "duration_s: 0.02\nsensor: {width: 64, height: 48}"))
    out = tmp_path / "o"
    out.mkdir()
    p = subprocess.Popen([sys.executable, "-c", SLOW_FINAL_RENAME, "generate", str(scene), "-o", str(out / "q.h5"),
                          "--preview", "--quiet"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    for line in p.stdout:
        if line.startswith("RENAMED"):
            break
    p.send_signal(signal.SIGINT)
    _, err = p.communicate(timeout=600)
    assert p.returncode == 0, err
    assert err.strip().splitlines() == ["dvsot generate: done; SIGINT arrived after its outputs were written"], err
    assert sorted(n for n in os.listdir(out) if "~" not in n) == sorted(n for n in os.listdir(out))  # no temps
    assert {"q.gif", "q.h5"} <= set(os.listdir(out))


@pytest.mark.blender
@pytest.mark.parametrize("delay", [0.1, 0.3])
def test_a_signal_while_blender_cleans_up_changes_nothing(tmp_path, delay):
    from synthetic import MINIMAL_SCENE

    scene = tmp_path / "q.yaml"
    scene.write_text(MINIMAL_SCENE.replace("duration_s: 0.1", "duration_s: 0.02\nsensor: {width: 64, height: 48}"))
    p = subprocess.Popen([sys.executable, "-m", "dvsot.cli", "generate", str(scene), "-o", str(tmp_path / "q.h5"),
                          "--quiet"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    p.stdout.readline()  # the summary: printed after the commit, before the interpreter (and Blender) exits
    time.sleep(delay)
    p.send_signal(signal.SIGTERM)
    _, err = p.communicate(timeout=600)
    assert p.returncode == 0 and "Traceback" not in err, (p.returncode, err)
    assert (tmp_path / "q.h5").is_file()


def test_a_signal_while_the_process_exits_changes_nothing(tmp_path, inputs):
    p = subprocess.Popen([sys.executable, "-c", SLOW_EXIT, "export", str(inputs / "seq.h5"), "-o",
                          str(tmp_path / "x.csv")], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    for line in p.stdout:
        if line.startswith("EXITING"):
            break
    p.send_signal(signal.SIGTERM)
    time.sleep(0.2)
    p.send_signal(signal.SIGINT)
    _, err = p.communicate(timeout=60)
    assert p.returncode == 0, err
    assert "Traceback" not in err and "done; SIGTERM arrived after its outputs were written" in err, err
    assert (tmp_path / "x.csv").is_file()


# `dvsot` starting: a signal inside the imports of the command line (after the package's first lines)
SIGNAL_IN_IMPORTS = """
import importlib.abc, os, signal, sys
sys.argv[0] = "dvsot"
class Finder(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path, target=None):
        if name == "dvsot.cli.flags":  # the command's own imports, after its start-up hook
            os.kill(os.getpid(), getattr(signal, sys.argv.pop(1)))
            for _ in range(10_000_000):  # the handler runs at the next bytecode
                pass
        return None
sys.meta_path.insert(0, Finder())
from dvsot.cli import main
sys.exit(main())
"""


@pytest.mark.parametrize("sig", ["SIGINT", "SIGTERM"])
def test_a_signal_at_start_up_is_one_line(tmp_path, sig):
    r = subprocess.run([sys.executable, "-c", SIGNAL_IN_IMPORTS, sig, "info", str(tmp_path / "none.h5")],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 128 + getattr(signal, sig), r.stderr
    assert r.stderr.strip().splitlines() == [f"dvsot: interrupted ({sig})"], r.stderr


def test_a_signal_after_a_commit_stops_the_work_that_follows(tmp_path):
    from dvsot.runtime import interrupts
    from dvsot.runtime.outputs import replacing

    saved = interrupts.install()
    try:
        with replacing(tmp_path / "a.txt") as tmp:
            tmp.write_text("a")
        assert interrupts.committed()
        os.kill(os.getpid(), signal.SIGINT)  # after the commit: recorded as late, nothing raised
        assert interrupts.late() == signal.SIGINT and (tmp_path / "a.txt").read_text() == "a"
        with pytest.raises(interrupts.Interrupted):  # the command goes on to stage more: the signal stops it there
            with replacing(tmp_path / "b.txt") as tmp:
                tmp.write_text("b")
        assert not (tmp_path / "b.txt").exists()
        with replacing(tmp_path / "c.txt") as tmp:
            tmp.write_text("c")
        os.kill(os.getpid(), signal.SIGINT)
        with pytest.raises(interrupts.Interrupted):  # a step between frames after a commit stops too
            interrupts.check()
    finally:
        interrupts.restore(saved)
