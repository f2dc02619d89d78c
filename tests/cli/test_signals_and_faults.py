"""Faults driven as a user meets them: real signals to a running command, SIGKILL of a
parent with workers, a read-only directory, a full disk, symlinks and reused --keep-frames directories.

Read-only directories and full disks are real mounts (tmpfs) when the tests run as root, since root
ignores file modes; as another user a read-only directory is a chmod 555 one and the full-disk test
is skipped (no mount without root).
"""

import hashlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
QUICKSTART = ROOT / "blender_scenes" / "quickstart.yaml"
TINY_RENDER = ["--resolution", "160x120", "--duration", "0.2", "--quiet"]
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from processes import alive, children, dvsot, names, wait_for  # noqa: E402
from synthetic import moving_square_file  # noqa: E402


@pytest.fixture(autouse=True)
def _no_leftover_processes(monkeypatch):
    """Every process a test starts is killed when the test ends, even if it failed midway."""
    started = []
    real = subprocess.Popen.__init__

    def init(self, *a, **k):
        real(self, *a, **k)
        started.append(self)

    monkeypatch.setattr(subprocess.Popen, "__init__", init)
    yield
    for p in started:
        if p.poll() is None:
            p.kill()
            p.wait()


def run(*args: str, timeout: float = 120) -> subprocess.CompletedProcess:
    return subprocess.run(dvsot(*args), capture_output=True, text=True, timeout=timeout)


def temps(d: Path) -> list[str]:
    return [n for n in names(d) if ".tmp" in n or ".commit~" in n]


def writer_temp(d: Path, name: str = "x.h5") -> bool:
    """Whether the staged file of `name` exists (not just the writability probe, which comes and goes first)."""
    return any(n.startswith(f".{name}.tmp") for n in names(d))


def frames_stack(path: Path, n: int = 120, w: int = 160, h: int = 120) -> Path:
    """A .npy (T, H, W) stack of noisy frames: many events, so writing them takes a moment."""
    rng = np.random.default_rng(0)
    np.save(path, rng.uniform(0.05, 1.0, size=(n, h, w)).astype(np.float32))
    return path


