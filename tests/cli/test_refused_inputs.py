"""Inputs that used to pass and then alter data, fail late or allocate without bound: each is refused up front
with one line naming the file or flag (exit 2) or kept exactly, driven through the command line."""

from __future__ import annotations

import numpy as np

from dvsot.cli import main
from dvsot.dataset import Dataset


def _import(tmp_path, name: str, text: str, *flags: str) -> tuple[int, str]:
    """`dvsot import` of a CSV/TXT text on a 32x32 sensor: (exit status, the output's path)."""
    src = tmp_path / name
    src.write_text(text)
    out = tmp_path / (src.stem + ".h5")
    return main(["import", str(src), "--size", "32x32", "--segment-us", "1000", "-o", str(out), *flags]), str(out)


def test_csv_and_txt_events_are_kept_exactly_or_refused_naming_the_line(tmp_path, capsys):
    # a first line in another notation is an event, not a header dropped without a word
    for first in ("1e3,1,2,1", "+1000,1,2,1"):
        code, out = _import(tmp_path, "a.csv", f"{first}\n2000,3,4,0\n")
        assert code == 0, capsys.readouterr().err
        with Dataset(out) as ds:
            assert ds.num_events == 2 and ds.t_offset_us == 1000
            assert ds.events(0, ds.duration_us).t.tolist() == [0, 1000]
    # dvsot's own header needs no flag; another needs --header, and without it the error names line 1
    assert _import(tmp_path, "own.csv", "t,x,y,p\n1000,1,2,1\n3000,1,2,1\n")[0] == 0
    code, _ = _import(tmp_path, "b.csv", "time,x,y,pol\n1000,1,2,1\n")
    assert code == 2 and "b.csv:1: field t is 'time'" in capsys.readouterr().err
    code, out = _import(tmp_path, "b.csv", "time,x,y,pol\n1000,1,2,1\n3000,1,2,1\n", "--header")
    assert code == 0
    with Dataset(out) as ds:
        assert ds.num_events == 2
    # a bad line in the middle is named by its own line number (comments and blank lines counted)
    code, _ = _import(tmp_path, "c.csv", "# made by hand\n1000,1,2,1\n\nfoo,1,2,1\n")
    assert code == 2 and "c.csv:4: field t is 'foo'" in capsys.readouterr().err
    # times are exact or refused: no truncated fraction, no NaN or infinity turned into INT64_MIN
    for text, line, word in (("1000,1,2,1\n1500.5,1,2,1\n", 2, "whole number of microseconds"),
                             ("1000,1,2,1\nnan,1,2,1\n", 2, "finite"), ("inf,1,2,1\n", 1, "finite"),
                             ("1000,1,2,1\n-inf,1,2,1\n", 2, "finite")):
        code, out = _import(tmp_path, "d.csv", text)
        err = capsys.readouterr().err
        assert code == 2 and f"d.csv:{line}: field t is" in err and word in err, err
        assert len(err.strip().splitlines()) == 1
    for text, line in (("0.001 1 2 1\n0.0010005 1 2 1\n", 2), ("nan 1 2 1\n", 1)):
        code, _ = _import(tmp_path, "e.txt", text)
        err = capsys.readouterr().err
        assert code == 2 and f"e.txt:{line}: field t is" in err, err
    code, out = _import(tmp_path, "f.txt", "0.000001 1 2 1\n12.345678 3 4 0\n")
    assert code == 0
    with Dataset(out) as ds:
        assert ds.t_offset_us == 1 and ds.events(0, ds.duration_us).t.tolist() == [0, 12_345_677]
    assert not (tmp_path / "d.h5").exists() and not (tmp_path / "e.h5").exists()
    # a box track's times too: seconds with at most six decimals, or refused naming the line
    (tmp_path / "b.boxes.csv").write_text("0.000001,1,1,5,5\n0.0030005,2,2,5,5\n")
    code, _ = _import(tmp_path, "g.txt", "0.000001 1 2 1\n0.004 3 4 0\n", "--boxes", str(tmp_path / "b.boxes.csv"))
    err = capsys.readouterr().err
    assert code == 2 and "b.boxes.csv:2: field t_s is" in err, err


def _small_file(path, t_offset_us: int = 0, t=None, **attrs):
    """A 32x32 dataset file of 50 ms: 100 events (at times t, us), a box track, the given /t_offset (us) and root
    attributes."""
    from dvsot.dataset import DatasetWriter
    from dvsot.events import EventBatch

    t = np.linspace(0, 49_000, 100).astype(np.int64) if t is None else np.asarray(t, np.int64)
    with DatasetWriter(path, 32, 32, 10_000, attrs=attrs, t_offset_us=t_offset_us) as w:
        w.append_events(EventBatch(np.full(100, 3, np.uint16), np.full(100, 4, np.uint16), t, np.ones(100, np.uint8)))
        w.append_boxes([0, 50_000], [[2, 2, 8, 8], [4, 4, 8, 8]])
        w.close(50_000)
    return path


