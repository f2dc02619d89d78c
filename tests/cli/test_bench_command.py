"""`dvsot bench` end to end with a tracker registered in the test, and its bad-input errors."""

import json

import numpy as np

from benchmarks.trackers import register
from benchmarks.trackers.base import Tracker
from dvsot.cli import main
from dvsot.dataset import DatasetWriter
from dvsot.events import EventBatch


@register("test-still")
class StillTracker(Tracker):
    """Never moves: succeeds while the target stands still."""

    def init(self, segment, box_xywh, width, height):
        self.box = box_xywh.copy()

    def update(self, segment):
        return self.box.copy()


def make(path, split="test", moving=True, boxes=True):
    n = 20
    with DatasetWriter(path, 64, 48, attrs={"split": split}) as w:
        t = np.arange(n) * 10_000 + 1
        w.append_events(EventBatch(np.full(n, 3, np.uint16), np.full(n, 3, np.uint16), t, np.ones(n, np.uint8)))
        if boxes:
            ts = np.arange(n + 1) * 10_000
            x = 5 + (ts / 10_000 * 4 if moving else 0 * ts)
            w.append_boxes(ts, np.stack([x, np.full(n + 1, 5), np.full(n + 1, 10), np.full(n + 1, 10)], 1))
        w.close(n * 10_000)


def test_fake_tracker_end_to_end(tmp_path, capsys):
    make(tmp_path / "moving.h5")
    make(tmp_path / "still.h5", moving=False)
    make(tmp_path / "train.h5", split="train")
    out = tmp_path / "bench"
    assert main(["bench", "--tracker", "test-still", "--data", str(tmp_path), "--out", str(out), "--jobs", "1",
                 "--quiet", "--plots"]) == 0
    printed = capsys.readouterr().out
    assert "moving" in printed and "still" in printed and "train" not in printed
    res = json.loads((out / "results.json").read_text())["test-still"]
    assert res["still"]["A"] == 1.0 and res["still"]["segments"] == 19
    # moving 4 px per segment with a 10 px box: IoU 6/14 < 0.5 every time -> every other segment re-inits
    assert res["moving"]["R"] == 0.0 and res["moving"]["segments"] == 10
    assert (out / "iou_over_time.png").stat().st_size > 1000


def test_bad_input_exits_2(tmp_path, capsys):
    make(tmp_path / "a.h5")
    make(tmp_path / "nobox.h5", boxes=False)
    (tmp_path / "junk.h5").write_text("not hdf5")
    cases = [
        (["--tracker", "nope", "--data", str(tmp_path / "a.h5")], "unknown tracker 'nope'"),
        (["--tracker", "rct", "--data", str(tmp_path / "junk.h5")], "not a readable HDF5"),
        (["--tracker", "rct", "--data", str(tmp_path / "nobox.h5")], "no ground-truth"),
        (["--tracker", "rct", "--data", str(tmp_path / "a.h5"), "--split", "train"], "split 'train'"),
        (["--tracker", "rct", "--tracker-module", "no_such_module_x"], "cannot import"),
        (["--tracker", "rct", "--data", str(tmp_path / "a.h5"), "--option", "rct-size=3"], "TRACKER.KEY=VALUE"),
        (["--tracker", "rct", "--data", str(tmp_path / "a.h5"), "--option", "sctn.fast=false"], "not in this run"),
    ]
    for argv, words in cases:
        assert main(["bench", *argv, "--quiet"]) == 2, argv
        err = capsys.readouterr().err.strip().splitlines()
        words = [words] if isinstance(words, str) else words
    assert len(err) == 1 and all(w in err[0] for w in words), (argv, err)


# --- bad input is found before any run, and nothing is written or changed (audit cases 11-19) ---


def snapshot(root):
    """{relative path: bytes, or None for a directory} of everything under root."""
    return {str(p.relative_to(root)): None if p.is_dir() else p.read_bytes() for p in sorted(root.rglob("*"))}


def fails_cleanly(tmp_path, capsys, argv, words):
    """`dvsot bench argv` exits 2 with one stderr line holding `words` (a string or several), tmp_path unchanged."""
    before = snapshot(tmp_path)
    assert main(["bench", *argv, "--quiet", "--jobs", "1"]) == 2, argv
    captured = capsys.readouterr()
    # a checkpoint's one-line note (the shipped one was trained with the old error-time rule) is not an error
    err = [line for line in captured.err.strip().splitlines() if ": note: " not in line]
    words = [words] if isinstance(words, str) else words
    assert len(err) == 1 and all(w in err[0] for w in words), (argv, err)
    assert "written" not in captured.out, argv
    assert snapshot(tmp_path) == before, argv


@register("test-crash")
class CrashTracker(Tracker):
    """Raises a two-line error on its first update, like torch's messages."""

    def init(self, segment, box_xywh, width, height):
        self.box = box_xywh.copy()

    def update(self, segment):
        raise RuntimeError("boom\nsecond line")


@register("test-interrupt")
class InterruptTracker(StillTracker):
    """Stands for Ctrl-C in the middle of a run."""

    def update(self, segment):
        raise KeyboardInterrupt


