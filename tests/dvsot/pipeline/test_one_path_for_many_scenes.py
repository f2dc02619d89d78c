"""`--jobs N` is `--scheduler local:N`: the same two scenes give the same dataset files and the same manifest."""

import json

import pytest

from dvsot.cli import main
from dvsot.dataset import Dataset

pytestmark = pytest.mark.blender

SCENE = """name: {name}
duration_s: 0.04
sensor: {{width: 64, height: 48, focal_mm: 35}}
camera:
  keyframes: [{{t: 0, location: [0, -10, 0], look_at: [0, 0, 0]}}]
target:
  shape: {shape}
  size_m: 1.5
  material: {{color: [0.9, 0.9, 0.9]}}
  trajectory:
    interpolation: linear
    keyframes: [{{t: 0, location: [-1.0, 0, 0]}}, {{t: 0.04, location: [1.0, 0, 0]}}]
background:
  material: {{color: [0.1, 0.1, 0.1], emission: 0.3}}
lights: []
world: {{color: [0.5, 0.5, 0.5], strength: 1.0}}
sampling: {{min_rate_hz: 200}}
"""
# fields of a manifest that say where and how long, not what: the worker's address and CPUs, seconds
WHERE_AND_WHEN = {"worker", "wall_s", "task_s", "cpu_s", "cpus"}


def manifest(out_dir):
    m = json.loads((out_dir / "manifest.json").read_text())
    for rec in m["scenes"]:
        rec["file"] = rec["file"].rpartition("/")[2]  # each run has its own directory
        for a in rec["attempts"]:
            for k in WHERE_AND_WHEN:
                a.pop(k, None)
    return m["scenes"]


def test_jobs_2_and_scheduler_local_2_give_the_same_files_and_manifest(tmp_path, capsys):
    scenes = []
    for name, shape in (("a", "cube"), ("b", "sphere")):
        p = tmp_path / f"{name}.yaml"
        p.write_text(SCENE.format(name=name, shape=shape))
        scenes.append(str(p))
    runs = {"jobs": ["--jobs", "2"], "scheduler": ["--scheduler", "local:2"]}
    for run, flags in runs.items():
        assert main(["generate", *scenes, "--out-dir", str(tmp_path / run), "--quiet", *flags]) == 0
        # both went through the one many-scene path: one JSON record per scene, and the run's summary line
        out = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
        assert sorted(r["name"] for r in out) == ["a", "b"] and all(r["status"] == "done" for r in out)
    jobs, scheduler = tmp_path / "jobs", tmp_path / "scheduler"
    for name in ("a", "b"):
        with Dataset(jobs / f"{name}.h5") as ds:
            assert ds.num_events > 0
        # byte-identical: the files carry no wall-clock time, host or path of their own
        assert (jobs / f"{name}.h5").read_bytes() == (scheduler / f"{name}.h5").read_bytes()
    assert manifest(jobs) == manifest(scheduler)
    assert [r["status"] for r in manifest(jobs)] == ["done", "done"]
    assert {p.name for p in jobs.iterdir()} == {p.name for p in scheduler.iterdir()} == {"a.h5", "b.h5",
                                                                                          "manifest.json"}
