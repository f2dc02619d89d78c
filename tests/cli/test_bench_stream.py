"""`dvsot bench --protocol stream` end to end with rct on a tiny synthetic file, and its option refusals."""

import csv
import json

import numpy as np
import pytest

from dvsot.cli import main
from tests.synthetic import moving_square_file


@pytest.fixture(scope="module")
def square(tmp_path_factory):
    return moving_square_file(tmp_path_factory.mktemp("s") / "sq.h5", width=96, height=72, size=20,
                              duration_ms=80, velocity_px_s=(200.0, 0.0), split="test")


def test_rct_streams_end_to_end(square, tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["bench", "--tracker", "rct", "--data", str(square), "--protocol", "stream", "--latency", "measured",
                 "--latency", "scaled:1,4", "--query-hz", "500", "--stream-window", "since", "--predictive",
                 "--out", str(out), "--quiet", "--plots"]) == 0
    printed = capsys.readouterr().out
    assert "| rct | measured |" in printed and "| rct (predictive) | scaled:4 |" in printed
    summary = json.loads((out / "stream.json").read_text())
    assert summary["settings"] == {"latency": ["measured", "scaled:1,4"], "query_hz": 500.0, "window": "since",
                                   "predictive": True}
    assert summary["machines"] and summary["machines"][0]["threads"] >= 1  # a measured run names its machine
    rows = summary["rows"]["rct"]
    assert set(rows) == {"free", "measured", "scaled:1", "scaled:4"}
    assert rows["measured"]["all"]["queries"] == 35  # 500 Hz after the init at 10 ms up to 80 ms
    assert set(summary["drop"]["rct"]) == {"measured", "scaled:1", "scaled:4"}
    assert [f for f, _ in summary["scale_curves"]["rct"]] == [1.0, 4.0]
    # per row, the factor at which it falls to half its latency-free ARscore, in the json and the printed table
    assert set(summary["half_factor"]) == {"rct", "rct (predictive)"}
    assert "scale factor at half the latency-free ARscore" in printed
    for name in ("stream.md", "latency_scale.png", "iou_over_time.png", "run.json"):
        assert (out / name).is_file()
    with open(out / "rct" / "stream" / "sq.scaled-4.csv") as f:
        calls = list(csv.DictReader(f))
    assert calls[0]["kind"] == "init" and all(c["kind"] == "update" for c in calls[1:])
    t1 = np.array([int(c["t1_us"]) for c in calls[1:]])
    avail = np.array([int(c["available_us"]) for c in calls[1:]])
    lat = np.array([float(c["latency_s"]) for c in calls[1:]])
    assert np.all(avail - t1 == np.ceil(lat * 1e6 - 1e-6))  # each answer arrives its latency after its window
    assert np.all(t1[1:] >= avail[:-1])  # the next call starts when the previous answer is out


@pytest.mark.parametrize("flags, message", [
    (["--latency", "wall"], "--latency wall: unknown latency model"),
    (["--latency", "declared:tpu"], "--latency declared:tpu: unknown hardware profile 'tpu'"),
    (["--latency", "declared:cpu"], "--latency declared:cpu: tracker 'rct' has no latency under it"),
    (["--query-hz", "0.5"], "--query-hz 0.5: outside 1..1e+06 Hz"),
    (["--query-hz", "0"], "--query-hz 0: outside"),
    (["--latency", "scaled:1,-2"], "--latency scaled:1,-2: scale factor '-2'"),
    (["--query-hz", "2e6"], "--query-hz 2e+06: outside"),
    (["--query-hz", "nan"], "--query-hz nan: outside"),
    (["--latency", "declared:"], "--latency declared:: unknown latency model"),
    (["--tracker", "siamfc", "--latency", "declared:loihi"], "--latency declared:loihi: tracker 'rct' has no latency"),
    (["--video", "sq"], "--video sq: not made by --protocol stream"),
])
def test_bad_stream_options_exit_2_before_any_tracking(square, tmp_path, capsys, flags, message):
    out = tmp_path / "run"
    assert main(["bench", "--tracker", "rct", "--data", str(square), "--protocol", "stream", *flags,
                 "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0]
    assert not out.exists()


def test_stream_flags_without_the_stream_protocol_are_refused(square, tmp_path, capsys):
    assert main(["bench", "--tracker", "rct", "--data", str(square), "--predictive", "--out", str(tmp_path / "r"),
                 "--quiet"]) == 2
    assert "--predictive: only with --protocol stream" in capsys.readouterr().err


def test_declared_runs_are_bit_identical_across_reruns_and_jobs(square, tmp_path, capsys):
    second = moving_square_file(tmp_path / "sq2.h5", width=96, height=72, size=20, duration_ms=60,
                                velocity_px_s=(0.0, 150.0), split="test")
    outs = []
    for k, jobs in enumerate(["1", "2"]):  # a rerun, in worker processes
        out = tmp_path / f"run{k}"
        assert main(["bench", "--tracker", "siamfc", "--data", str(square), str(second), "--protocol", "stream",
                     "--latency", "declared:cpu", "--latency", "declared:loihi", "--no-energy", "--jobs", jobs,
                     "--out", str(out), "--quiet"]) == 0
        files = sorted(p.relative_to(out) for p in out.rglob("*") if p.is_file() and p.name != "run.json")
        outs.append({p: (out / p).read_bytes() for p in files})
    assert outs[0] == outs[1]
    assert any(str(p).endswith("sq2.declared-loihi.csv") for p in outs[0])
