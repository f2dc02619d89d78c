"""A commit journal completes only its own run's regular staged files; a run's tree is checked for collisions; a
writer past a file-size limit (a full disk) ends in one line with nothing left."""

import json
import os
import resource
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from dvsot.runtime import staging
from dvsot.runtime.outputs import tree_collision

SHIPPED = Path(__file__).resolve().parents[3] / "sctn" / "checkpoints" / "sctn_dvsot21.pt"


def _dead_pid() -> int:
    p = subprocess.Popen([sys.executable, "-c", "pass"])
    p.wait()
    return p.pid


def _journal(d: Path, entries: list[dict], pid: int, token: str = "0badc0de") -> Path:
    j = d / f".run.json.commit~{staging.host()}~{pid}~{token}.json"
    j.write_text(json.dumps({"format": "dvsot-run", "files": {}, "entries": entries, "pointers": [],
                             "manifest": str(d / "run.json")}))
    return j


def _staged(final: Path, pid: int, token: str = "0badc0de") -> Path:
    return final.with_name(f".{final.name}.tmp~{staging.host()}~{pid}~{token}{final.suffix}")


@pytest.mark.parametrize("case", ["final-is-a-directory", "staged-is-a-fifo", "staged-of-another-run"])
def test_a_journal_of_entries_that_are_not_its_runs_files_is_discarded(tmp_path, case):
    pid = _dead_pid()
    good, bad = tmp_path / "a.txt", tmp_path / "b.txt"
    s_good = _staged(good, pid)
    s_bad = _staged(bad, os.getpid(), "feedface") if case == "staged-of-another-run" else _staged(bad, pid)
    s_good.write_text("new a")
    if case == "final-is-a-directory":
        bad.mkdir()
        s_bad.write_text("new b")
    elif case == "staged-is-a-fifo":
        os.mkfifo(s_bad)
    else:
        s_bad.write_text("new b")
    journal = _journal(tmp_path, [{"final": str(good), "staged": str(s_good), "kind": "file", "old": None},
                                  {"final": str(bad), "staged": str(s_bad), "kind": "file", "old": None}], pid)
    staging.clean_stale(tmp_path)
    assert not journal.exists() and not (tmp_path / "run.json").exists()  # never completed into a manifest
    assert not good.exists() and not s_good.exists()
    assert (case == "staged-of-another-run") == s_bad.exists()  # another (live) run's staged file stays


def test_a_journal_of_its_own_regular_files_completes(tmp_path):
    pid = _dead_pid()
    final = tmp_path / "a.txt"
    _staged(final, pid).write_text("new a")
    _journal(tmp_path, [{"final": str(final), "staged": str(_staged(final, pid)), "kind": "file", "old": None}], pid)
    staging.clean_stale(tmp_path)
    assert final.read_text() == "new a" and (tmp_path / "run.json").is_file()


@pytest.mark.parametrize("files, words", [
    (["t/timing.csv", "t/timing.csv/timing.csv_001.txt"], "is written as a file and is also the directory"),
    (["t/a.txt", "t/a.txt/a.txt_001.txt", "t/a/a_001.txt"], "is written as a file and is also the directory"),
    (["t/Seq.txt", "t/seq.txt"], "differ only in case"),
    (["t/A/x.txt", "t/a/y.txt"], "differ only in case"),
    (["t/a.txt", "t/a/a_001.txt", "t/times/a_time.txt"], None),
])
def test_tree_collisions(files, words):
    problem = tree_collision(files)
    assert (problem is None) if words is None else (words in problem), problem


def _limit_40k() -> None:
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write past the limit fails with EFBIG instead of killing
    resource.setrlimit(resource.RLIMIT_FSIZE, (40 * 1024, 40 * 1024))


@pytest.mark.parametrize("argv", [
    ["export-model", str(SHIPPED), "-o", "x.nir"],
    ["export-model", str(SHIPPED), "-o", "x.nir", "--discretisation", "euler"],
])
def test_a_file_size_limit_is_one_line_and_leaves_nothing(tmp_path, argv):
    (tmp_path / "x.nir").write_bytes(b"old")
    r = subprocess.run([sys.executable, "-m", "dvsot.cli", *argv], cwd=tmp_path, capture_output=True, text=True,
                       timeout=300, preexec_fn=_limit_40k)
    err = [line for line in r.stderr.strip().splitlines() if ": note: " not in line]  # a checkpoint's recipe note
    assert r.returncode == 1 and len(err) == 1 and "File too large" in err[0] and "x.nir" in err[0], r.stderr[-2000:]
    assert sorted(os.listdir(tmp_path)) == ["x.nir"] and (tmp_path / "x.nir").read_bytes() == b"old"
