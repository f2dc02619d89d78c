"""Output-path checks every command runs before it starts work."""

import json
import os

import pytest

from dvsot.core.errors import RunError, UserError
from dvsot.runtime import staging
from dvsot.runtime.outputs import output_dir, output_file, replacing, run_outputs


def test_output_file_accepts_a_new_or_existing_file(tmp_path):
    assert output_file(tmp_path / "a.h5", "-o") == tmp_path / "a.h5"
    (tmp_path / "b.h5").write_text("x")
    assert output_file(tmp_path / "b.h5", "-o", inputs=[tmp_path / "c.yaml"]) == tmp_path / "b.h5"


@pytest.mark.parametrize("make, words", [
    (lambda d: (d / "sub").mkdir() or d / "sub", "-o names a directory"),
    (lambda d: d / "nope" / "a.h5", "does not exist"),
])
def test_output_file_refuses(tmp_path, make, words):
    with pytest.raises(UserError, match=words):
        output_file(make(tmp_path), "-o")


def test_output_file_refuses_an_input(tmp_path):
    src = tmp_path / "scene.yaml"
    src.write_text("name: x\n")
    with pytest.raises(UserError, match="would overwrite an input file"):
        output_file(tmp_path / "." / "scene.yaml", "-o", inputs=[tmp_path / "other.yaml", src])


def test_output_dir(tmp_path):
    assert output_dir(tmp_path / "new" / "deeper", "--out-dir") == tmp_path / "new" / "deeper"
    assert not (tmp_path / "new").exists()  # nothing made before there is output
    (tmp_path / "f").write_text("x")
    with pytest.raises(UserError, match="names a file"):
        output_dir(tmp_path / "f", "--out-dir")
    with pytest.raises(UserError, match="is a file, not a directory"):
        output_dir(tmp_path / "f" / "sub", "--out-dir")


# --- run-atomic outputs, temp names, stale temps ---


def test_temp_names_carry_host_pid_and_a_random_token(tmp_path):
    a, b = staging.temp_name(tmp_path / "x.h5"), staging.temp_name(tmp_path / "x.h5")
    assert a != b and a.suffix == ".h5" and a.name.startswith(".x.h5.tmp~")
    assert f"~{os.getpid()}~" in a.name and staging.host() in a.name


def test_a_run_commits_all_its_outputs_or_none(tmp_path):
    (tmp_path / "a.txt").write_text("old a")
    (tmp_path / "b.txt").write_text("old b")
    with pytest.raises(ValueError):
        with run_outputs(tmp_path / "run.json"):
            with replacing(tmp_path / "a.txt") as t:
                t.write_text("new a")
            raise ValueError("the second output failed")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt", "b.txt"]  # no temp, nothing replaced
    assert (tmp_path / "a.txt").read_text() == "old a"
    with run_outputs(tmp_path / "run.json") as run:
        for name in ("a.txt", "b.txt"):
            with replacing(tmp_path / name) as t:
                t.write_text("new " + name[0])
        assert (tmp_path / "a.txt").read_text() == "old a"  # nothing renamed before the end of the run
    assert [(tmp_path / n).read_text() for n in ("a.txt", "b.txt")] == ["new a", "new b"]
    manifest = json.loads((tmp_path / "run.json").read_text())
    assert manifest["run"] == run.run_id and set(manifest["files"]) == {"a.txt", "b.txt"}
    import hashlib

    assert manifest["files"]["b.txt"]["sha256"] == hashlib.sha256(b"new b").hexdigest()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt", "b.txt", "run.json"]


def test_a_journal_left_by_a_dead_process_is_completed_by_the_next_run(tmp_path, monkeypatch):
    real, calls = os.replace, []

    def replace(src, dst):  # the process "dies" after the journal and the first rename
        calls.append(dst)
        if len(calls) == 3:
            raise OSError(5, "killed here")
        real(src, dst)

    (tmp_path / "a.txt").write_text("old a")
    (tmp_path / "b.txt").write_text("old b")
    monkeypatch.setattr(os, "replace", replace)
    with pytest.raises(RunError, match="the next dvsot run"):
        with run_outputs(tmp_path / "run.json"):
            for name in ("a.txt", "b.txt"):
                with replacing(tmp_path / name) as t:
                    t.write_text("new " + name[0])
    monkeypatch.undo()
    assert any(".commit~" in p.name for p in tmp_path.iterdir())  # a reader can tell: the run is incomplete
    monkeypatch.setattr(staging, "pid_alive", lambda pid: False)
    output_file(tmp_path / "a.txt", "-o")  # what every command checks first
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt", "b.txt", "run.json"]
    assert [(tmp_path / n).read_text() for n in ("a.txt", "b.txt")] == ["new a", "new b"]


