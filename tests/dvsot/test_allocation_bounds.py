"""What a file or a flag can make dvsot allocate is bounded, and the error names the bound:
deep or alias-expanding YAML, tiny segments, rates and timestamps spanning days, huge sensors, fuzzed files."""

from __future__ import annotations

import h5py
import numpy as np
import pytest
from synthetic import MINIMAL_SCENE

from dvsot.cli import main
from dvsot.dataset import DatasetWriter
from dvsot.events import EventBatch


def refused(argv, capsys, *words) -> str:
    assert main(argv) == 2, argv
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "Traceback" not in err, err
    assert all(w in err for w in words), err
    return err


DEEP_FLOW = "challenges: " + "[" * 3000 + "]" * 3000 + "\n"
DEEP_BLOCK = "challenges:\n" + "".join(" " * i + "- \n" for i in range(200))
ALIASES = "x0: &a0 [q, q, q, q, q, q, q, q, q, q]\n" + "".join(
    f"x{i}: &a{i} [{', '.join([f'*a{i - 1}'] * 10)}]\n" for i in range(1, 8))


@pytest.mark.parametrize("text, words", [
    (MINIMAL_SCENE + DEEP_FLOW, ("nested more than 64 levels",)),
    (MINIMAL_SCENE + DEEP_BLOCK, ("nested more than 64 levels",)),
    (ALIASES + MINIMAL_SCENE, ("aliases", "bound of 1000000")),
    (MINIMAL_SCENE + "segment_ms: 0.0001\n", ("segment_ms", "greater than or equal to 1")),
    (MINIMAL_SCENE + "# " + "x" * (1 << 20) + "\n", ("bound of 1048576 bytes",)),
])
def test_scene_files_that_would_blow_up_are_refused_naming_the_bound(tmp_path, capsys, text, words):
    scene = tmp_path / "s.yaml"
    scene.write_text(text)
    refused(["generate", str(scene), "-o", str(tmp_path / "o.h5")], capsys, str(scene), *words)
    assert not (tmp_path / "o.h5").exists()


@pytest.mark.parametrize("flags, times, words", [
    (["--fps", "1e-9"], None, ("--fps 1e-09", "bound of 3600 s")),
    ([], "0\n0.001\n0.002\n0.003\n1000000\n", ("t.txt", "bound of 3600 s")),
    (["--fps", "1000", "--segment-us", "1"], None, ("--segment-us", "at least 1000")),
    (["--fps", "10", "--shot-noise-hz", "1e9"], None, ("shot_noise_hz 1e+09", "bound of 5e+07")),
])
def test_simulate_flags_that_would_blow_up_are_refused_naming_the_bound(tmp_path, capsys, flags, times, words):
    np.save(tmp_path / "s.npy", np.random.default_rng(0).random((5, 12, 16), dtype=np.float32))
    if times:
        (tmp_path / "t.txt").write_text(times)
        flags = flags + ["--timestamps", str(tmp_path / "t.txt")]
    refused(["simulate", str(tmp_path / "s.npy"), "-o", str(tmp_path / "o.h5"), "--quiet"] + flags, capsys, *words)
    assert not (tmp_path / "o.h5").exists()


def small_file(path, width=64, height=48) -> None:
    with DatasetWriter(path, width, height, attrs={"split": "test"}) as w:
        t = np.arange(40) * 5000 + 3
        w.append_events(EventBatch(np.full(40, 3, np.uint16), np.full(40, 4, np.uint16), t, np.ones(40, np.uint8)))
        ts = np.arange(0, 200_001, 10_000)
        w.append_boxes(ts, np.tile([2.0, 2.0, 8.0, 8.0], (len(ts), 1)))
        w.close(200_000)


def test_huge_sensors_are_refused_before_tracking(tmp_path, capsys):
    big = tmp_path / "big.h5"
    small_file(big)
    with h5py.File(big, "a") as f:  # what a hostile or broken writer could leave
        f.attrs["width"] = f.attrs["height"] = 65535
        f.attrs.pop("attrs_sha256", None)  # no digest: as an old file
    out = tmp_path / "b"
    refused(["bench", "--tracker", "rct", "--data", str(big), "--out", str(out), "--video", "big"], capsys,
            "65535x65535", "bound of 67108864 pixels")
    wide = tmp_path / "wide.h5"
    small_file(wide, 8192, 8192)  # allowed as a file, but 20 preview frames of it are 3.8 GiB
    refused(["bench", "--tracker", "rct", "--data", str(wide), "--out", str(out), "--video", "wide"], capsys,
            "--video wide", "bound of 2 GiB")
    assert not out.exists()


def test_fuzzed_files_give_one_line_never_a_traceback(tmp_path, capsys):
    src = tmp_path / "src.h5"
    small_file(src)
    data = src.read_bytes()
    rng = np.random.default_rng(2026)
    outcomes = {0: 0, 2: 0}
    for k in range(150):
        b = bytearray(data)
        hi = 4096 if k % 2 else len(b)  # half in the superblock and root object headers
        for off in rng.integers(0, min(hi, len(b)), 4):
            b[off] = rng.integers(0, 256)
        path = tmp_path / f"f{k}.h5"
        path.write_bytes(bytes(b))
        code = main(["info", str(path)])
        captured = capsys.readouterr()
        assert code in outcomes, (k, code)
        outcomes[code] += 1
        if code == 2:
            assert str(path) in captured.err and captured.err.count("\n") == 1, captured.err
        path.unlink()
    assert outcomes[2] > 0, outcomes


@pytest.mark.parametrize("flags, words", [
    (["--batch-segments", "100000000"], ("--batch-segments", "at most 64 (the bound)")),
    (["--channels", "8", "100000", "8"], ("--channels", "between 1 and 1024 (the bound)")),
    (["--fc", "10000000", "32"], ("--fc", "between 1 and 1024 (the bound)")),
])
def test_train_flags_that_would_blow_up_are_refused_naming_the_bound(tmp_path, capsys, flags, words):
    small_file(tmp_path / "d.h5")
    refused(["train", "--data", str(tmp_path / "d.h5"), "--split", "any", "-o", str(tmp_path / "c.pt")] + flags,
            capsys, *words)
    assert not (tmp_path / "c.pt").exists()
