"""`dvsot simulate` and `dvsot info` end to end, in-process, on tiny inputs; bad input exits 2 with no file."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from dvsot.cli import main
from dvsot.dataset import Dataset
from dvsot.events import EventParams, EventSimulator


def stack(n: int = 30, h: int = 24, w: int = 32) -> np.ndarray:
    yy, xx = np.mgrid[0:h, 0:w]
    return np.stack([0.5 + 0.4 * np.sin(0.4 * (xx - 0.7 * i)) * np.cos(0.3 * yy) for i in range(n)]).astype(np.float32)


def test_npy_stack_with_timestamps_matches_the_simulator(tmp_path, capsys):
    frames = stack()
    np.save(tmp_path / "s.npy", frames)
    times = 0.5 + np.arange(len(frames)) * 1e-3
    (tmp_path / "t.txt").write_text("\n".join(f"{t:.6f}" for t in times))
    out = tmp_path / "s.h5"
    assert main(["simulate", str(tmp_path / "s.npy"), "--timestamps", str(tmp_path / "t.txt"), "-o", str(out),
                 "--cp", "0.15", "--cn", "0.25", "--sigma", "0.02", "--seed", "3", "--quiet"]) == 0
    summary = json.loads(capsys.readouterr().out)
    sim = EventSimulator(32, 24, EventParams(cp=0.15, cn=0.25, sigma_cp=0.02, sigma_cn=0.02), seed=3)
    expected = [sim.step(f, i * 1000) for i, f in enumerate(frames)]
    with Dataset(out) as ds:
        got = ds.events(0, ds.duration_us)
        assert ds.width == 32 and ds.height == 24 and ds.duration_us == 29_001
        np.testing.assert_array_equal(got.t, np.concatenate([e.t for e in expected]))
        np.testing.assert_array_equal(got.x, np.concatenate([e.x for e in expected]))
        assert ds.attrs["simulator"]["cn"] == 0.25
    assert summary["events"] == len(got) > 0


def test_boxes_csv_gives_the_segment_ground_truth(tmp_path, capsys):
    np.save(tmp_path / "s.npy", stack(31))
    # boxes for the first 20 ms only (times in seconds, as the frames: 1 kHz from t = 0)
    (tmp_path / "b.csv").write_text("# t_s,x,y,w,h\n0.000,2,3,10,8\n0.020,12,3,10,8\n")
    out = tmp_path / "b.h5"
    assert main(["simulate", str(tmp_path / "s.npy"), "--fps", "1000", "-o", str(out), "--quiet",
                 "--boxes", str(tmp_path / "b.csv")]) == 0
    with Dataset(out) as ds:
        seg = ds.segment_boxes()
        assert ds.num_segments == 3 and len(ds.boxes().t) == 2
        np.testing.assert_allclose(seg[0], [7, 3, 10, 8])  # halfway between the two samples at t = 10 ms
        np.testing.assert_allclose(seg[1], [12, 3, 10, 8])
    capsys.readouterr()
    assert main(["info", "--json", str(out)]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["segments_with_box"] >= 2 and info["box_width_px"][0] == 10
    (tmp_path / "bad.csv").write_text("0.0,1,2,3\n")
    assert main(["simulate", str(tmp_path / "s.npy"), "--fps", "1000", "-o", str(tmp_path / "c.h5"),
                 "--quiet", "--boxes", str(tmp_path / "bad.csv")]) == 2
    assert not (tmp_path / "c.h5").exists()


def test_png_directory_8_and_16_bit_with_fps(tmp_path, capsys):
    frames = stack(12)
    for i, f in enumerate(frames):
        cv2.imwrite(str(tmp_path / f"f{i:03d}.png"), np.round(f * 255).astype(np.uint8))
    out = tmp_path / "png.h5"
    assert main(["simulate", str(tmp_path), "--fps", "500", "-o", str(out), "--quiet"]) == 0
    with Dataset(out) as ds:
        assert ds.duration_us == 11 * 2000 + 1 and ds.num_events > 0
    d16 = tmp_path / "d16"
    d16.mkdir()
    for i, f in enumerate(frames):
        cv2.imwrite(str(d16 / f"f{i:03d}.png"), np.round(f * 65535).astype(np.uint16))
    assert main(["simulate", str(d16), "--fps", "500", "-o", str(tmp_path / "p16.h5"), "--quiet", "--srgb"]) == 0
    capsys.readouterr()
    assert main(["info", str(out)]) == 0
    text = capsys.readouterr().out
    assert "32x24" in text and "events" in text
    assert main(["info", "--json", str(out)]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["resolution"] == [32, 24] and info["segments"] == 2 and 0 < info["positive_fraction"] < 1


def bad_inputs(tmp_path):
    np.save(tmp_path / "ok.npy", stack(5))
    np.save(tmp_path / "flat.npy", np.zeros((4, 5)))
    (tmp_path / "empty").mkdir()
    mixed = tmp_path / "mixed"
    mixed.mkdir()
    cv2.imwrite(str(mixed / "a.png"), np.zeros((8, 8), np.uint8))
    cv2.imwrite(str(mixed / "b.png"), np.zeros((9, 8), np.uint8))
    (tmp_path / "t.txt").write_text("0\n0.001\n0.001\n0.003\n0.004\n")
    (tmp_path / "short.txt").write_text("0\n0.001\n")
    ok = str(tmp_path / "ok.npy")
    return [
        ([str(tmp_path / "missing"), "--fps", "100"], "no such file"),
        ([str(tmp_path / "empty"), "--fps", "100"], "no images"),
        ([str(mixed), "--fps", "100"], "the first was"),
        ([str(tmp_path / "flat.npy"), "--fps", "100"], "(T, H, W)"),
        ([ok], "--fps"),
        ([ok, "--timestamps", str(tmp_path / "t.txt")], "must increase"),
        ([ok, "--timestamps", str(tmp_path / "short.txt")], "2 timestamps for 5 frames"),
        ([ok, "--fps", "100", "--cp", "-0.1"], "--cp"),
        ([ok, "--fps", "100", "--refractory-us", "-1"], "--refractory-us"),
    ]


def test_bad_input_exits_2_with_one_line_and_no_output(tmp_path, capsys):
    out = tmp_path / "out" / "x.h5"
    out.parent.mkdir()
    for argv, words in bad_inputs(tmp_path):
        assert main(["simulate", *argv, "-o", str(out), "--quiet"]) == 2, argv
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and words in err[0], (argv, err)
        assert list(out.parent.iterdir()) == []


def test_existing_output_survives_a_failed_run(tmp_path, capsys):
    np.save(tmp_path / "ok.npy", stack(5))
    out = tmp_path / "x.h5"
    assert main(["simulate", str(tmp_path / "ok.npy"), "--fps", "100", "-o", str(out), "--quiet"]) == 0
    before = out.read_bytes()
    bad = np.stack([np.ones((24, 32))] * 4 + [np.full((24, 32), np.nan)]).astype(np.float32)
    np.save(tmp_path / "bad.npy", bad)
    assert main(["simulate", str(tmp_path / "bad.npy"), "--fps", "100", "-o", str(out), "--quiet"]) == 2
    assert "NaN" in capsys.readouterr().err
    assert out.read_bytes() == before and sorted(p.name for p in tmp_path.iterdir()) == ["bad.npy", "ok.npy", "x.h5"]


@pytest.mark.parametrize("content", [b"", b"\x89HDF\r\n\x1a\n garbage"])
def test_info_on_a_damaged_file_exits_2(tmp_path, capsys, content):
    bad = tmp_path / "bad.h5"
    bad.write_bytes(content)
    assert main(["info", str(bad)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "bad.h5" in err[0]


def snapshot(d) -> dict:
    """Every file under d (names of dot files too) with its bytes, to show that a failed run changed nothing."""
    return {str(p.relative_to(d)): (p.read_bytes() if p.is_file() else None) for p in sorted(d.rglob("*"))}


def assert_refused(argv, words, tmp_path, capsys) -> str:
    """`dvsot simulate argv` exits 2 with one line holding every one of words, and no file under tmp_path changes."""
    before = snapshot(tmp_path)
    assert main(["simulate", *argv, "--quiet"]) == 2, argv
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and all(w in err[0] for w in words), (argv, err)
    assert snapshot(tmp_path) == before, argv
    return err[0]


def test_output_that_is_a_directory_or_the_input_is_refused(tmp_path, capsys):
    np.save(tmp_path / "ok.npy", stack(5))
    (tmp_path / "adir").mkdir()
    ok = str(tmp_path / "ok.npy")
    assert_refused([ok, "--fps", "100", "-o", str(tmp_path / "adir")], ["adir", "-o", "directory"], tmp_path, capsys)
    assert_refused([ok, "--fps", "100", "-o", ok], ["ok.npy", "-o", "input"], tmp_path, capsys)
    (tmp_path / "t.txt").write_text("\n".join(str(i / 100) for i in range(5)))
    assert_refused([ok, "--timestamps", str(tmp_path / "t.txt"), "-o", str(tmp_path / "t.txt")], ["t.txt", "input"],
                   tmp_path, capsys)
    frames = tmp_path / "frames"
    frames.mkdir()
    for i, f in enumerate(stack(3)):
        cv2.imwrite(str(frames / f"{i:04d}.png"), (np.clip(f, 0, 1) * 255).astype(np.uint8))
    assert_refused([str(frames), "--fps", "100", "-o", str(frames / "0002.png")], ["0002.png", "-o", "input"],
                   tmp_path, capsys)


@pytest.mark.parametrize("flags, words", [
    (["--seed=-1"], ["--seed", "-1"]),
    (["--fps", "nan"], ["--fps", "finite", "nan"]),
    (["--fps", "inf"], ["--fps", "finite", "inf"]),
    (["--fps", "0"], ["--fps", "positive"]),
    (["--fps", "1e7"], ["--fps"]),
    (["--fps", "100", "--cp=inf"], ["--cp", "finite"]),
    (["--fps", "100", "--cn", "nan"], ["--cn", "finite"]),
    (["--fps", "100", "--sigma", "inf"], ["--sigma", "finite"]),
    (["--fps", "100", "--refractory-us", "inf"], ["--refractory-us", "finite"]),
    (["--fps", "100", "--log-eps", "inf"], ["--log-eps", "finite"]),
    (["--fps", "100", "--shot-noise-hz", "inf"], ["--shot-noise-hz", "finite"]),
    (["--fps", "100", "--leak-hz", "nan"], ["--leak-hz", "finite"]),
    (["--fps", "100", "--cp", "-0.1"], ["--cp", "greater than 0"]),
])
def test_bad_numeric_flags_name_the_flag(tmp_path, capsys, flags, words):
    np.save(tmp_path / "ok.npy", stack(5))
    assert_refused([str(tmp_path / "ok.npy"), *flags, "-o", str(tmp_path / "x.h5")], words, tmp_path, capsys)


@pytest.mark.parametrize("lines, words", [
    (["0", "nan", "0.002", "0.003", "0.004"], ["ts.txt:2", "'nan'"]),
    (["0", "0.001", "0.002", "0.003", "inf"], ["ts.txt:5", "'inf'"]),
    (["0", "0.001", "-inf", "0.003", "0.004"], ["ts.txt:3", "'-inf'"]),
    (["0", "0.001", "1e300", "0.003", "0.004"], ["ts.txt:3", "'1e300'"]),
])
def test_non_finite_timestamps_name_the_file_and_line(tmp_path, capsys, lines, words):
    np.save(tmp_path / "ok.npy", stack(5))
    (tmp_path / "ts.txt").write_text("\n".join(lines) + "\n")
    assert_refused([str(tmp_path / "ok.npy"), "--timestamps", str(tmp_path / "ts.txt"), "-o", str(tmp_path / "x.h5")],
                   words, tmp_path, capsys)


@pytest.mark.parametrize("shape", [(10, 0, 0), (10, 0, 5), (10, 4, 0)])
def test_npy_with_no_pixels_names_the_file(tmp_path, capsys, shape):
    np.save(tmp_path / "zero.npy", np.zeros(shape, np.float32))
    assert_refused([str(tmp_path / "zero.npy"), "--fps", "100", "-o", str(tmp_path / "x.h5")],
                   ["zero.npy", f"{shape[2]}x{shape[1]}"], tmp_path, capsys)


@pytest.mark.parametrize("rows, words", [
    ("0,1,1,-5,5\n0.002,2,2,5,5\n", ["b.csv:2", "width and height must be positive", "w=-5"]),
    ("0,1,1,5,5\n0.002,2,2,5,-5\n", ["b.csv:3", "positive", "h=-5"]),
    ("0,1,1,5,5\n0.002,2,2,0,5\n", ["b.csv:3", "positive"]),
    ("0,1,1,5,5\ninf,2,2,5,5\n", ["b.csv:3", "box time", "'inf'"]),
    ("0,1,1,5,5\n0.002,nan,2,5,5\n", ["b.csv:3", "finite"]),
    ("0,1,1,5,5\n0.002,2,2,5\n", ["b.csv:3", "expected 5 columns"]),
    ("0.002,1,1,5,5\n0.001,2,2,5,5\n", ["b.csv:3", "must increase"]),
])
def test_bad_boxes_name_the_file_and_line(tmp_path, capsys, rows, words):
    np.save(tmp_path / "ok.npy", stack(5))
    (tmp_path / "b.csv").write_text("# t_s,x,y,w,h\n" + rows)
    assert_refused([str(tmp_path / "ok.npy"), "--fps", "1000", "-o", str(tmp_path / "x.h5"),
                    "--boxes", str(tmp_path / "b.csv")], words, tmp_path, capsys)


def test_boxes_that_are_all_nan_mean_no_target(tmp_path, capsys):
    np.save(tmp_path / "ok.npy", stack(5))
    (tmp_path / "b.csv").write_text("0,1,1,5,5\n0.002,nan,nan,nan,nan\n")
    assert (
        main(
            [
                "simulate",
                str(tmp_path / "ok.npy"),
                "--fps",
                "1000",
                "--segment-us",
                "1000",
                "-o",
                str(tmp_path / "x.h5"),
                "--quiet",
                "--boxes",
                str(tmp_path / "b.csv"),
            ]
        )
        == 0
    )
    with Dataset(tmp_path / "x.h5") as ds:
        assert np.isnan(ds.boxes().xywh[1]).all()


def test_corrupt_png_frame_gives_only_our_line(tmp_path, capfd):
    """OpenCV's own warning (written to fd 2, past capsys) must not precede the one-line error."""
    for i, f in enumerate(stack(5)):
        cv2.imwrite(str(tmp_path / f"f{i}.png"), np.round(f * 255).astype(np.uint8))
    (tmp_path / "f3.png").write_bytes(b"\x89PNG\r\n\x1a\ngarbage")  # OpenCV warns "chunk data is too large"
    out = tmp_path.parent / f"{tmp_path.name}.h5"
    assert main(["simulate", str(tmp_path), "--fps", "100", "-o", str(out), "--quiet"]) == 2
    err = capfd.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "f3.png: cannot read image" in err[0], err
    assert not out.exists()


def test_garbage_video_gives_only_our_line(tmp_path):
    """ffmpeg's note ("moov atom not found") must not precede the error; a fresh process, as ffmpeg's level is
    fixed when OpenCV first opens a video."""
    import subprocess
    import sys

    (tmp_path / "g.mp4").write_bytes(np.random.default_rng(0).integers(0, 256, 4096, dtype=np.uint8).tobytes())
    r = subprocess.run([sys.executable, "-m", "dvsot.cli", "simulate", str(tmp_path / "g.mp4"), "--fps", "100",
                        "-o", str(tmp_path / "x.h5"), "--quiet"], capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and r.stdout == ""
    err = r.stderr.strip().splitlines()
    assert len(err) == 1 and "g.mp4: cannot open video" in err[0], err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["g.mp4"]
