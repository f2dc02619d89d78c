"""`dvsot info FILE | head -1`: a reader that closes the pipe early gets no traceback, only SIGPIPE's exit status."""

from __future__ import annotations

import os
import signal
import subprocess
import sys

import numpy as np

from tests.dvsot.dataset.test_round_trip import random_events, write_file


def test_info_into_a_closed_pipe_exits_quietly(tmp_path):
    path = tmp_path / "seq.h5"
    write_file(path, random_events(np.random.default_rng(0), 500, 20_000), 20_000)
    read_end, write_end = os.pipe()
    os.close(read_end)  # the reader is gone before the first line is written, as after `head -1` read its line
    env = dict(os.environ, PYTHONPATH=os.getcwd() + os.pathsep + os.environ.get("PYTHONPATH", ""))
    done = subprocess.run([sys.executable, "-m", "dvsot.cli", "info", str(path), str(path), "--json"],
                          stdout=write_end, stderr=subprocess.PIPE, text=True, env=env, timeout=60)
    os.close(write_end)
    assert done.stderr == ""
    assert done.returncode == 128 + signal.SIGPIPE


def test_info_into_head_prints_its_first_line(tmp_path):
    path = tmp_path / "seq.h5"
    write_file(path, random_events(np.random.default_rng(0), 500, 20_000), 20_000)
    env = dict(os.environ, PYTHONPATH=os.getcwd() + os.pathsep + os.environ.get("PYTHONPATH", ""))
    done = subprocess.run(f"'{sys.executable}' -m dvsot.cli info '{path}' '{path}' | head -1", shell=True,
                          capture_output=True, text=True, env=env, timeout=60)
    assert done.stdout == f"{path}  (seq)\n" and done.stderr == "" and done.returncode == 0
