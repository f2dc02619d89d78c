"""Sizes inside every bound that would still exhaust memory are refused before any work, with the estimate."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from dvsot.cli import main
from dvsot.core.errors import UserError
from dvsot.events import EventParams, memory


def test_estimate_grows_with_pixels_and_noise_events() -> None:
    ideal, hot = EventParams(), EventParams(hot_pixel_fraction=1.0, hot_pixel_hz=1e7)
    small = memory.peak_bytes(ideal, 640, 480, 1000)
    assert small < 1 << 30  # the default sensor is far inside any machine
    assert memory.peak_bytes(ideal, 8192, 8192, 1000) > 16 << 30
    assert memory.noise_events(hot, 640, 480, 15.625) == pytest.approx(4.8e7, rel=1e-3)
    assert memory.peak_bytes(hot, 640, 480, 15.625) > 7 << 30


def test_a_large_sensor_is_refused_with_the_estimate(monkeypatch) -> None:
    monkeypatch.setattr(memory, "usable_memory_bytes", lambda: 8 << 30)
    with pytest.raises(UserError, match=r"^scene: 8192x8192 px need about 2\d\.\d GB of memory at once, more than "
                                        r"the bound of 4\.0 GB \(0\.5 of this machine's 8\.0 GB\)"):
        memory.check_memory(EventParams(), 8192, 8192, 1000, "scene", render=True)
    memory.check_memory(EventParams(), 640, 480, 1000, "scene", render=True)  # passes


def test_simulate_refuses_hot_pixels_beyond_memory_before_writing(tmp_path: Path, capsys) -> None:
    stack = tmp_path / "s.npy"
    np.save(stack, np.full((3, 64, 64), 0.3, np.float32))
    out = tmp_path / "o.h5"
    assert main(["simulate", str(stack), "-o", str(out), "--fps", "50", "--segment-us", "1000",
                 "--hot-pixel-fraction", "1", "--hot-pixel-hz", "1e7", "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "8.19e+08 noise events between frames 20 ms apart" in err[0] and "GB" in err[0], err
    assert not out.exists()