def test_a_flipped_bit_in_t_offset_is_refused_and_files_before_its_check_still_load(tmp_path, capsys):
    import h5py

    from dvsot.dataset.digest import DIGEST_ATTR, attrs_digest
    from dvsot.dataset.format import decode_attr

    path = _small_file(tmp_path / "rec.h5", t_offset_us=1_650_000_000_000_000)
    with h5py.File(path, "r+") as f:  # one bit: 2**40 us is 12.7 days
        f["t_offset"][()] = np.int64(1_650_000_000_000_000 ^ (1 << 40))
    for argv in (["info", str(path)], ["export", str(path), "-o", str(tmp_path / "rec.csv")]):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert "/t_offset" in err and str(path) in err and len(err.strip().splitlines()) == 1, err
    assert not (tmp_path / "rec.csv").exists()
    # the attribute that guards it is itself covered by the digest
    with h5py.File(path, "r+") as f:
        f.attrs["t_offset_us"] = np.int64(1_650_000_000_000_000 ^ (1 << 40))
    assert main(["info", str(path)]) == 2 and DIGEST_ATTR in capsys.readouterr().err
    # a file written before the attribute (its digest over the others) still loads, offset as stored
    old = _small_file(tmp_path / "old.h5", t_offset_us=5_000)
    with h5py.File(old, "r+") as f:
        del f.attrs["t_offset_us"]
        f.attrs[DIGEST_ATTR] = attrs_digest({k: decode_attr(v) for k, v in f.attrs.items()})
    assert main(["info", str(old)]) == 0
    with Dataset(old) as ds:
        assert ds.t_offset_us == 5_000


