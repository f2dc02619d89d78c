"""No long silences: a scene file's size is bounded (so is its copy in the dataset file),
a scene file that would block is refused at once, and generate says what it does before its bar appears."""

from __future__ import annotations

import os
import subprocess
import sys
import time

import pytest
from synthetic import MINIMAL_SCENE

from dvsot.cli import main


def test_a_huge_scene_file_is_refused_at_once_naming_the_bound(tmp_path, capsys):
    scene = tmp_path / "big.yaml"
    keyframes = "".join(f"    - {{t: {i * 1e-4:.4f}, location: [0, 0, 0]}}\n" for i in range(1, 20_000))
    text = MINIMAL_SCENE.replace("    keyframes: [{t: 0, location: [0, 0, 0]}]\n",
                                 "    keyframes:\n    - {t: 0, location: [0, 0, 0]}\n" + keyframes)
    scene.write_text(text * 1 + "#" * (50 << 20) + "\n")  # 50 MB: it used to parse for 95 s
    start = time.perf_counter()
    assert main(["generate", str(scene), "-o", str(tmp_path / "o.h5")]) == 2
    assert time.perf_counter() - start < 5
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and str(scene) in err and "bound of 1048576 bytes (1 MB)" in err, err


def test_a_scene_fifo_is_refused_without_waiting_for_a_writer(tmp_path):
    scene = tmp_path / "s.yaml"
    os.mkfifo(scene)
    env = dict(
        os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p and f"{os.sep}bpy{os.sep}" not in p)
    )  # not bpy's script folders: they hide bpy
    r = subprocess.run([sys.executable, "-m", "dvsot.cli", "generate", str(scene), "-o", str(tmp_path / "o.h5")],
                       capture_output=True, text=True, timeout=60, env=env)
    assert r.returncode == 2 and "is a FIFO (named pipe), not a scene file" in r.stderr, r.stderr


@pytest.mark.blender
def test_generate_says_what_it_does_before_the_bar(tmp_path):
    scene = tmp_path / "s.yaml"
    scene.write_text(MINIMAL_SCENE.replace("duration_s: 0.1", "duration_s: 0.02\nsensor: {width: 32, height: 24}"))
    env = dict(
        os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p and f"{os.sep}bpy{os.sep}" not in p)
    )  # not bpy's script folders: they hide bpy
    r = subprocess.run([sys.executable, "-m", "dvsot.cli", "generate", str(scene), "-o", str(tmp_path / "o.h5")],
                       capture_output=True, text=True, timeout=300, env=env)
    assert r.returncode == 0, r.stderr
    lines = r.stderr.replace("\r", "\n").splitlines()
    first_bar = next(i for i, ln in enumerate(lines) if "frame" in ln and "|" in ln)
    said = " ".join(lines[:first_bar])
    assert "planning render times for 0.02 s" in said and "building the Blender scene" in said, lines[:first_bar + 1]
