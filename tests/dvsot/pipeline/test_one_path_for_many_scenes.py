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


TEMPLATE = SCENE.format(name="tiny", shape="{choice: [cube, sphere]}").replace("size_m: 1.5",
                                                                                "size_m: {uniform: [1.2, 1.8]}")


def test_generate_variants_draws_and_renders_in_one_call(tmp_path):
    import dvsot
    from dvsot.scene.templates import draw_variants, read_template

    tpl = tmp_path / "tiny.yaml"
    tpl.write_text(TEMPLATE)
    out = tmp_path / "out"
    m = dvsot.generate_variants(tpl, 2, out)  # here, in this process: no scheduler
    assert m.path == out / "manifest.json" and not m.failed()
    drawn = draw_variants(read_template(tpl), 2)
    assert [(r["name"], r["variant"], r["seed"], r["status"]) for r in m.records] == [
        (v.name, v.index, v.seed, "done") for v in drawn]
    assert json.loads(m.path.read_text())["scenes"] == m.records
    for v in drawn:
        with Dataset(out / f"{v.name}.h5") as ds:
            assert ds.num_events > 0 and ds.attrs["scene_yaml"] == v.text("tiny.yaml")


@pytest.mark.parametrize("n, words", [(0, "n (variants to draw) must be >= 1, got 0"),
                                      (2.5, "n (variants to draw) must be an integer, got 2.5")])
def test_generate_variants_names_a_bad_count_before_any_work(tmp_path, n, words):
    import dvsot

    tpl = tmp_path / "tiny.yaml"
    tpl.write_text(TEMPLATE)
    with pytest.raises(dvsot.UserError, match=words.replace("(", r"\(").replace(")", r"\)")):
        dvsot.generate_variants(tpl, n, tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_several_scenes_here_keep_their_frames_each_in_its_own_directory(tmp_path, capsys):
    scenes = []
    for name, shape in (("a", "cube"), ("b", "sphere")):
        p = tmp_path / f"{name}.yaml"
        p.write_text(SCENE.format(name=name, shape=shape))
        scenes.append(str(p))
    out, keep = tmp_path / "out", tmp_path / "frames"
    assert main(["generate", *scenes, "--out-dir", str(out), "--keep-frames", str(keep), "--quiet"]) == 0
    recs = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert [(r["name"], r["status"]) for r in recs] == [("a", "done"), ("b", "done")]
    assert [r["status"] for r in json.loads((out / "manifest.json").read_text())["scenes"]] == ["done", "done"]
    for name in ("a", "b"):
        with Dataset(out / f"{name}.h5") as ds:
            assert ds.num_events > 0
        assert len(list((keep / name).glob("*.npy"))) >= 8  # min rate 200 Hz over 40 ms
