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
        ([ok, "--fps", "100", "--cp", "-0.1"], "'cp'"),
        ([ok, "--fps", "100", "--refractory-us", "-1"], "'refractory_us'"),
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
