"""A run's output directory as a user meets it: results that would overwrite each other, a later run into the same
--out, a file where a directory goes, and the temps killed runs leave (bench under <out>/<tracker>/, export's
writer temps)."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from processes import dvsot  # noqa: E402
from synthetic import moving_square_file  # noqa: E402


def run(*args, timeout: float = 300) -> subprocess.CompletedProcess:
    return subprocess.run(dvsot(*args), capture_output=True, text=True, timeout=timeout)


def tree(d: Path) -> list[str]:
    return sorted(str(p.relative_to(d)) for p in d.rglob("*") if p.is_file())


def dead_pid() -> int:
    p = subprocess.Popen([sys.executable, "-c", "pass"])
    p.wait()
    return p.pid


@pytest.fixture(scope="module")
def data(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("rundirs")
    moving_square_file(d / "s0.h5", width=64, height=48, size=12, duration_ms=60, split="test")
    return d


def bench(data: Path, out: Path, *more) -> subprocess.CompletedProcess:
    return run("bench", "--data", data, "--out", out, "--jobs", "1", "--quiet", "--no-energy", *more)


# --- 3: per-sequence names unique within a run; --out holds one run's files only ---

def test_sequences_whose_safe_names_collide_are_refused_before_work(tmp_path, monkeypatch):
    import synthetic

    from benchmarks.evaluation.safe_names import file_stem

    twin = file_stem("a/b")  # "a_b-<hash>": a plain name that the safe name of "a/b" equals
    d = tmp_path / "data"
    d.mkdir()
    real = synthetic.DatasetWriter
    for k, name in enumerate(("a/b", twin)):
        monkeypatch.setattr(synthetic, "DatasetWriter",
                            lambda path, w, h, seg, attrs, name=name: real(path, w, h, seg, {**attrs, "name": name}))
        moving_square_file(d / f"s{k}.h5", width=64, height=48, size=12, duration_ms=60, split="test")
    r = bench(d, tmp_path / "b", "--tracker", "rct")
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert "same result file" in r.stderr and not (tmp_path / "b").exists()


def test_a_later_run_into_the_same_out_leaves_only_its_own_files(tmp_path, data):
    out = tmp_path / "b"
    assert bench(data, out, "--tracker", "rct", "--plots").returncode == 0
    assert (out / "iou_over_time.png").exists() and (out / "rct").is_dir()
    r = bench(data, out, "--tracker", "kcf")
    assert r.returncode == 0, r.stderr
    named = set(json.loads((out / "run.json").read_text())["files"])
    assert set(tree(out)) == named | {"run.json"}  # no picture, no rct/ of the earlier run
    assert not (out / "rct").exists() and not (out / "iou_over_time.png").exists()


def test_an_out_holding_other_files_is_refused_before_work(tmp_path, data):
    out = tmp_path / "b"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    r = bench(data, out, "--tracker", "rct")
    assert r.returncode == 2 and "notes.txt" in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert tree(out) == ["notes.txt"]


# --- 11: every path under --out is checked before work ---

@pytest.mark.parametrize("blocker", ["rct/times", "rct/baseline", "rct/baseline/s0"])
def test_a_file_where_a_directory_under_out_goes_is_refused_before_work(tmp_path, data, blocker):
    out = tmp_path / "b"
    assert bench(data, out, "--tracker", "rct").returncode == 0
    before = {p: (out / p).read_bytes() for p in tree(out)}
    target = out / blocker
    import shutil

    shutil.rmtree(target)
    target.write_text("in the way")
    manifest = json.loads((out / "run.json").read_text())
    manifest["files"][blocker] = {}  # the user's file, named as the earlier run's so only the path check refuses it
    (out / "run.json").write_text(json.dumps(manifest))
    t0 = time.monotonic()
    r = bench(data, out, "--tracker", "rct")
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert blocker in r.stderr and "directory" in r.stderr and time.monotonic() - t0 < 60
    assert target.read_text() == "in the way"
    assert not [n for n in tree(out) if "~" in n]
    assert all((out / p).read_bytes() == b for p, b in before.items() if (out / p).exists() and p != "run.json")


# --- 13: temps nobody removes ---

def test_a_killed_benchs_temps_under_a_tracker_folder_go_with_the_next_run_of_other_trackers(tmp_path, data):
    from dvsot.runtime.staging import host

    out = tmp_path / "b"
    assert bench(data, out, "--tracker", "rct").returncode == 0
    pid = dead_pid()
    left = [out / "rct" / f".s0.txt.tmp~{host()}~{pid}~0123abcd.txt",
            out / "rct" / "times" / f".s0_time.txt.tmp~{host()}~{pid}~0123abcd.txt"]
    for p in left:
        p.write_text("half a result")
    r = bench(data, out, "--tracker", "kcf")
    assert r.returncode == 0, r.stderr
    assert not any(p.exists() for p in left) and not [n for n in tree(out) if "~" in n], tree(out)


@pytest.fixture
def big_file(tmp_path) -> Path:
    """A dataset file with enough events that exporting it takes a moment."""
    rng = np.random.default_rng(0)
    frames = tmp_path / "f.npy"
    np.save(frames, rng.uniform(0.05, 1.0, size=(150, 120, 160)).astype(np.float32))
    out = tmp_path / "big.h5"
    assert run("simulate", frames, "--fps", "1000", "-o", out, "--quiet").returncode == 0
    return out


@pytest.mark.parametrize("how", ["kill", "interrupt"])
def test_an_exports_writer_temp_is_removed(tmp_path, big_file, how):
    d = tmp_path / "x"
    d.mkdir()
    out = d / "e.aedat4"
    p = subprocess.Popen(dvsot("export", big_file, "-o", out, "--no-boxes"), stdout=subprocess.DEVNULL,
                         stderr=subprocess.PIPE, text=True)
    end = time.monotonic() + 120
    while not any(n.endswith(".write") for n in os.listdir(d)) and p.poll() is None and time.monotonic() < end:
        time.sleep(0.001)
    if p.poll() is not None:
        pytest.skip("the export ended before its writer's temp could be caught")
    if how == "kill":
        p.kill()
        p.wait()
        assert any(n.endswith(".write") for n in os.listdir(d))
        assert run("export", big_file, "-o", out, "--no-boxes").returncode == 0  # the next run cleans up
        assert os.listdir(d) == ["e.aedat4"]
    else:
        p.send_signal(signal.SIGINT)
        _, err = p.communicate(timeout=60)
        assert p.returncode == 130 and err.strip().splitlines() == ["dvsot export: interrupted (SIGINT)"], err
        assert os.listdir(d) == []