def test_stale_temps_of_dead_local_processes_are_removed(tmp_path, monkeypatch):
    dead = tmp_path / f".x.h5.tmp~{staging.host()}~999999~0123abcd.h5"
    other_host = tmp_path / ".x.h5.tmp~another-host~999999~0123abcd.h5"
    mine = staging.temp_name(tmp_path / "x.h5")
    legacy = tmp_path / ".x.h5.tmp-999999"
    for p in (dead, other_host, mine, legacy):
        p.write_text("temp")
    monkeypatch.setattr(staging, "pid_alive", lambda pid: pid == os.getpid())
    output_file(tmp_path / "x.h5", "-o")
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([other_host.name, mine.name])


def test_a_symlink_output_is_written_through_to_its_target(tmp_path):
    (tmp_path / "real").mkdir()
    (tmp_path / "real" / "t.txt").write_text("old")
    (tmp_path / "link.txt").symlink_to(tmp_path / "real" / "t.txt")
    output_file(tmp_path / "link.txt", "-o")
    with replacing(tmp_path / "link.txt") as t:
        t.write_text("new")
    assert (tmp_path / "link.txt").is_symlink() and (tmp_path / "real" / "t.txt").read_text() == "new"
    assert sorted(p.name for p in (tmp_path / "real").iterdir()) == ["t.txt"]


def test_a_dir_output_is_replaced_whole(tmp_path):
    (tmp_path / "frames").mkdir()
    (tmp_path / "frames" / "000009.npy").write_text("stale")
    with run_outputs(tmp_path / "run.json") as run:
        staged = run.stage_dir(tmp_path / "frames")
        (staged / "000000.npy").write_text("new")
    assert sorted(p.name for p in (tmp_path / "frames").iterdir()) == ["000000.npy"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["frames", "run.json"]


def test_the_writability_probe_leaves_nothing_when_a_signal_lands_inside_it(tmp_path, monkeypatch):
    """An interrupt between the probe's create and its unlink still removes the probe (SIGTERM raced it once)."""
    import dvsot.runtime.outputs as outputs

    real_close = os.close

    def close_then_interrupt(fd):
        real_close(fd)
        raise KeyboardInterrupt

    monkeypatch.setattr(outputs.os, "close", close_then_interrupt)
    with pytest.raises(KeyboardInterrupt):
        outputs.check_writable(tmp_path, "-o")
    monkeypatch.undo()
    assert list(tmp_path.iterdir()) == []


def test_a_staged_output_is_read_at_its_temp_until_the_commit(tmp_path):
    from dvsot.runtime.outputs import readable, replacing, run_outputs

    out = tmp_path / "a.txt"
    assert readable(out) == out  # no run open
    with run_outputs():
        with replacing(out) as tmp:
            tmp.write_text("new")
        assert not out.exists() and readable(out).read_text() == "new"
        assert readable(tmp_path / "b.txt") == tmp_path / "b.txt"  # not this run's
    assert readable(out) == out and out.read_text() == "new"


def test_an_owned_run_that_fails_leaves_no_directory_it_made(tmp_path):
    from dvsot.runtime.outputs import owned_run, replacing

    root = tmp_path / "a" / "out"
    with pytest.raises(RuntimeError):
        with owned_run(root, "--out", ["x/y/f.txt"]):
            (root / "x" / "y").mkdir(parents=True)
            with replacing(root / "x" / "y" / "f.txt") as tmp:
                tmp.write_text("staged")
            raise RuntimeError("the run fails")
    assert list(tmp_path.iterdir()) == []  # root and its parent a/ were this run's
    # in a directory that was there: only the directories the run made go
    root.mkdir(parents=True)
    (root / "old").mkdir()
    with pytest.raises(RuntimeError):
        with owned_run(root, "--out", ["x/f.txt"]):
            (root / "x").mkdir()
            raise RuntimeError("the run fails")
    assert sorted(p.name for p in root.iterdir()) == ["old"]


def test_a_run_nested_in_an_owned_tree_knows_the_previous_runs_files(tmp_path):
    from dvsot.runtime.outputs import owned_run, replacing, run_dir

    root = tmp_path / "out"

    def write(names):
        with owned_run(root, "--out", names):
            run_dir(root / "inner", "--inner", [n.removeprefix("inner/") for n in names if n.startswith("inner/")])
            for n in names:
                (root / n).parent.mkdir(parents=True, exist_ok=True)
                with replacing(root / n) as tmp:
                    tmp.write_text(n)

    write(["inner/a.txt", "inner/b.txt", "top.txt"])
    write(["inner/a.txt", "top.txt"])  # inner/b.txt: the outer run's previous file, not a stranger, and gone now
    assert sorted(str(p.relative_to(root)) for p in root.rglob("*") if p.is_file()) == [
        "inner/a.txt", "run.json", "top.txt"]
    (root / "inner" / "mine.txt").write_text("mine")
    with pytest.raises(UserError, match="mine.txt"):
        write(["inner/a.txt", "top.txt"])