def test_a_scene_file_at_the_1_mb_limit_is_stored_and_read_back(tmp_path, capsys):
    import h5py

    from dvsot.core import bounds
    from dvsot.dataset.digest import DIGEST_ATTR
    from dvsot.scene.loader import yaml_text_problem

    # a scene file of exactly the bound (comment lines, some of them not ASCII), as generate stores it
    line = "# padding: ščena ünd ßzene\n"
    text = "name: big\n" + line * ((bounds.MAX_SCENE_BYTES - 100) // len(line.encode()))
    text += "#" * (bounds.MAX_SCENE_BYTES - len(text.encode()) - 1) + "\n"
    assert len(text.encode()) == bounds.MAX_SCENE_BYTES
    assert yaml_text_problem(text) is None  # a scene file generate accepts
    path = _small_file(tmp_path / "big.h5", scene_yaml=text, config={"notes": [text[:70_000]]})
    assert main(["info", str(path)]) == 0
    with Dataset(path) as ds:
        assert ds.attrs["scene_yaml"] == text and ds.attrs["config"] == {"notes": [text[:70_000]]}
    # the long text is under the attribute digest too
    with h5py.File(path, "r+") as f:
        (key,) = [k for k in f if k not in ("events", "boxes", "segments", "ms_to_idx", "t_offset")]
        data = bytearray(f[f"{key}/scene_yaml"][()])
        data[500_000] ^= 1
        f[f"{key}/scene_yaml"][()] = bytes(data)
    capsys.readouterr()
    assert main(["info", str(path)]) == 2
    err = capsys.readouterr().err
    assert DIGEST_ATTR in err and len(err.strip().splitlines()) == 1, err


def _refused(argv: list[str], capsys, *words: str) -> str:
    """Run the command: exit 2 and one stderr line holding every word (the bound among them)."""
    code = main(argv)
    err = capsys.readouterr().err.strip()
    assert code == 2, (argv, err)
    assert "\n" not in err and "Traceback" not in err and all(w in err for w in words), (argv, err)
    return err


def test_sizes_from_files_and_flags_are_bounded_before_any_work(tmp_path, capsys):
    import struct
    import zlib

    import h5py
    from synthetic import MINIMAL_SCENE

    from dvsot.core import bounds
    from dvsot.dataset.digest import DIGEST_ATTR, attrs_digest
    from dvsot.dataset.format import decode_attr

    # a small file declaring 33 million events at t = 0 whose chunks were never written (they read as zeros)
    path = _small_file(tmp_path / "big.h5", t=np.zeros(100))
    n = 1 << 25
    with h5py.File(path, "r+") as f:
        for name in ("x", "y", "t", "p"):
            f[f"events/{name}"].resize((n,))
        f["events/ms_to_idx"][1:] = n
        f.attrs["num_events"] = n
        f.attrs[DIGEST_ATTR] = attrs_digest({k: decode_attr(v) for k, v in f.attrs.items()})
    assert path.stat().st_size < 100_000
    for argv in (["info", str(path)], ["export", str(path), "-o", str(tmp_path / "big.csv")],
                 ["bench", "--tracker", "kcf", "--data", str(path), "--split", "any", "--out", str(tmp_path / "b")]):
        _refused(argv, capsys, str(path), "/events/", f"declares {n} rows")
    assert not (tmp_path / "big.csv").exists() and not (tmp_path / "b").exists()

    template = "blender_scenes/templates/dvsot21_random.yaml"
    scene = tmp_path / "s.yaml"
    scene.write_text(MINIMAL_SCENE)
    csv = tmp_path / "e.csv"
    csv.write_text("1000,1,2,1\n2000,3,4,0\n")
    for argv, words in (
        (["generate", template, "--variants", "3000000", "--dry-run"], ("--variants", str(bounds.MAX_VARIANTS))),
        (["generate", str(scene), "--jobs", "1000000"], ("--jobs", str(bounds.MAX_WORKERS))),
        (
            ["generate", template, "--variants", "2", "--scheduler", "local:100000", "--out-dir", str(tmp_path / "o")],
            ("local:N", str(bounds.MAX_WORKERS)),
        ),
        (
            ["bench", "--tracker", "kcf", "--jobs", "1000000", "--data", str(_small_file(tmp_path / "ok.h5"))],
            ("--jobs", str(bounds.MAX_WORKERS)),
        ),
        (
            ["import", str(csv), "--size", "32x32", "--segment-us", str(10**15), "-o", str(tmp_path / "i.h5")],
            ("--segment-us", str(bounds.MAX_SEGMENT_US)),
        ),
        (
            [
                "simulate",
                str(tmp_path / "frames"),
                "--fps",
                "1000",
                "--segment-us",
                str(10**15),
                "-o",
                str(tmp_path / "s.h5"),
            ],
            ("--segment-us", str(bounds.MAX_SEGMENT_US)),
        ),
        (["train", "--data", str(tmp_path / "ok.h5"), "--threads", "100000"], ("--threads", str(bounds.MAX_THREADS))),
        (
            ["train", "--data", str(tmp_path / "ok.h5"), "--tail-steps", "1000000000"],
            ("--tail-steps", str(bounds.MAX_TAIL_STEPS)),
        ),
        (["train", "--data", str(tmp_path / "ok.h5"), "--lr", "1e38"], ("--lr", "1e+38", "1.0")),
        (["train", "--model", "siamfc", "--data", str(tmp_path / "ok.h5"), "--lr", "1e38"], ("--lr", "1e+38", "1.0")),
        (
            ["import", str(csv), "--size", "65536x65536", "-o", str(tmp_path / "i.h5")],
            ("--size", str(bounds.MAX_SENSOR_PIXELS)),
        ),
    ):
        _refused(argv, capsys, *words)
    # a TXT header of 65536x65536: refused on its line before its events are read
    txt = tmp_path / "e.txt"
    txt.write_text("65536 65536\n0.001 1 2 1\n")
    _refused(["import", str(txt), "-o", str(tmp_path / "i.h5")], capsys, f"{txt}:1", str(bounds.MAX_SENSOR_PIXELS))

    # a 60000x60000 PNG texture (a header and a token of data): refused from its header, before decoding
    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    png = tmp_path / "huge.png"
    png.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", 60000, 60000, 8, 0, 0, 0, 0))
                    + chunk(b"IDAT", zlib.compress(b"\0" * 60001)) + chunk(b"IEND", b""))
    scene.write_text(MINIMAL_SCENE + f"background:\n  material: {{texture: {{type: image, path: {png}}}}}\n")
    _refused(["generate", str(scene), "-o", str(tmp_path / "t.h5")], capsys, str(png), "60000x60000",
             str(bounds.MAX_TEXTURE_PIXELS))
    # and as a frame of `dvsot simulate`
    (tmp_path / "frames").mkdir()
    png.rename(tmp_path / "frames" / "f0.png")
    _refused(["simulate", str(tmp_path / "frames"), "--fps", "100", "-o", str(tmp_path / "t.h5")], capsys,
             "f0.png", "60000x60000", str(bounds.MAX_SENSOR_PIXELS))
    assert not list(tmp_path.glob("*.h5.*")) and not (tmp_path / "i.h5").exists() and not (tmp_path / "t.h5").exists()


