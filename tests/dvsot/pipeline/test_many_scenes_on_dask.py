"""Variants on Dask: a LocalCluster of two worker processes, and a scheduler and a worker started as processes."""

import json
import os
import socket
import subprocess
import sys
import time
from pathlib import Path

import dask
import distributed  # noqa: F401  (loads its config defaults before the test sets one of them)
import pytest

from dvsot.cli import main
from dvsot.dataset import Dataset
from dvsot.scene.templates import draw_variants, read_template

pytestmark = pytest.mark.blender

PRELOAD = Path(__file__).resolve().parent / "fail_scene_preload.py"
TEMPLATE = """name: tiny
seed: 3
duration_s: 0.05
sensor: {width: 80, height: 60, focal_mm: 35}
camera:
  keyframes: [{t: 0, location: [0, -10, 0], look_at: [0, 0, 0]}]
target:
  shape: {choice: [cube, sphere]}
  size_m: {uniform: [1.2, 1.8]}
  trajectory:
    interpolation: linear
    keyframes: [{t: 0, location: [-1, 0, 0]}, {t: 0.05, location: [{uniform: [0.5, 1.5]}, 0, 0]}]
background:
  material: {color: [0.1, 0.1, 0.1], emission: 0.3}
lights: []
world: {color: [0.5, 0.5, 0.5], strength: 1.0}
sampling: {min_rate_hz: 200, max_displacement_px: 2}
"""


def cores():
    return len(os.sched_getaffinity(0))


def test_local_cluster_records_a_failure_retried_elsewhere_and_resume_renders_only_what_is_missing(tmp_path, capsys):
    import bpy  # noqa: F401  as after any render in this process: the workers inherit Blender's sys.path

    tpl = tmp_path / "tiny.yaml"
    tpl.write_text(TEMPLATE)
    out = tmp_path / "out"
    argv = ["generate", str(tpl), "--variants", "3", "--out-dir", str(out)]
    os.environ["DVSOT_TEST_FAIL"] = "tiny_00001"  # read by the preload in each worker process
    try:
        with dask.config.set({"distributed.worker.preload": [str(PRELOAD)]}):
            assert main(argv + ["--scheduler", "local:2", "--retries", "1"]) == 1
    finally:
        del os.environ["DVSOT_TEST_FAIL"]
    err = capsys.readouterr().err
    assert "tiny_00001: failed on tcp://" in err and "2 rendered, 0 already done, 1 failed (tiny_00001)" in err
    recs = {r["name"]: r for r in json.loads((out / "manifest.json").read_text())["scenes"]}
    variants = draw_variants(read_template(tpl), 3)
    for v in variants:
        rec = recs[v.name]
        assert (rec["variant"], rec["seed"], rec["drawn"]) == (v.index, v.seed, v.drawn)
        assert rec["file"] == str((out / f"{v.name}.h5").resolve())
    bad = recs["tiny_00001"]
    assert bad["status"] == "failed" and bad["error"] == "RuntimeError: injected failure"
    assert [a["error"] for a in bad["attempts"]] == ["RuntimeError: injected failure"] * 2
    assert bad["attempts"][0]["worker"] != bad["attempts"][1]["worker"]  # retried on the other worker
    assert not (out / "tiny_00001.h5").exists()
    stamps = {}
    for name in ("tiny_00000", "tiny_00002"):
        assert recs[name]["status"] == "done" and recs[name]["attempts"][0]["render_threads"] == max(1, cores() // 2)
        # two workers on this machine: each bound to its own half of the CPUs (one CPU: both have it all)
        assert len(recs[name]["attempts"][0]["cpus"]) == (cores() // 2 if cores() >= 2 else 1)
        with Dataset(out / f"{name}.h5") as ds:
            ds.verify()
            assert ds.num_events > 0 and ds.attrs["scene_yaml"].startswith(f"# variant {name[-1]} of tiny.yaml")
        stamps[name] = (out / f"{name}.h5").stat().st_mtime_ns
    # --resume (here, in this process, with nothing injected): only the missing variant is rendered ...
    assert main(argv + ["--resume", "--quiet"]) == 0
    assert "1 rendered, 2 already done, 0 failed" in capsys.readouterr().err
    assert {n: (out / f"{n}.h5").stat().st_mtime_ns for n in stamps} == stamps
    # ... and a second --resume renders nothing (no cluster is even started)
    assert main(argv + ["--resume", "--scheduler", "local:2"]) == 0
    assert "0 rendered, 3 already done, 0 failed" in capsys.readouterr().err
    recs = json.loads((out / "manifest.json").read_text())["scenes"]
    assert all(r["status"] == "done" and r["resumed"] for r in recs)


def test_scheduler_and_worker_started_as_processes(tmp_path):
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    tpl = tmp_path / "tiny.yaml"
    tpl.write_text(TEMPLATE)
    dask_cli = Path(sys.executable).parent / "dask"
    address = f"tcp://127.0.0.1:{port}"
    log = open(tmp_path / "dask.log", "w")
    procs = [subprocess.Popen([str(dask_cli), "scheduler", "--host", "127.0.0.1", "--port", str(port),
                               "--no-dashboard"], stdout=log, stderr=log)]
    try:
        for _ in range(900):  # the scheduler's start takes seconds (minutes on a loaded machine)
            with socket.socket() as s:
                if s.connect_ex(("127.0.0.1", port)) == 0:
                    break
            assert procs[0].poll() is None, (tmp_path / "dask.log").read_text()
            time.sleep(0.1)
        procs.append(subprocess.Popen([str(dask_cli), "worker", address, "--nthreads", "1", "--no-dashboard",
                                       "--host", "127.0.0.1"], stdout=log, stderr=log))
        assert main(["generate", str(tpl), "--variants", "1", "--out-dir", str(tmp_path / "o"),
                     "--scheduler", address]) == 0
    finally:
        for p in reversed(procs):
            p.terminate()
        for p in procs:
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                p.kill()
        log.close()
    rec = json.loads((tmp_path / "o" / "manifest.json").read_text())["scenes"][0]
    assert rec["status"] == "done" and rec["attempts"][0]["worker"].startswith("tcp://127.0.0.1:")
    assert rec["attempts"][0]["render_threads"] == cores()  # the only worker on its machine gets every core
    with Dataset(tmp_path / "o" / "tiny_00000.h5") as ds:
        assert ds.num_events > 0


def test_local_workers_die_with_a_killed_head(tmp_path):
    import psutil

    tpl = tmp_path / "tiny.yaml"
    tpl.write_text(TEMPLATE.replace("duration_s: 0.05", "duration_s: 3.0").replace("t: 0.05", "t: 3.0"))
    out = tmp_path / "out"
    head = subprocess.Popen([sys.executable, "-m", "dvsot.cli", "generate", str(tpl), "--variants", "2",
                             "--out-dir", str(out), "--scheduler", "local:2"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    kids = []
    try:
        for _ in range(600):  # until a worker is rendering (its temp file exists), at most 60 s
            if any(out.glob(".tiny_*.h5.tmp~*")):  # a worker is rendering (dvsot.runtime.staging.temp_name)
                break
            assert head.poll() is None, "the run ended before it could be killed"
            psutil.Process(head.pid).children()  # the head is alive
            time.sleep(0.1)
        kids = psutil.Process(head.pid).children(recursive=True)
        assert len(kids) >= 2
    finally:
        head.kill()
        head.wait()
    gone, alive = psutil.wait_procs(kids, timeout=20)
    for p in alive:
        p.kill()
    assert not alive, [p.cmdline() for p in alive]
