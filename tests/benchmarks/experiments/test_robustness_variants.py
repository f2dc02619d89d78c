"""The robustness sweep: variants that differ never share a file, repeated ones are refused, frames are matched to
their sequence by the digest it recorded, and signals, refused writes and bad frames end in one line."""

from __future__ import annotations

import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from dvsot.core.errors import UserError
from tests.synthetic import kept_sequence

ROOT = Path(__file__).resolve().parents[3]


def test_close_rates_get_names_that_keep_them_apart() -> None:
    from benchmarks.experiments.robustness import output_names, variant_name

    assert variant_name("ideal", 200.0) == "ideal_noise200"
    a, b = variant_name("ideal", 0.1234561), variant_name("ideal", 0.1234564)
    assert a != b and float(a.removeprefix("ideal_noise")) == 0.1234561
    assert len(set(output_names(["ideal"], [0.1234561, 0.1234564], [1, 2], False))) == 4 + 4


@pytest.mark.parametrize("presets, rates, seeds, flag", [
    (["ideal", "ideal"], None, None, "--preset"),
    (["ideal"], [1.0, 1.0], None, "--noise-hz"),
    (["ideal"], [None, None], None, "--noise-hz"),
    (["ideal"], None, [1, 1], "--event-seed"),
])
def test_repeated_variants_are_refused(presets, rates, seeds, flag) -> None:
    from benchmarks.experiments.robustness import output_names

    with pytest.raises(UserError, match=rf"{flag}: .* is given twice"):
        output_names(presets, rates, seeds, False)


def test_another_sequences_frames_of_the_same_count_are_refused_before_work(tmp_path: Path) -> None:
    from benchmarks.experiments.robustness import run

    seq, frames = kept_sequence(tmp_path / "a", n=12)
    _, other = kept_sequence(tmp_path / "b", n=12, start=(30, 30))
    with pytest.raises(UserError, match=r"frames: these 12 frames are not the ones .*kept_frames_sha256"):
        run(seq, other, ["rct"], ["ideal"], None, tmp_path / "out")
    assert not (tmp_path / "out").exists()
    run(seq, frames, ["rct"], ["ideal"], None, tmp_path / "out", max_segments=1)  # its own frames pass


def test_an_object_frame_is_one_line(tmp_path: Path) -> None:
    seq, frames = kept_sequence(tmp_path, n=12)
    np.save(frames / "000003.npy", np.array([{"a": 1}], dtype=object), allow_pickle=True)
    run = subprocess.run([sys.executable, "-m", "benchmarks.experiments.robustness", str(seq), str(frames),
                          "--tracker", "rct", "--out", str(tmp_path / "out")], capture_output=True, text=True,
                         cwd=ROOT)
    assert run.returncode == 2, run.stderr
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and "000003.npy" in lines[0], run.stderr


def test_sigterm_during_the_sweep_is_one_line_and_leaves_nothing(tmp_path: Path) -> None:
    import time

    seq, frames = kept_sequence(tmp_path, n=41)
    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-m", "benchmarks.experiments.robustness", str(seq), str(frames),
                             "--tracker", "rct", "--preset", "ideal", "--preset", "noisy", "--noise-hz", "0", "1",
                             "2", "3", "--out", str(out)], stderr=subprocess.PIPE, text=True, cwd=ROOT)
    deadline = time.monotonic() + 120
    while not (out.exists() and any(out.iterdir())) and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.05)  # the run has staged its first file
    proc.send_signal(signal.SIGTERM)
    err = proc.communicate(timeout=120)[1]
    assert proc.returncode == 128 + signal.SIGTERM, err
    assert err.strip().splitlines() == ["benchmarks.experiments.robustness: interrupted (SIGTERM)"]
    assert not out.exists() or not any(out.iterdir())


def test_a_refused_write_is_one_line_exit_1(tmp_path: Path, monkeypatch, capsys) -> None:
    import errno

    import benchmarks.experiments.robustness as robustness

    seq, frames = kept_sequence(tmp_path, n=12)

    def full(*args, **kwargs):
        raise OSError(errno.EFBIG, "File too large", str(tmp_path / "out" / "robustness.csv"))

    monkeypatch.setattr(robustness, "write_outputs", full)
    monkeypatch.setattr(sys, "argv", ["robustness", str(seq), str(frames), "--tracker", "rct", "--max-segments", "1",
                                      "--out", str(tmp_path / "out")])
    with pytest.raises(SystemExit) as stop:
        robustness.main()
    assert stop.value.code == 1
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and "File too large" in lines[0]
    assert not (tmp_path / "out").exists()


@pytest.mark.blender
def test_generate_records_the_digest_of_the_frames_it_keeps(tmp_path: Path) -> None:
    from dvsot.cli import main
    from dvsot.dataset import Dataset
    from dvsot.pipeline.kept_frames import DIGEST_ATTR, FrameDigest

    out, keep = tmp_path / "q.h5", tmp_path / "frames"
    assert main(["generate", str(ROOT / "blender_scenes" / "quickstart.yaml"), "--resolution", "160x120",
                 "--duration", "0.2", "--quiet", "-o", str(out), "--keep-frames", str(keep)]) == 0
    digest = FrameDigest()
    for f in sorted(keep.glob("*.npy")):
        digest.update(np.load(f))
    with Dataset(out) as ds:
        assert ds.attrs[DIGEST_ATTR] == digest.hexdigest()
