"""A dataset's name is free text: `bench --video` writes inside --out whatever the name,
and results.md / table.txt / results.tex keep one row per tracker and one column per sequence."""

from __future__ import annotations

import numpy as np

from dvsot.cli import main
from dvsot.dataset import DatasetWriter
from dvsot.events import EventBatch


def make(path, name: str) -> None:
    """A 64x48, 200 ms test file named `name`, a still 10x10 box with events inside it."""
    n = 400
    rng = np.random.default_rng(0)
    with DatasetWriter(path, 64, 48, attrs={"split": "test", "name": name}) as w:
        w.append_events(EventBatch(rng.integers(5, 15, n).astype(np.uint16), rng.integers(5, 15, n).astype(np.uint16),
                                   np.sort(rng.integers(0, 199_000, n)), rng.integers(0, 2, n).astype(np.uint8)))
        ts = np.arange(0, 200_001, 10_000)
        w.append_boxes(ts, np.tile([5.0, 5.0, 10.0, 10.0], (len(ts), 1)))
        w.close(200_000)


def files_under(root):
    return sorted(str(p.relative_to(root)) for p in root.rglob("*") if p.is_file())


def test_names_with_paths_pipes_and_newlines_stay_inside_out_and_tables(tmp_path, capsys):
    data = tmp_path / "a" / "b" / "data"
    data.mkdir(parents=True)
    names = ["../../escaped", "pipe|name", "two\nlines", ".hidden", "/abs/path"]
    for k, name in enumerate(names):
        make(data / f"s{k}.h5", name)
    out = tmp_path / "a" / "b" / "out"
    before = set(files_under(tmp_path))
    argv = ["bench", "--tracker", "rct", "--data", str(data), "--out", str(out), "--jobs", "1", "--quiet"]
    for name in names:
        argv += ["--video", name]
    assert main(argv) == 0, capsys.readouterr().err
    written = set(files_under(tmp_path)) - before
    assert written and all(p.startswith("a/b/out/") and ".." not in p.split("/") for p in written), written
    gifs = [p for p in written if p.endswith(".gif") and p.count("/") == 3]
    assert len(gifs) == len(names) and not any(p.split("/")[-1].startswith(".") for p in gifs), gifs
    md = (out / "results.md").read_text().split("\n\n")[0].splitlines()
    assert len(md) == 3, md  # header, rule, one tracker
    cells = [len(line.replace("\\|", "").split("|")) for line in md]
    assert len(set(cells)) == 1 and cells[0] == len(names) + 6, md  # tracker, names, all, seg/s, init s + 2 ends
    assert main(["bench", "--tracker", "rct", "--data", str(data), "--out", str(out / "ope"), "--jobs", "1",
                 "--quiet", "--protocol", "ope"]) == 0
    ope = (out / "ope" / "ope.md").read_text().splitlines()
    assert len(ope) == 3 and len({len(line.replace("\\|", "").split("|")) for line in ope}) == 1, ope
    txt = (out / "table.txt").read_text().splitlines()
    assert len(txt) == 5 and len({line.replace("\\|", "").count("|") for line in txt if "|" in line}) == 1, txt
    tex = (out / "results.tex").read_text()
    assert "two\nlines" not in tex and "pipe|name" in tex and tex.count("\n") == 10, tex