def checkpoints(tmp_path):
    """Bad SCTN checkpoints of every kind the audit tried, made from a fresh (untrained) network."""
    import torch

    from sctn.checkpoint import DIGEST_KEY, save_checkpoint, weights_digest
    from sctn.network import SCTN, NetworkConfig

    def sealed(b):  # well-formed files whose digest fits their (wrong) tensors: refused for the tensors
        return dict(b, meta={**b["meta"], DIGEST_KEY: weights_digest(b["state_dict"])})

    d = tmp_path / "ckpt"
    d.mkdir()
    good = save_checkpoint(d / "good.pt", SCTN(NetworkConfig()), {})
    blob = torch.load(good, weights_only=True)
    (d / "garbage.pt").write_bytes(b"\x00not a checkpoint" * 50)
    (d / "trunc.pt").write_bytes(good.read_bytes()[: good.stat().st_size // 2])
    torch.save({"hello": 1}, d / "notsctn.pt")
    torch.save([1, 2, 3], d / "list.pt")
    missing = dict(blob, state_dict={k: v for k, v in blob["state_dict"].items() if k != "convs.0.weight"})
    torch.save(sealed(missing), d / "missingkey.pt")
    torch.save(dict(blob, config={**blob["config"], "bogus": 1}), d / "badconfig.pt")
    torch.save(sealed(dict(blob, state_dict={**blob["state_dict"], "convs.0.weight": torch.zeros(3, 3)})),
               d / "badshape.pt")
    good.unlink()
    good.with_suffix(".json").unlink()
    return d


def test_bad_flags_fail_before_the_run(tmp_path, capsys):
    make(tmp_path / "a.h5")
    data = ["--data", str(tmp_path / "a.h5"), "--out", str(tmp_path / "out")]
    for n in ("-5", "0"):
        fails_cleanly(tmp_path, capsys, ["--tracker", "test-still", *data, "--max-segments", n],
                      f"--max-segments must be >= 1, got {n}")


def test_out_that_is_a_file_fails_before_the_run(tmp_path, capsys):
    make(tmp_path / "a.h5")
    (tmp_path / "afile.txt").write_text("hi\n")
    fails_cleanly(tmp_path, capsys, ["--tracker", "test-still", "--data", str(tmp_path / "a.h5"),
                                     "--out", str(tmp_path / "afile.txt")], "--out names a file, not a directory")
    # a file to write that is a directory inside --out
    (tmp_path / "out" / "results.csv").mkdir(parents=True)
    fails_cleanly(tmp_path, capsys, ["--tracker", "test-still", "--data", str(tmp_path / "a.h5"),
                                     "--out", str(tmp_path / "out")], "results.csv: --out names a directory")
    (tmp_path / "out" / "results.csv").rmdir()
    (tmp_path / "out" / "a.gif").mkdir()
    fails_cleanly(tmp_path, capsys, ["--tracker", "test-still", "--data", str(tmp_path / "a.h5"),
                                     "--out", str(tmp_path / "out"), "--video", "a"],
                  "a.gif: --video names a directory")


def test_bad_checkpoints_fail_before_the_run(tmp_path, capsys):
    make(tmp_path / "a.h5")
    d = checkpoints(tmp_path)
    words = {"nothere": "no such checkpoint", "garbage": "not a readable SCTN checkpoint",
             "trunc": "not a readable SCTN checkpoint", "notsctn": "not an SCTN checkpoint",
             "list": "not an SCTN checkpoint", "missingkey": "Missing key(s) in state_dict",
             "badconfig": "config field 'bogus'", "badshape": "size mismatch for convs.0.weight"}
    for name, expected in words.items():
        ckpt = str(d / f"{name}.pt")
        for extra in ([], ["--no-energy"]):
            fails_cleanly(tmp_path, capsys, ["--tracker", "sctn", "--data", str(tmp_path / "a.h5"), "--checkpoint",
                                             ckpt, "--out", str(tmp_path / "out"), *extra], [f"{ckpt}: ", expected])


def test_checkpoint_without_sctn_is_an_error(tmp_path, capsys):
    make(tmp_path / "a.h5")
    fails_cleanly(tmp_path, capsys, ["--tracker", "test-still", "--data", str(tmp_path / "a.h5"), "--checkpoint",
                                     str(tmp_path / "nothere.pt"), "--out", str(tmp_path / "out")],
                  "only used by --tracker sctn")


def test_bad_options_fail_before_the_run(tmp_path, capsys):
    make(tmp_path / "a.h5")
    data = ["--data", str(tmp_path / "a.h5"), "--out", str(tmp_path / "out")]
    cases = [
        ("rct", "rct.bogus=1", "--option rct.bogus=1: tracker 'rct' has no option 'bogus'"),
        ("rct", "rct.cluster_size=-1", "--option rct.cluster_size=-1: Input should be greater than 0"),
        ("rct", "rct.cluster_size=abc", "--option rct.cluster_size=abc: Input should be a valid number"),
        ("test-still", "test-still.bogus=1", "--option test-still.bogus=1: tracker 'test-still' takes no options"),
        ("sctn", "sctn.bogus=1", "--option sctn.bogus=1: tracker 'sctn' has no option 'bogus'"),
        ("sctn", "sctn.crop=foo", "--option sctn.crop=foo: Input should be 'bilinear' or 'nearest'"),
        ("sctn", "sctn.fast=maybe", "--option sctn.fast=maybe: Input should be a valid boolean"),
        ("sctn", "sctn.n_candidates=0", "--option sctn.n_candidates=0: Input should be greater than or equal to 1"),
        ("sctn", "sctn.trans=.nan", "--option sctn.trans=.nan: Input should be a finite number"),
    ]
    for tracker, option, words in cases:
        fails_cleanly(tmp_path, capsys, ["--tracker", tracker, *data, "--option", option], words)


def test_unknown_video_leaves_existing_tables_alone(tmp_path, capsys):
    make(tmp_path / "a.h5")
    out = tmp_path / "out"
    assert main(["bench", "--tracker", "test-still", "--data", str(tmp_path / "a.h5"), "--out", str(out),
                 "--jobs", "1", "--quiet", "--max-segments", "5"]) == 0
    capsys.readouterr()
    fails_cleanly(tmp_path, capsys, ["--tracker", "test-still", "--data", str(tmp_path / "a.h5"), "--out", str(out),
                                     "--video", "nosuchseq"], "--video nosuchseq: no such sequence in this run")


def test_two_files_of_one_sequence_name_are_an_error(tmp_path, capsys):
    for sub in ("x", "y"):
        (tmp_path / sub).mkdir()
        make(tmp_path / sub / "a.h5")
    fails_cleanly(tmp_path, capsys, ["--tracker", "test-still", "--data", str(tmp_path / "x"), str(tmp_path / "y"),
                                     "--out", str(tmp_path / "out")], "sequence 'a' is also in")


def test_an_interrupted_run_leaves_existing_tables_alone(tmp_path, capsys):
    make(tmp_path / "a.h5", moving=False)
    out = tmp_path / "out"
    assert main(["bench", "--tracker", "test-still", "--data", str(tmp_path / "a.h5"), "--out", str(out),
                 "--jobs", "1", "--quiet"]) == 0
    before = snapshot(tmp_path)
    assert main(["bench", "--tracker", "test-still", "--tracker", "test-interrupt", "--data", str(tmp_path / "a.h5"),
                 "--out", str(out), "--jobs", "1", "--quiet"]) == 130
    assert snapshot(tmp_path) == before


def test_a_tracker_crash_is_reported_and_exits_1(tmp_path, capsys):
    make(tmp_path / "moving.h5")
    make(tmp_path / "still.h5", moving=False)
    out = tmp_path / "out"
    assert main(["bench", "--tracker", "test-still", "--tracker", "test-crash", "--data", str(tmp_path),
                 "--out", str(out), "--jobs", "1", "--quiet"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    # one line per failure, naming tracker, sequence and the error (its two lines joined)
    assert len(err) == 2, err
    for line, seq in zip(sorted(err), ("moving", "still")):
        assert line.startswith(f"dvsot bench: failed: test-crash on {seq}: RuntimeError: boom second line ("), line
    res = json.loads((out / "results.json").read_text())
    assert res["test-still"]["still"]["A"] == 1.0 and res["test-still"]["all"]["error"] is None
    assert res["test-crash"]["still"]["error"].startswith("RuntimeError: boom")
    assert res["test-crash"]["all"]["error"] == "all sequences failed"


def test_option_values_read_as_yaml():
    from benchmarks.bench.plan import _options

    opts = _options(
        ["sctn.fast=False", "sctn.trans=1e-1", "rct.cluster_size=0.05", "sctn.crop=nearest"], ["sctn", "rct"]
    )
    assert opts == {"sctn": {"fast": False, "trans": 0.1, "crop": "nearest"}, "rct": {"cluster_size": 0.05}}


def test_bench_on_a_dask_local_cluster_gives_the_same_results(tmp_path):
    from synthetic import moving_square_file

    data = tmp_path / "data"
    data.mkdir()
    moving_square_file(data / "a.h5", split="test", seed=1)
    moving_square_file(data / "b.h5", split="test", seed=2, velocity_px_s=(-80.0, 40.0), start=(100.0, 40.0))
    res = {}
    for how in (["--jobs", "1"], ["--scheduler", "local:1"]):
        out = tmp_path / how[1].replace(":", "")
        assert (
            main(
                [
                    "bench",
                    "--tracker",
                    "rct",
                    "--data",
                    str(data),
                    "--out",
                    str(out),
                    "--quiet",
                    "--max-segments",
                    "8",
                    *how,
                ]
            )
            == 0
        )
        res[how[0]] = {s: {k: v[k] for k in ("A", "R", "segments")}
                       for s, v in json.loads((out / "results.json").read_text())["rct"].items()}
    assert res["--jobs"] == res["--scheduler"] and set(res["--jobs"]) >= {"a", "b"}
