"""The right words: a directory or FIFO is not "no such file", a bad format_version is
not Python's int() message, and an interrupted run's progress bar is not redrawn under "interrupted"."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time

import h5py
import numpy as np
import pytest
from synthetic import MINIMAL_SCENE

from dvsot.cli import main
from dvsot.dataset import DatasetWriter


def error_line(argv, capsys) -> str:
    assert main(argv) == 2, argv
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "Traceback" not in err, err
    return err


@pytest.mark.parametrize("kind, words", [("dir", "is a directory"), ("fifo", "is a FIFO")])
def test_a_directory_or_fifo_named_h5_is_named_for_what_it_is(tmp_path, capsys, kind, words):
    path = tmp_path / "x.h5"
    path.mkdir() if kind == "dir" else os.mkfifo(path)
    argvs = [["info", str(path)], ["train", "--data", str(tmp_path / "*.h5"), "-o", str(tmp_path / "c.pt")]]
    if kind == "fifo":  # bench --data DIR reads the .h5 files in DIR: a directory named x.h5 is one to look in
        argvs.append(["bench", "--tracker", "rct", "--data", str(path), "--out", str(tmp_path / "b")])
    for argv in argvs:
        err = error_line(argv, capsys)
        assert str(path) in err and words in err and "no such" not in err, err


@pytest.mark.parametrize("setup, words", [
    (lambda d: ("mesh: " + str(d / "m.obj"), (d / "m.obj").mkdir()), "is a directory"),
    (lambda d: ("mesh: " + str(d / "p.obj"), os.mkfifo(d / "p.obj")), "is a FIFO"),
    (lambda d: ("shape: cube\n  material: {texture: {type: image, path: /dev/zero}}", None), "is a character device"),
])
def test_a_mesh_or_texture_that_is_not_a_regular_file_is_named_for_what_it_is(tmp_path, capsys, setup, words):
    line, _ = setup(tmp_path)
    scene = tmp_path / "s.yaml"
    scene.write_text(MINIMAL_SCENE.replace("shape: cube", line))
    err = error_line(["generate", str(scene), "-o", str(tmp_path / "o.h5")], capsys)
    assert str(scene) in err and words in err and "not found" not in err, err


@pytest.mark.parametrize("value", ["one", "1.5", b"2x"])
def test_a_bad_format_version_names_the_attribute(tmp_path, capsys, value):
    path = tmp_path / "v.h5"
    with DatasetWriter(path, 8, 8) as w:
        w.close(20_000)
    with h5py.File(path, "a") as f:
        f.attrs["format_version"] = value
    err = error_line(["info", str(path)], capsys)
    assert "'format_version'" in err and "expected an integer" in err and "invalid literal" not in err, err


def test_an_interrupted_bar_is_not_redrawn_under_the_message(tmp_path):
    np.save(tmp_path / "s.npy", np.random.default_rng(0).random((3000, 24, 32), dtype=np.float32))
    env = dict(
        os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p and f"{os.sep}bpy{os.sep}" not in p)
    )  # not bpy's script folders: they hide bpy
    proc = subprocess.Popen([sys.executable, "-m", "dvsot.cli", "simulate", str(tmp_path / "s.npy"), "--fps", "1000",
                             "-o", str(tmp_path / "o.h5")], stderr=subprocess.PIPE, env=env)
    chunks: list[bytes] = []
    reader = threading.Thread(target=lambda: chunks.extend(iter(lambda: proc.stderr.read1(4096), b"")))
    reader.start()
    deadline = time.time() + 60
    while b"frame/s" not in b"".join(chunks) and time.time() < deadline:  # the bar has drawn a rate
        time.sleep(0.05)
    proc.send_signal(signal.SIGINT)
    assert proc.wait(60) == 130
    reader.join()
    err = b"".join(chunks).decode()
    last = err.rstrip("\n").split("\n")[-1]  # the message is the last line: no bar drawn after it
    assert "frame/s" in err and last.startswith("dvsot simulate: interrupted") and "\r" not in last, err[-300:]
    assert not (tmp_path / "o.h5").exists()


def test_a_checkpoint_or_timestamps_that_are_not_regular_files_are_named(tmp_path, capsys):
    (tmp_path / "ck.pt").mkdir()
    with DatasetWriter(tmp_path / "d.h5", 16, 16, attrs={"split": "test"}) as w:
        w.append_boxes([0, 40_000], [[2, 2, 5, 5], [2, 2, 5, 5]])
        w.close(40_000)
    err = error_line(["bench", "--tracker", "sctn", "--checkpoint", str(tmp_path / "ck.pt"), "--data",
                      str(tmp_path / "d.h5"), "--out", str(tmp_path / "b")], capsys)
    assert "ck.pt: is a directory, not a checkpoint file" in err, err
    np.save(tmp_path / "s.npy", np.zeros((3, 4, 4), np.float32))
    os.mkfifo(tmp_path / "t.txt")
    env = dict(
        os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p and f"{os.sep}bpy{os.sep}" not in p)
    )  # not bpy's script folders: they hide bpy
    r = subprocess.run([sys.executable, "-m", "dvsot.cli", "simulate", str(tmp_path / "s.npy"), "--timestamps",
                        str(tmp_path / "t.txt"), "-o", str(tmp_path / "o.h5")], capture_output=True, text=True,
                       timeout=60, env=env)
    assert r.returncode == 2 and "is a FIFO (named pipe)" in r.stderr, r.stderr


def test_an_error_mid_run_is_the_last_line_not_the_bar(tmp_path):
    stack = np.random.default_rng(0).random((40, 24, 32), dtype=np.float32)
    stack[30, 3, 3] = np.nan  # a bad frame after the bar has been drawn
    np.save(tmp_path / "s.npy", stack)
    env = dict(
        os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p and f"{os.sep}bpy{os.sep}" not in p)
    )  # not bpy's script folders: they hide bpy
    r = subprocess.run([sys.executable, "-m", "dvsot.cli", "simulate", str(tmp_path / "s.npy"), "--fps", "1000",
                        "-o", str(tmp_path / "o.h5")], capture_output=True, text=True, timeout=300, env=env)
    last = r.stderr.rstrip("\n").split("\n")[-1]
    assert r.returncode == 2 and "frame/s" in r.stderr and last.startswith("dvsot simulate: error:"), r.stderr[-300:]
    assert "frame 30" in last and "\r" not in last
