"""`export_dataset` and `import_recording` check their outputs as `dvsot export` and `dvsot import` do: the same
refusal from Python (naming the parameter) and from the command (naming the flag), before anything is written."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from synthetic import moving_square_file

from dvsot.cli import main
from dvsot.core.errors import UserError
from dvsot.interop.event_files import export_dataset, write_event_file
from dvsot.interop.recordings import import_recording


def snapshot(d: Path) -> dict:
    """Every file under d with its bytes."""
    return {str(p): (p.read_bytes() if p.is_file() else None) for p in sorted(d.rglob("*"))}


@pytest.fixture
def dataset(tmp_path) -> Path:
    """A small labelled dataset file."""
    return moving_square_file(tmp_path / "syn.h5", width=32, height=24, size=8, duration_ms=30,
                              velocity_px_s=(50.0, 0.0), start=(4.0, 4.0))


@pytest.fixture
def events(tmp_path) -> tuple[Path, Path]:
    """An events file (CSV) and a box file of t_s,x,y,w,h beside it."""
    n = 100
    write_event_file(tmp_path / "ev.csv", 1_000 + np.arange(n) * 400, np.full(n, 5), np.full(n, 6), np.arange(n) % 2,
                     32, 24)
    (tmp_path / "boxes.csv").write_text("0.001,2,2,8,8\n0.03,4,2,8,8\n")
    return tmp_path / "ev.csv", tmp_path / "boxes.csv"


def names(message: str, word: str) -> bool:
    """Whether message names the setting `word` (as a word of its own, not inside a path)."""
    return re.search(rf"(^|\s){re.escape(word)}[\s:]", message) is not None


def refused_both_ways(call, argv, param: str, flag: str, where: Path, capsys) -> None:
    """call() raises UserError naming param (not flag), `dvsot argv` exits 2 naming flag; neither writes a file."""
    before = snapshot(where)
    with pytest.raises(UserError) as caught:
        call()
    text = str(caught.value)
    assert names(text, param) and not names(text, flag), text
    assert snapshot(where) == before
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and names(err[0], flag) and not names(err[0], param), err
    # the same message, the flag in the parameter's place
    assert err[0] == f"dvsot {argv[0]}: error: " + re.sub(rf"(^|\s){re.escape(param)}(?=[\s:])", rf"\g<1>{flag}", text)
    assert snapshot(where) == before


def test_export_refuses_to_overwrite_its_input(dataset, capsys):
    # a link to the dataset file, named as an events file, is still the input
    link = dataset.parent / "same.csv"
    link.symlink_to(dataset)
    refused_both_ways(lambda: export_dataset(dataset, link, boxes=False),
                      ["export", str(dataset), "-o", str(link), "--no-boxes"], "out_path", "-o", dataset.parent, capsys)


def test_export_refuses_a_directory_and_an_unknown_suffix(dataset, tmp_path, capsys):
    (tmp_path / "d.csv").mkdir()
    refused_both_ways(lambda: export_dataset(dataset, tmp_path / "d.csv"),
                      ["export", str(dataset), "-o", str(tmp_path / "d.csv")], "out_path", "-o", tmp_path, capsys)
    refused_both_ways(lambda: export_dataset(dataset, tmp_path / "x.mp4"),
                      ["export", str(dataset), "-o", str(tmp_path / "x.mp4")], "out_path", "-o", tmp_path, capsys)


def test_export_refuses_a_boxes_file_that_is_its_input(dataset, tmp_path, capsys):
    (tmp_path / "out.csv.boxes.csv").symlink_to(dataset)
    refused_both_ways(lambda: export_dataset(dataset, tmp_path / "out.csv"),
                      ["export", str(dataset), "-o", str(tmp_path / "out.csv")], "out_path", "-o", tmp_path, capsys)


@pytest.mark.parametrize("which", ["events", "boxes"])
def test_import_refuses_to_overwrite_its_input(events, tmp_path, capsys, which):
    ev, boxes = events
    out = ev if which == "events" else boxes
    refused_both_ways(lambda: import_recording(ev, out, boxes=boxes, size=(32, 24)),
                      ["import", str(ev), "--boxes", str(boxes), "--size", "32x24", "-o", str(out)],
                      "out", "-o", tmp_path, capsys)


def test_import_refuses_a_segment_length_out_of_range(events, tmp_path, capsys):
    ev, boxes = events
    out = tmp_path / "o.h5"
    refused_both_ways(lambda: import_recording(ev, out, boxes=boxes, size=(32, 24), segment_us=0),
                      ["import", str(ev), "--boxes", str(boxes), "--size", "32x24", "--segment-us", "0",
                       "-o", str(out)],
                      "segment_us", "--segment-us", tmp_path, capsys)


def test_both_write_when_the_outputs_are_fine(dataset, events, tmp_path):
    written = export_dataset(dataset, tmp_path / "e.csv")
    assert [p.name for p in written] == ["e.csv", "e.csv.boxes.csv", "e.csv.gt.csv"]
    assert all(p.is_file() for p in written)
    ev, boxes = events
    assert import_recording(ev, tmp_path / "r.h5", boxes=boxes, size=(32, 24)).is_file()
