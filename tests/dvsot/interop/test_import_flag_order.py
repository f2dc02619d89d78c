"""`import` refuses flags that need another flag before it reads any event."""

from __future__ import annotations

from pathlib import Path

from dvsot.cli import main


def test_absent_without_boxes_is_refused_before_the_events_are_read(tmp_path: Path, capsys) -> None:
    events = tmp_path / "e.csv"
    events.write_text("t,x,y,p\n0,1,1,1\n5,not a number,1,1\n")  # reading it would fail on line 3
    absent = tmp_path / "absent.txt"
    absent.write_text("0\n1\n")
    out = tmp_path / "o.h5"
    assert main(["import", str(events), "--size", "32x32", "--absent", str(absent), "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "need a box file (--boxes)" in err[0] and "absent.txt" in err[0], err
    assert not out.exists()
