"""`simulate_file` refuses what `dvsot simulate` refuses, naming the parameter where the command names its flag,
before a file is begun."""

from __future__ import annotations

import re

import numpy as np
import pytest

from dvsot.cli import main
from dvsot.core.errors import UserError
from dvsot.pipeline.simulate import simulate_file


def names(message: str, word: str) -> bool:
    """Whether message names `word` as a word of its own (not inside a path)."""
    return re.search(rf"(^|[\s'(]){re.escape(word)}([\s:']|$)", message) is not None


@pytest.mark.parametrize("kwargs, flags, param, flag", [
    ({"seed": -1}, ["--seed=-1"], "seed", "--seed"),
    ({"fps": 0.0}, ["--fps", "0"], "fps", "--fps"),
    ({"segment_us": 10}, ["--segment-us", "10"], "segment_us", "--segment-us"),
    ({"segment_us": 10**15}, ["--segment-us", str(10**15)], "segment_us", "--segment-us"),
    ({"params": {"cp": 1e308}}, ["--cp", "1e308"], "cp", "--cp"),
    ({"params": {"sigma_cp": -1.0, "sigma_cn": -1.0}}, ["--sigma=-1"], "sigma_cp", "--sigma"),
])
def test_the_same_refusal_from_python_and_from_the_command(tmp_path, capsys, kwargs, flags, param, flag):
    frames = tmp_path / "f.npy"
    np.save(frames, np.linspace(0.1, 0.9, 20 * 8 * 8, dtype=np.float32).reshape(20, 8, 8))
    out = tmp_path / "o.h5"
    with pytest.raises(UserError) as caught:
        simulate_file(frames, out, **{"fps": 1000.0, **kwargs})
    assert names(str(caught.value), param) and not names(str(caught.value), flag), caught.value
    fps = [] if "--fps" in flags else ["--fps", "1000"]
    assert main(["simulate", str(frames), *fps, *flags, "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and names(err[0], flag) and not names(err[0], param), err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f.npy"]
