"""Table 2 rows over seeds: means and standard deviations checked by hand, and bad groups refused."""

import pytest

from benchmarks.analysis import seed_table

HEADER = "tracker,sequence,A,R,ARscore,segments,failures,inits,segments_per_s,init_s,energy_pj,error\n"


def bench_dir(root, name, tracker, rows):
    d = root / name
    d.mkdir()
    lines = [f"{tracker},{seq},{a},{r},{ar},10,0,1,5.0,1.0,," for seq, (a, r, ar) in rows.items()]
    (d / "results.csv").write_text(HEADER + "\n".join(lines) + "\n")
    return d


def test_mean_and_std_over_seeds(tmp_path):
    a = bench_dir(tmp_path, "s0", "sctn", {"x": (0.6, 0.9, 0.8), "all": (0.6, 0.9, 0.8)})
    b = bench_dir(tmp_path, "s1", "sctn", {"x": (0.8, 1.0, 0.9), "all": (0.8, 1.0, 0.9)})
    row = seed_table.seed_row("sctn", [a, b])
    assert row.seeds == 2 and row.tracker == "sctn"
    mean, std = row.cells["all"]["ARscore"]
    assert mean == pytest.approx(0.85) and std == pytest.approx(0.05)  # ddof 0
    assert row.cells["x"]["A"] == (pytest.approx(0.7), pytest.approx(0.1))
    md = seed_table.to_markdown([row])
    assert "| sctn | 2 | 0.850 ± 0.050 | 0.700 ± 0.100 / 0.950 ± 0.050 / **0.850 ± 0.050** |" in md
    assert "sctn,sctn,2,all,ARscore,0.8500,0.0500" in seed_table.to_csv([row])


def test_groups_must_be_like_runs(tmp_path):
    a = bench_dir(tmp_path, "s0", "sctn", {"x": (0.6, 0.9, 0.8), "all": (0.6, 0.9, 0.8)})
    b = bench_dir(tmp_path, "s1", "kcf", {"x": (0.6, 0.9, 0.8), "all": (0.6, 0.9, 0.8)})
    c = bench_dir(tmp_path, "s2", "sctn", {"y": (0.6, 0.9, 0.8), "all": (0.6, 0.9, 0.8)})
    with pytest.raises(ValueError, match="tracker kcf"):
        seed_table.seed_row("g", [a, b])
    with pytest.raises(ValueError, match="different sequences"):
        seed_table.seed_row("g", [a, c])
    with pytest.raises(ValueError, match="no results.csv"):
        seed_table.read_results(tmp_path)


def test_cli_refuses_a_group_matching_nothing(tmp_path, capsys):
    assert seed_table.main([f"g={tmp_path}/nothing*"]) == 2
    assert "matches no directory" in capsys.readouterr().err
    bench_dir(tmp_path, "s0", "sctn", {"x": (0.6, 0.9, 0.8), "all": (0.6, 0.9, 0.8)})
    assert seed_table.main([f"sctn={tmp_path}/s*"]) == 0
    assert "**0.800 ± 0.000**" in capsys.readouterr().out
