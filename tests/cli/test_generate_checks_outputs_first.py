"""`dvsot generate` checks every output path before it renders anything (no Blender needed here)."""

import hashlib

import pytest
from synthetic import MINIMAL_SCENE

from dvsot.cli import main

SCENE = MINIMAL_SCENE.replace("duration_s: 0.1", "duration_s: 0.02\nsensor: {width: 64, height: 48}")


def digest(path):
    return hashlib.md5(path.read_bytes()).hexdigest()


@pytest.fixture
def scene(tmp_path):
    p = tmp_path / "cli.yaml"
    p.write_text(SCENE)
    return p


def snapshot(root):
    return sorted((str(p.relative_to(root)), p.is_dir() or digest(p)) for p in root.rglob("*"))


@pytest.mark.parametrize("extra, words", [
    (lambda d, s: ["-o", str(d / "adir")], "-o names a directory, not a file"),
    (lambda d, s: ["--out-dir", str(d / "afile")], "--out-dir names a file, not a directory"),
    (lambda d, s: ["--out-dir", str(d / "afile" / "sub")], "is a file, not a directory"),
    (lambda d, s: ["-o", str(d / "o.h5"), "--keep-frames", str(d / "afile")], "--keep-frames names a file"),
    (lambda d, s: ["-o", str(d / "prev.h5"), "--preview"], "--preview would write this path, a directory"),
    (lambda d, s: ["-o", str(s)], "-o would overwrite an input file"),
    (lambda d, s: [str(s), "--out-dir", str(d / "multi")], "gives the same output"),
    (lambda d, s: ["--out-dir", str(d / "outs")], "the output of"),  # outs/t.h5 is a directory
    (lambda d, s: ["-o", str(d / "x.gif"), "--preview"], "--preview would write this path, the dataset file itself"),
    (lambda d, s: ["-o", str(d / "m.obj")], "-o would overwrite an input file"),  # the scene's own mesh
    (lambda d, s: ["-o", str(d / "o.h5"), "--duration", "nan"], "field 'duration_s' = nan (an override)"),
])
def test_bad_output_paths_fail_before_any_work(tmp_path, scene, capsys, extra, words):
    (tmp_path / "adir").mkdir()
    (tmp_path / "prev.gif").mkdir()
    (tmp_path / "afile").write_text("keep me")
    (tmp_path / "prev.h5").write_bytes(b"an earlier dataset")
    (tmp_path / "outs" / "t.h5").mkdir(parents=True)
    (tmp_path / "m.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\nf 1 3 4\nf 2 3 4\n")
    scene.write_text(SCENE.replace("shape: cube", "mesh: m.obj"))
    before = snapshot(tmp_path)
    assert main(["generate", str(scene), *extra(tmp_path, scene), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and words in err[0], err
    assert snapshot(tmp_path) == before  # nothing made, nothing changed


@pytest.mark.parametrize("argv, words", [
    (["train", "--loss", "bogus"], "dvsot train: error: argument --loss: invalid choice: 'bogus'"),
    (["bench", "--max-segments", "abc"], "dvsot bench: error: argument --max-segments: invalid int value: 'abc'"),
    ([], "dvsot: error: the following arguments are required: COMMAND"),
])
def test_a_bad_flag_is_one_line_with_exit_status_2(capsys, argv, words):
    with pytest.raises(SystemExit) as info:
        main(argv)
    err = capsys.readouterr().err.strip().splitlines()
    assert info.value.code == 2 and len(err) == 1 and err[0].startswith(words), err
