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


def test_the_papers_table2_follows_its_own_a_and_r():
    from benchmarks.analysis.paper import TABLE2
    from benchmarks.evaluation.metrics import ar_score

    assert set(TABLE2) == {"rct", "goturn", "siamrpn", "siammask", "ocean", "automatch", "sctn"}
    for tracker, row in TABLE2.items():
        assert set(row) == {"city_bottle", "city_cat", "city_star", "sky_cube", "woman_ball", "all"}, tracker
        for seq, (a, r, printed) in row.items():  # printed to three places from unrounded A and R
            assert ar_score(a, r) == pytest.approx(printed, abs=1.5e-3), (tracker, seq)


def test_paper_row_under_the_first_row_of_a_tracker_it_reports(tmp_path):
    seqs = ["city_bottle", "city_cat", "city_star", "sky_cube", "woman_ball", "all"]
    sctn = [bench_dir(tmp_path, f"s{i}", "sctn", {s: (0.7, 0.9, 0.85) for s in seqs}) for i in range(2)]
    twin = bench_dir(tmp_path, "t0", "sctn_ann", {s: (0.7, 0.9, 0.85) for s in seqs})
    rows = [seed_table.seed_row("preset", sctn), seed_table.seed_row("online", sctn),
            seed_table.seed_row("twin", [twin])]
    md = seed_table.to_markdown(rows, with_paper=True)
    lines = md.splitlines()
    assert lines[3] == "| sctn, paper | - | 0.912 | 0.904 | 0.896 | 0.948 | 0.907 | 0.773 / 0.960 / **0.916** |"
    assert lines[2].startswith("| preset |") and lines[4].startswith("| online |") and len(lines) == 6
    assert "paper" not in seed_table.to_markdown(rows)
    other = bench_dir(tmp_path, "x0", "goturn", {"x": (0.6, 0.9, 0.8), "all": (0.6, 0.9, 0.8)})
    assert "paper" not in seed_table.to_markdown([seed_table.seed_row("g", [other])], with_paper=True)