@pytest.fixture
def mount_dir(tmp_path):
    """mount(name, options) -> a fresh tmpfs directory under tmp_path (root only), unmounted afterwards."""
    made = []

    def mount(name: str, options: str) -> Path:
        if os.geteuid() != 0:
            pytest.skip("needs root to mount a tmpfs")
        d = tmp_path / name
        d.mkdir()
        r = subprocess.run(["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(d)], capture_output=True)
        if r.returncode:
            pytest.skip(f"cannot mount a tmpfs here: {r.stderr.decode().strip()}")
        made.append(d)
        return d

    yield mount
    for d in made:
        subprocess.run(["umount", "-l", str(d)], capture_output=True)


@pytest.fixture
def readonly_dir(tmp_path, mount_dir):
    """An empty directory nobody can write in: a read-only tmpfs (root ignores modes), else chmod 555."""
    if os.geteuid() == 0:
        yield mount_dir("ro", "ro,size=64k")
        return
    d = tmp_path / "ro"
    d.mkdir()
    d.chmod(0o555)
    yield d
    d.chmod(0o755)


# --- 1, 6: SIGINT and SIGTERM stop generate between frames: nothing replaced, no temp, one line ---

@pytest.mark.blender
@pytest.mark.parametrize("sig, status", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_a_signal_stops_generate_and_keeps_the_old_output(tmp_path, sig, status):
    out = tmp_path / "x.h5"
    out.write_bytes(b"the previous dataset")
    p = subprocess.Popen(dvsot("generate", QUICKSTART, *TINY_RENDER, "-o", out), stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True)
    wait_for(lambda: temps(tmp_path) or p.poll() is not None)  # rendering has started
    time.sleep(0.3)  # a few frames in
    p.send_signal(sig)
    _, err = p.communicate(timeout=60)
    assert p.returncode == status, err
    assert err.strip().splitlines() == [f"dvsot generate: interrupted ({signal.Signals(sig).name})"]
    assert out.read_bytes() == b"the previous dataset" and names(tmp_path) == ["x.h5"]


# --- 2: killing the parent of --jobs ends its workers, and they replace nothing ---

@pytest.mark.blender
def test_workers_die_with_their_parent(tmp_path):
    text = QUICKSTART.read_text()
    scenes = []
    for name in ("fa", "fb", "fc"):
        s = tmp_path / f"{name}.yaml"
        s.write_text(text.replace("name: quickstart", f"name: {name}"))
        scenes.append(s)
    d = tmp_path / "d"
    d.mkdir()
    (d / "fa.h5").write_bytes(b"old a")
    p = subprocess.Popen(dvsot("generate", *scenes, "--out-dir", d, "--jobs", "2", *TINY_RENDER),
                         stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    assert "name: fa" in scenes[0].read_text()
    staged = lambda: any(writer_temp(d, f"{n}.h5") for n in ("fa", "fb", "fc"))  # noqa: E731
    wait_for(lambda: (staged() and len(children(p.pid)) >= 2) or p.poll() is not None)  # a worker is writing
    kids = children(p.pid)
    p.kill()
    p.wait()
    assert len(kids) >= 2, kids  # two workers (and multiprocessing's resource tracker)
    wait_for(lambda: not any(alive(k) for k in kids), timeout=120, step=0.05)
    time.sleep(1.0)
    # no new file, no temp (the run's manifest, written before any render, says what was done: nothing)
    assert (d / "fa.h5").read_bytes() == b"old a" and [n for n in names(d) if n != "manifest.json"] == ["fa.h5"]


# --- 3: an unwritable output is found before any work ---

@pytest.fixture(scope="module")
def train_file(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("faults_data")
    return moving_square_file(d / "syn.h5", width=64, height=48, size=12, duration_ms=60, split="train")


@pytest.fixture(scope="module")
def test_file(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("faults_test_data")
    return moving_square_file(d / "seq.h5", width=64, height=48, size=12, duration_ms=60, split="test")


@pytest.mark.parametrize("case", ["train", "bench", "generate", "generate-out-dir", "simulate"])
def test_an_unwritable_output_fails_before_any_work(tmp_path, readonly_dir, train_file, test_file, case):
    ro = readonly_dir
    argv = {
        "train": ["train", "--data", train_file, "-o", ro / "c.pt", "--epochs", "1", "--segments-per-epoch", "2",
                  "--batch-segments", "1", "--channels", "2", "2", "2", "--fc", "4", "4", "--threads", "1", "--quiet"],
        "bench": ["bench", "--tracker", "rct", "--data", test_file, "--out", ro / "b", "--jobs", "1", "--quiet"],
        "generate": ["generate", QUICKSTART, *TINY_RENDER, "-o", ro / "x.h5"],
        "generate-out-dir": ["generate", QUICKSTART, *TINY_RENDER, "--out-dir", ro / "sub"],
        "simulate": ["simulate", frames_stack(tmp_path / "f.npy", n=3), "--fps", "1000", "-o", ro / "x.h5",
                     "--quiet"],
    }[case]
    t0 = time.monotonic()
    r = run(*argv)
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "cannot write in" in lines[0] and str(ro) in lines[0], lines
    assert names(ro) == [] and time.monotonic() - t0 < 30  # refused up front: no rendering, training or tracking


# --- 4: a full disk is one line naming the output, exit 1, the old file kept, no temp ---

@pytest.mark.parametrize("case", ["simulate", "train"])
def test_a_full_disk_is_one_line_and_keeps_the_old_output(tmp_path, mount_dir, train_file, case):
    disk = mount_dir("disk", "size=1m")
    out = disk / ("x.h5" if case == "simulate" else "c.pt")
    out.write_bytes(b"old output")
    (disk / "filler").write_bytes(b"\0" * (1024 * 1024 - 16 * 1024))  # about 12 KB left
    if case == "simulate":
        argv = ["simulate", frames_stack(tmp_path / "f.npy", n=20), "--fps", "1000", "-o", out, "--quiet"]
    else:
        argv = ["train", "--data", train_file, "-o", out, "--epochs", "1", "--segments-per-epoch", "2",
                "--batch-segments", "1", "--threads", "1", "--quiet"]
    r = run(*argv)
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 1 and len(lines) == 1, r.stderr
    assert str(out) in lines[0] and "No space left on device" in lines[0], lines
    assert out.read_bytes() == b"old output" and names(disk) == sorted(["filler", out.name])


# --- 5: a run's outputs are all new or all old, even if it is stopped between its renames ---

SLOW_RENAMES = """
import os, sys, time
real = os.replace
finals = {"table.txt", "results.csv", "results.json", "results.md", "results.tex", "iou_over_time.png"}
def replace(src, dst, *a, **k):
    real(src, dst, *a, **k)
    if os.path.basename(str(dst)) in finals:
        print("RENAMED", flush=True)
        time.sleep(3)
os.replace = replace
from dvsot.cli import main
sys.exit(main(sys.argv[1:]))
"""


def _tables(d: Path) -> dict:
    return {n: hashlib.sha256((d / n).read_bytes()).hexdigest() for n in names(d)
            if n in ("table.txt", "results.csv", "results.json", "results.md", "results.tex", "iou_over_time.png")}


@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGINT])
def test_a_run_stopped_between_renames_leaves_no_mix(tmp_path, test_file, sig):
    out = tmp_path / "b"
    argv = ["bench", "--tracker", "rct", "--data", str(test_file), "--out", str(out), "--jobs", "1", "--quiet",
            "--plots"]
    assert run(*argv).returncode == 0
    old = _tables(out)
    for name in old:  # mark the old outputs, so that old and new differ
        with open(out / name, "ab") as f:
            f.write(b"\n")
    old = _tables(out)
    p = subprocess.Popen([sys.executable, "-c", SLOW_RENAMES, *argv], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True)
    for line in p.stdout:
        if line.startswith("RENAMED"):
            break
    p.send_signal(sig)
    _, err = p.communicate(timeout=60)
    now = _tables(out)
    changed = {n for n in old if now[n] != old[n]}
    pending = [n for n in names(out) if ".commit~" in n]
    if sig == signal.SIGINT:  # signals wait for the renames: the run completes, and says the signal came late
        assert p.returncode == 0 and changed == set(old) and not pending and not temps(out)
        assert err.strip().splitlines() == ["dvsot bench: done; SIGINT arrived after its outputs were written"], err
    else:  # killed: either nothing changed, or all did, or a journal says the run is incomplete
        assert changed in (set(), set(old)) or pending, (changed, names(out))
        r = run(*argv[:-1])  # the next run (without --plots) finishes the commit first, then writes its own
        assert r.returncode == 0 and not temps(out)
    manifest = json.loads((out / "run.json").read_text())
    for name, entry in manifest["files"].items():  # the manifest and the files on disk agree
        assert hashlib.sha256((out / name).read_bytes()).hexdigest() == entry["sha256"], name


# --- 6: a SIGKILLed run's temp is removed by the next run; SIGTERM cleans up at once ---

def test_a_killed_runs_temp_is_removed_by_the_next_run(tmp_path):
    frames = frames_stack(tmp_path / "f.npy")
    out_dir = tmp_path / "o"
    out_dir.mkdir()
    argv = ["simulate", frames, "--fps", "1000", "-o", out_dir / "x.h5", "--quiet"]
    p = subprocess.Popen(dvsot(*argv), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    wait_for(lambda: writer_temp(out_dir) or p.poll() is not None, step=0.001)
    p.kill()
    p.wait()
    left = temps(out_dir)
    assert left
    assert run(*argv).returncode == 0
    assert names(out_dir) == ["x.h5"]  # the dead run's temp is gone
    from dvsot.runtime.staging import host

    assert all(f".tmp~{host()}~{p.pid}~" in n for n in left)  # named with host, pid and a random token


def test_sigterm_is_handled_like_sigint(tmp_path):
    out_dir = tmp_path / "o"
    out_dir.mkdir()
    (out_dir / "x.h5").write_bytes(b"old")
    p = subprocess.Popen(dvsot("simulate", frames_stack(tmp_path / "f.npy"), "--fps", "1000", "-o", out_dir / "x.h5",
                               "--quiet"), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    wait_for(lambda: writer_temp(out_dir) or p.poll() is not None, step=0.001)
    p.terminate()
    _, err = p.communicate(timeout=60)
    assert p.returncode == 143 and err.strip().splitlines() == ["dvsot simulate: interrupted (SIGTERM)"], err
    assert names(out_dir) == ["x.h5"] and (out_dir / "x.h5").read_bytes() == b"old"


# --- 7: -o through a symlink writes the link's target; the link stays ---

def test_an_output_symlink_is_written_through(tmp_path):
    (tmp_path / "real").mkdir()
    target = tmp_path / "real" / "data.h5"
    target.write_bytes(b"old")
    link = tmp_path / "link.h5"
    link.symlink_to(target)
    r = run("simulate", frames_stack(tmp_path / "f.npy", n=12), "--fps", "1000", "-o", link, "--quiet")
    assert r.returncode == 0, r.stderr
    assert link.is_symlink() and os.path.samefile(link, target) and target.read_bytes()[:4] == b"\x89HDF"
    assert names(tmp_path / "real") == ["data.h5"]


# --- 8: --keep-frames into a used directory holds this run's frames only ---

@pytest.mark.blender
def test_keep_frames_never_mixes_runs(tmp_path):
    keep = tmp_path / "frames"
    keep.mkdir()
    for i in range(80):  # the frames of an earlier, longer run
        np.save(keep / f"{i:06d}.npy", np.zeros((2, 2), np.float32))
    r = run("generate", QUICKSTART, *TINY_RENDER, "-o", tmp_path / "x.h5", "--keep-frames", keep)
    assert r.returncode == 0, r.stderr
    frames = json.loads(r.stdout.strip().splitlines()[-1])["frames"]
    kept = names(keep)
    assert kept == [f"{i:06d}.npy" for i in range(frames)] and np.load(keep / kept[0]).shape == (120, 160)
    assert not temps(tmp_path)
    (keep / "notes.txt").write_text("mine")  # a directory with other files is refused, not replaced
    r = run("generate", QUICKSTART, *TINY_RENDER, "-o", tmp_path / "x.h5", "--keep-frames", keep)
    assert r.returncode == 2 and "not kept frames" in r.stderr and (keep / "notes.txt").exists()


def test_a_signal_inside_compiled_code_is_still_one_interrupted_line(monkeypatch, capsys, tmp_path):
    # numba's dispatcher calls back into Python; a signal handled there comes out as a SystemError caused by it
    import signal

    from dvsot import cli
    from dvsot.runtime import interrupts

    def stopped(args):
        try:
            raise interrupts.Interrupted(signal.SIGINT)
        except interrupts.Interrupted as exc:
            raise SystemError("CPUDispatcher(<function f>) returned a result with an exception set") from exc

    parser = cli.build_parser()
    monkeypatch.setattr(cli, "build_parser", lambda: parser)
    args = parser.parse_args(["simulate", str(tmp_path), "-o", str(tmp_path / "x.h5")])
    monkeypatch.setattr(parser, "parse_args", lambda argv=None: args)
    monkeypatch.setattr(args, "_run", stopped)
    assert cli.main([]) == 130
    assert capsys.readouterr().err.strip().splitlines() == ["dvsot simulate: interrupted (SIGINT)"]

    def broken(args):
        raise SystemError("a SystemError of its own")

    monkeypatch.setattr(args, "_run", broken)
    with pytest.raises(SystemError, match="of its own"):
        cli.main([])


def test_an_interrupt_swallowed_by_a_callback_is_raised_at_the_next_check(capsys):
    # Python drops (and prints) an exception raised in a weakref callback or __del__: the signal must not be lost
    import gc
    import weakref

    from dvsot.runtime import interrupts

    class Thing:
        pass

    saved = interrupts.install()
    try:
        thing = Thing()
        ref = weakref.ref(thing, lambda r: interrupts._handler(signal.SIGTERM, None))
        del thing
        gc.collect()
        assert ref() is None
        with pytest.raises(interrupts.Interrupted) as caught:
            interrupts.check()
        assert caught.value.exit_status == 143
        interrupts.check()  # raised once
    finally:
        interrupts.restore(saved)
    assert "Interrupted" not in capsys.readouterr().err
