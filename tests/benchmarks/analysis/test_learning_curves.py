"""Learning curves of several runs (models x seeds) from synthetic checkpoint histories: grouping, mean and spread per
model, and the step where validation ARscore stops improving."""

import json

import numpy as np
import pytest

from benchmarks.analysis.learning_curves import main, model_means, plateau, plateaus, read_curves


def _write(path, model: str, seed: int, arscores: dict[int, float], losses: dict[int, float] | None = None,
           extra: str = "accuracy") -> str:
    """A checkpoint .json whose history holds validations at the steps of `losses` (or of `arscores`)."""
    losses = losses or {s: 1.0 / s for s in arscores}
    val = [{"step": s, "loss": loss, extra: 0.5} | ({"arscore": arscores[s]} if s in arscores else {})
           for s, loss in sorted(losses.items())]
    last = dict(val[-1])
    val.append(last)  # the final step is validated twice, as training does
    path.write_text(json.dumps({"model": model, "train_config": {"seed": seed},
                                "history": {"validation": "files", "val": val}}))
    return str(path)


def test_plateau_is_the_first_step_no_later_evaluation_beats_by_more_than_the_tolerance():
    curve = [(100, 0.30), (200, 0.50), (300, 0.55), (400, 0.54), (500, 0.56)]
    assert plateau(curve, 0.01) == (300, 0.55)  # 0.56 beats 0.55 by 0.01: not more than the tolerance
    assert plateau(curve, 0.0) == (500, 0.56)  # no tolerance: the last best
    assert plateau(curve, 0.06) == (200, 0.50)
    assert plateau(curve, 1.0) == (100, 0.30)
    assert plateau([(7, 0.2)], 0.01) == (7, 0.2) and plateau([], 0.01) is None
    dip = [(1, 0.6), (2, 0.1), (3, 0.605), (4, 0.3)]
    assert plateau(dip, 0.01) == (1, 0.6)  # a later dip does not move it; a later gain within tolerance neither
    with pytest.raises(ValueError, match="tolerance"):
        plateau(curve, -0.1)


def test_runs_of_each_model_are_averaged_on_their_common_steps(tmp_path):
    files = [_write(tmp_path / "a0.json", "sctn", 0, {2: 0.2, 4: 0.4, 6: 0.5}),
             _write(tmp_path / "a1.json", "sctn", 1, {2: 0.4, 4: 0.6, 6: 0.5},
                    losses={1: 1.0, 2: 0.8, 4: 0.6, 6: 0.5, 7: 0.4}),
             _write(tmp_path / "s0.json", "siamfc", 0, {3: 0.1, 6: 0.7}, extra="centre_error_px")]
    curves = [read_curves(f) for f in files]
    assert [c["model"] for c in curves] == ["sctn", "sctn", "siamfc"] and curves[1]["seed"] == 1
    assert curves[2]["centre_error_px"] and not curves[2]["accuracy"]
    steps, mean, std = model_means(curves[:2], "arscore")
    assert steps.tolist() == [2, 4, 6]
    np.testing.assert_allclose(mean, [0.3, 0.5, 0.5])
    np.testing.assert_allclose(std, [0.1, 0.1, 0.0])
    assert model_means(curves[:2], "loss")[0].tolist() == [2, 4, 6]  # step 1 and 7: one run only
    found = plateaus(curves, 0.01)
    assert found["models"]["sctn"]["step"] == 4 and found["models"]["sctn"]["runs"] == 2
    assert found["models"]["sctn"]["run_steps"] == [6, 4] and found["models"]["sctn"]["mean_run_step"] == 5.0
    assert found["models"]["siamfc"]["step"] == 6
    assert [r["step"] for r in found["runs"]] == [6, 4, 6] and found["runs"][1]["best"] == 0.6


def test_the_command_draws_every_run_and_prints_the_plateaus(tmp_path, capsys):
    files = [_write(tmp_path / f"{m}{s}.json", m, s, {10: 0.1 + s / 10, 20: 0.5, 30: 0.5 + s / 100})
             for m in ("sctn", "sctn_ann", "siamfc") for s in range(3)]
    out = tmp_path / "curves.png"
    assert main([*files, "-o", str(out), "--tolerance", "0.015"]) == 0
    printed = capsys.readouterr().out
    assert out.stat().st_size > 0 and str(out) in printed
    rows = {line.split("|")[1].strip(): line.split("|") for line in printed.splitlines() if line.startswith("| ")}
    # mean curves 0.2, 0.5, 0.51: 0.51 is within 0.015 of 0.5
    assert all(rows[f"{m}: mean curve"][3].strip() == "20" for m in ("sctn", "sctn_ann", "siamfc"))
    assert rows["sctn seed 2 (sctn2)"][3].strip() == "30"  # 0.52 beats 0.5 by more than 0.015


def test_bad_input_is_one_line_and_no_picture(tmp_path, capsys):
    good = _write(tmp_path / "g.json", "sctn", 0, {1: 0.5})
    empty = tmp_path / "e.json"
    empty.write_text(json.dumps({"history": {"val": []}}))
    broken = tmp_path / "b.json"
    broken.write_text("{not json")
    for argv, words in (([good, str(empty)], "no validation history"), ([good, str(broken)], "not JSON"),
                        ([good, "--tolerance", "-1"], "--tolerance"), ([good, "--tolerance", "nan"], "--tolerance")):
        out = tmp_path / "x.png"
        assert main([*argv, "-o", str(out)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and words in err[0], err
        assert not out.exists()
