"""The Table 3 script: rows compared with the paper and per-block sums that add up."""

import json

from benchmarks.perf import count_macs


def test_table_rows_and_blocks(capsys):
    assert count_macs.main(["--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    out = count_macs.table(rows, layers=True)
    assert "| SiamRPN 127/255 | 4.821e9 | 4.820e9 | +0.0% |" in out and "| backbone.conv4_x |" in out
    for row in rows:
        assert sum(row["frame_blocks"].values()) == row["per_frame"]
        assert sum(row["init_blocks"].values()) == row["init"]


def test_block_names():
    assert count_macs.block("SiamMask.backbone.conv4_x.3.conv2.0") == "backbone.conv4_x"
    assert count_macs.block("functional") == count_macs.block("SiamRPN") == "correlation"
