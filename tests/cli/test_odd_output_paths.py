"""Outputs that are not regular files, export side files, colliding result trees and non-regular inputs: each refused
in one line (exit 2) before any work, with nothing at the path replaced."""

import os
import socket
import stat
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from synthetic import MINIMAL_SCENE, moving_square_file  # noqa: E402

from dvsot.cli import main  # noqa: E402

SHIPPED = Path(__file__).resolve().parents[2] / "sctn" / "checkpoints" / "sctn_dvsot21.pt"


@pytest.fixture(scope="module")
def data(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("odd")
    moving_square_file(d / "seq.h5", width=48, height=36, size=10, duration_ms=40, split="train")
    np.save(d / "f.npy", np.random.default_rng(0).uniform(0.1, 1, (4, 12, 16)).astype(np.float32))
    (d / "ev.txt").write_text("16 12\n0.000001 1 2 1\n0.02 3 4 0\n")
    (d / "q.yaml").write_text(MINIMAL_SCENE.replace("duration_s: 0.1", "duration_s: 0.02"))
    return d


def commands(d: Path, out: str) -> dict[str, list[str]]:
    """Every command that writes a file, with `out` as its -o."""
    return {
        "generate": ["generate", str(d / "q.yaml"), "-o", out, "--quiet"],
        "simulate": ["simulate", str(d / "f.npy"), "--fps", "100", "-o", out, "--quiet"],
        "import": ["import", str(d / "ev.txt"), "-o", out],
        "export": ["export", str(d / "seq.h5"), "-o", out],
        "train": ["train", "--data", str(d / "seq.h5"), "-o", out, "--epochs", "1", "--quiet"],
        "export-model": ["export-model", str(SHIPPED), "-o", out],
    }


def _fifo(p: Path) -> Path:
    os.mkfifo(p)
    return p


def _socket(p: Path) -> Path:
    s = socket.socket(socket.AF_UNIX)
    s.bind(str(p))
    s.close()
    return p


def _device(p: Path) -> Path:
    # a private node of the null device (never the system's /dev/null: a regression would replace it), reached through
    # a symlink, as an output given as a link to a device is
    node = p.with_name("null-device")
    try:
        os.mknod(node, stat.S_IFCHR | 0o600, os.makedev(1, 3))
    except (PermissionError, OSError):
        pytest.skip("making a device node needs root")
    p.symlink_to(node)
    return p


def _directory(p: Path) -> Path:
    p.mkdir()
    return p


SUFFIX = {"generate": ".h5", "simulate": ".h5", "import": ".h5", "export": ".csv", "train": ".pt",
          "export-model": ".nir"}


@pytest.mark.parametrize("command", list(SUFFIX))
@pytest.mark.parametrize("make, words", [(_fifo, "names a FIFO"), (_socket, "names a socket"),
                                         (_device, "names a character device"), (_directory, "names a directory"),
                                         (None, "ends in a slash")])
def test_an_output_that_is_not_a_regular_file_is_refused_before_any_work(tmp_path, data, capsys, command, make,
                                                                         words):
    if make is None:
        out = str(tmp_path / f"newdir{SUFFIX[command]}") + "/"
    else:
        out = str(make(tmp_path / f"o{SUFFIX[command]}"))
    before = sorted((p.name, stat.S_IFMT(p.lstat().st_mode)) for p in tmp_path.iterdir())
    assert main(commands(data, out)[command]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and words in err[0], err
    assert sorted((p.name, stat.S_IFMT(p.lstat().st_mode)) for p in tmp_path.iterdir()) == before


def test_a_preview_and_a_bench_result_that_are_fifos_are_refused(tmp_path, data, capsys):
    _fifo(tmp_path / "q.gif")
    assert main(["generate", str(data / "q.yaml"), "-o", str(tmp_path / "q.h5"), "--preview", "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "q.gif" in err[0] and "names a FIFO" in err[0], err
    d = tmp_path / "data"
    d.mkdir()
    _bench_file(d / "s.h5")
    (tmp_path / "b" / "kcf").mkdir(parents=True)
    _fifo(tmp_path / "b" / "kcf" / "s.txt")
    assert main(["bench", "--tracker", "kcf", "--data", str(d), "--out", str(tmp_path / "b"), "--quiet",
                 "--no-energy"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "s.txt" in err[0] and "names a FIFO" in err[0], err


@pytest.mark.parametrize("side", ["x.csv.boxes.csv", "x.csv.objects.csv"])
def test_a_side_file_that_is_not_a_regular_file_is_refused(tmp_path, data, capsys, side):
    _fifo(tmp_path / side)
    assert main(["export", str(data / "seq.h5"), "-o", str(tmp_path / "x.csv")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "names a FIFO" in err[0] and side in err[0], err
    assert not (tmp_path / "x.csv").exists()


def test_export_side_files_belong_to_their_output(tmp_path, data, capsys):
    out_csv, out_txt = tmp_path / "x.csv", tmp_path / "x.txt"
    assert main(["export", str(data / "seq.h5"), "-o", str(out_csv)]) == 0
    assert main(["export", str(data / "seq.h5"), "-o", str(out_txt)]) == 0
    boxes_csv, boxes_txt = tmp_path / "x.csv.boxes.csv", tmp_path / "x.txt.boxes.csv"
    assert boxes_csv.is_file() and boxes_txt.is_file() and not (tmp_path / "x.boxes.csv").exists()
    help_text = capsys.readouterr()
    # an output named as another output's side file is refused, and so is a side file over a file that is no table
    for argv, words in [(["-o", str(boxes_csv)], "names the boxes table of the export"),
                        (["-o", str(tmp_path / "y.csv")], "is not an export's boxes table")]:
        (tmp_path / "y.csv.boxes.csv").write_text("t,x,y,p\n1,2,3,1\n")  # the events of an export named so
        before = boxes_csv.read_bytes()
        assert main(["export", str(data / "seq.h5"), *argv]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and words in err[0], err
        assert boxes_csv.read_bytes() == before and (tmp_path / "y.csv.boxes.csv").read_text().startswith("t,x,y,p")
    # a re-export that writes no boxes takes the old box table away with the old events, in the same commit
    assert main(["export", str(data / "seq.h5"), "-o", str(out_csv), "--no-boxes"]) == 0
    assert out_csv.is_file() and not boxes_csv.exists() and boxes_txt.is_file()
    capsys.readouterr()
    with pytest.raises(SystemExit):
        main(["export", "--help"])
    assert "x.csv.boxes.csv" in capsys.readouterr().out and help_text is not None


def _bench_file(path: Path) -> Path:
    return moving_square_file(path, width=48, height=36, size=10, duration_ms=40, split="test")


@pytest.mark.parametrize("names", [("a", "a.txt"), ("times", "times.txt"), ("timing.csv",), ("Seq", "seq")])
def test_bench_refuses_a_result_tree_that_collides_before_tracking(tmp_path, capsys, names):
    d = tmp_path / "data"
    d.mkdir()
    for n in names:
        _bench_file(d / f"{n}.h5")
    out = tmp_path / "b"
    assert main(["bench", "--tracker", "kcf", "--data", str(d), "--out", str(out), "--protocol", "ope",
                 "--jobs", "1", "--quiet", "--no-energy"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and ("written as a file and is also the directory" in err[0] or "only in case" in err[0]
                              or "same result file" in err[0]), err
    assert not out.exists()


def _undigested_checkpoint(path: Path) -> Path:
    blob = torch.load(SHIPPED, map_location="cpu", weights_only=True)
    blob["meta"] = {k: v for k, v in blob["meta"].items() if k != "weights_sha256"}
    torch.save(blob, path)
    return path


def test_a_fifo_where_an_input_file_is_read_is_refused_without_waiting(tmp_path):
    ckpt = _undigested_checkpoint(tmp_path / "c.pt")
    _fifo(tmp_path / "c.json")  # the checkpoint's side file: opening it would wait for a writer forever
    r = subprocess.run([sys.executable, "-m", "dvsot.cli", "export-model", ckpt, "-o", tmp_path / "x.nir"],
                       capture_output=True, text=True, timeout=120)
    err = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(err) == 1 and "c.json" in err[0] and "FIFO" in err[0], err
    assert not (tmp_path / "x.nir").exists()


def test_the_regular_input_helper(tmp_path):
    from dvsot.core.errors import UserError
    from dvsot.runtime.inputs import open_input, read_text, regular_input

    (tmp_path / "a.txt").write_text("hello")
    assert read_text(tmp_path / "a.txt") == "hello" and regular_input(tmp_path / "a.txt") == tmp_path / "a.txt"
    assert read_text(tmp_path / "none.txt", missing_ok=True) is None
    for p in (_fifo(tmp_path / "p"), _socket(tmp_path / "s"), Path("/dev/null"), tmp_path):  # read only
        with pytest.raises(UserError, match="not a regular file to read"):
            open_input(p, "rb", "a test input")
    with pytest.raises(UserError, match="no such file"):
        regular_input(tmp_path / "none.txt")


@pytest.mark.parametrize("module", ["..x", "x/y.py", "a..b"])
def test_a_tracker_module_that_is_no_module_name_is_one_line(tmp_path, capsys, module):
    assert main(["bench", "--tracker", "kcf", "--tracker-module", module, "--out", str(tmp_path / "b")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"dvsot bench: error: --tracker-module {module}: not a module name (dotted Python identifiers, "
                   "e.g. mypkg.trackers)"], err
