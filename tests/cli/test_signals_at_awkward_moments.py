"""Signals at awkward moments, sent as a user sends them: inside an extension module's import (which reports its own
error and drops the KeyboardInterrupt, as pyo3 and numpy's C API do), while bench writes a video, and after a
run's final renames have begun (the run completed: it says so and exits 0)."""

import json
import signal
import subprocess
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from synthetic import moving_square_file  # noqa: E402

# An import of `cv2` inside which a signal lands and comes out as the extension's own error, its cause dropped
SWALLOWING_IMPORT = """
import importlib.abc, os, signal, sys
KIND = sys.argv.pop(1)
class PanicException(BaseException):  # what pyo3 raises when Rust code panics (pydantic_core's datetime import)
    pass
class Finder(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path, target=None):
        if name != "cv2":
            return None
        try:
            os.kill(os.getpid(), signal.SIGINT)
            for _ in range(10_000_000):  # the handler runs at the next bytecode
                pass
        except KeyboardInterrupt:
            if KIND == "panic":
                raise PanicException("failed to import datetime") from None
            raise ImportError("numpy.core.multiarray failed to import") from None
        return None
sys.meta_path.insert(0, Finder())
from dvsot.cli import main
sys.exit(main(sys.argv[1:]))
"""

# train whose checkpoint's rename is followed by a pause in which the test sends its signal
SLOW_LAST_RENAME = """
import os, sys, time
real = os.replace
def replace(src, dst, *a, **k):
    real(src, dst, *a, **k)
    if str(dst).endswith(".pt"):
        print("RENAMED", flush=True)
        time.sleep(2)
os.replace = replace
from dvsot.cli import main
sys.exit(main(sys.argv[1:]))
"""


@pytest.fixture(scope="module")
def test_file(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("moments")
    return moving_square_file(d / "seq.h5", width=64, height=48, size=12, duration_ms=60, split="test")


@pytest.mark.parametrize("kind", ["import-error", "panic"])
def test_a_signal_inside_an_extensions_import_is_one_line(tmp_path, test_file, kind):
    r = subprocess.run([sys.executable, "-c", SWALLOWING_IMPORT, kind, "bench", "--tracker", "kcf", "--data",
                        test_file, "--out", tmp_path / "b", "--jobs", "1", "--quiet"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 130 and r.stderr.strip().splitlines() == ["dvsot bench: interrupted (SIGINT)"], r.stderr
    assert not (tmp_path / "b").exists()


def test_a_signal_after_the_final_renames_began_is_a_completed_run(tmp_path, test_file):
    train = moving_square_file(tmp_path / "tr.h5", width=64, height=48, size=12, duration_ms=60, split="train")
    out = tmp_path / "c.pt"
    out.write_bytes(b"old checkpoint")
    p = subprocess.Popen([sys.executable, "-c", SLOW_LAST_RENAME, "train", "--data", train, "-o", out, "--epochs",
                          "1", "--segments-per-epoch", "2", "--batch-segments", "1", "--channels", "2", "2", "2",
                          "--fc", "4", "4", "--threads", "1", "--quiet"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    for line in p.stdout:
        if line.startswith("RENAMED"):
            break
    p.send_signal(signal.SIGINT)
    out_text, err = p.communicate(timeout=120)
    assert p.returncode == 0, err
    assert err.strip().splitlines() == ["dvsot train: done; SIGINT arrived after its outputs were written"], err
    assert out.read_bytes() != b"old checkpoint" and out.with_suffix(".json").is_file()
    assert json.loads(out_text.strip().splitlines()[-1])["checkpoint"] == str(out)