def test_inputs_that_used_to_be_accepted_are_refused(tmp_path, capsys):
    import os

    import h5py
    from synthetic import MINIMAL_SCENE

    from dvsot.core import bounds
    from dvsot.dataset.digest import DIGEST_ATTR, attrs_digest
    from dvsot.dataset.format import decode_attr

    def rewrite(path, **datasets) -> None:
        """Overwrite datasets of a dataset file in place (the digest covers attributes only)."""
        with h5py.File(path, "r+") as f:
            for name, values in datasets.items():
                f[name.replace("__", "/")][...] = values
            f.attrs[DIGEST_ATTR] = attrs_digest({k: decode_attr(v) for k, v in f.attrs.items()})

    # boxes 1e-30 px wide (bench made an empty table of them at exit 0)
    thin = _small_file(tmp_path / "thin.h5")
    with h5py.File(thin, "r") as f:
        boxes, seg = f["boxes/xywh"][()], f["segments/xywh"][()]
    boxes[:, 2], seg[:, 2] = 1e-30, 1e-30
    rewrite(thin, boxes__xywh=boxes, boxes__xywh_visible=boxes, segments__xywh=seg, segments__xywh_visible=seg)
    _refused(["bench", "--tracker", "kcf", "--data", str(thin), "--split", "any", "--out", str(tmp_path / "b")],
             capsys, str(thin), "w=1e-30")
    assert not (tmp_path / "b").exists()
    # boxes of half a pixel are valid, but too small for the protocol to start on: nothing would be scored
    boxes[:, 2], seg[:, 2] = 0.5, 0.5
    rewrite(thin, boxes__xywh=boxes, boxes__xywh_visible=boxes, segments__xywh=seg, segments__xywh_visible=seg)
    _refused(["bench", "--tracker", "kcf", "--data", str(thin), "--split", "any", "--out", str(tmp_path / "b")],
             capsys, str(thin), "no segment of 5 can be scored")
    assert not (tmp_path / "b").exists()
    # a box sample after the end of the file
    late = _small_file(tmp_path / "late.h5")
    rewrite(late, boxes__t=np.array([0, 10_000_000]))
    _refused(["info", str(late)], capsys, str(late), "/boxes/t", "10000000")

    # a file with no segment is not written: a recording shorter than one segment
    csv = tmp_path / "e.csv"
    csv.write_text("1000,1,2,1\n2000,3,4,0\n")
    _refused(
        ["import", str(csv), "--size", "32x32", "-o", str(tmp_path / "e.h5")], capsys, "--segment-us", "no segment"
    )
    scene = tmp_path / "s.yaml"
    scene.write_text(MINIMAL_SCENE)
    _refused(
        ["generate", str(scene), "--duration", "0.005", "-o", str(tmp_path / "g.h5")],
        capsys,
        "segment_ms",
        "no segment",
    )
    # -o on a symlink loop; -o beside --out-dir
    loop = tmp_path / "loop.h5"
    os.symlink(loop.name, loop)
    _refused(
        ["import", str(csv), "--size", "32x32", "--segment-us", "1000", "-o", str(loop)], capsys, str(loop), "link"
    )
    assert loop.is_symlink() and os.readlink(loop) == loop.name
    _refused(["generate", str(scene), "--out-dir", str(loop)], capsys, str(loop), "link")
    _refused(["generate", str(scene), "-o", str(tmp_path / "g.h5"), "--out-dir", str(tmp_path / "d")], capsys,
             "-o", "--out-dir")
    # a scheduler port beyond 65535 (it used to fail after 20 s of trying to connect)
    _refused(["generate", "blender_scenes/templates/dvsot21_random.yaml", "--variants", "1", "--scheduler",
              "tcp://127.0.0.1:99999", "--out-dir", str(tmp_path / "d")], capsys, "99999", "65535")
    _refused(["bench", "--tracker", "kcf", "--data", str(_small_file(tmp_path / "ok.h5")), "--split", "any",
              "--scheduler", "tcp://127.0.0.1:99999", "--out", str(tmp_path / "b")], capsys, "99999", "65535")
    # a contrast threshold that overflows (it printed an overflow note and went on)
    np.save(tmp_path / "f.npy", np.linspace(0.1, 0.9, 20 * 8 * 8, dtype=np.float32).reshape(20, 8, 8))
    _refused(["simulate", str(tmp_path / "f.npy"), "--fps", "1000", "--cp", "1e308", "-o", str(tmp_path / "f.h5")],
             capsys, "--cp", str(bounds.MAX_CONTRAST)[:3])
    assert not any(
        p.suffix == ".h5" and p.name not in ("thin.h5", "late.h5", "ok.h5", "loop.h5") for p in tmp_path.iterdir()
    )
