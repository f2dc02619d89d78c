"""Every preset's events, pinned: digests taken from the sensor model before its stages were made faster, on
linear, log and 8-bit coded frames; a change of speed must not change an event."""

from __future__ import annotations

import hashlib

import numpy as np
import pytest

from dvsot.events import CodedFrame, EventParams, EventSimulator, log_intensity
from tests.dvsot.events.test_sensor_ideal import H, W, codes_sequence, times_us

# the presets with noise strong enough that every stage (shot, leak, hot pixels, latency, readout) fires here
CASES = {
    "clean": dict(preset="clean"),
    "noisy": dict(preset="noisy", shot_noise_hz=200.0, leak_hz=20.0),
    "davis346": dict(preset="davis346", shot_noise_hz=200.0, leak_hz=20.0, hot_pixel_fraction=0.01,
                     hot_pixel_hz=2000.0, readout_limit_hz=3e6, readout_fifo_events=256),
    "davis346_as_is": dict(preset="davis346"),
    "gen4": dict(preset="gen4", shot_noise_hz=100.0, hot_pixel_fraction=0.01, hot_pixel_hz=500.0),
}
KINDS = ("linear", "log", "coded")

# sha256 of x, y, t, p, signal, noise_kind of every batch and the sensor's counts (seed 11)
REFERENCE = {
    "clean": "4c1a70435baa262ba68e9b4876205cb2cf0e455a2de498e430eacaac0b08500d",
    "davis346": "453608804e8af6c2563a06b228cc6bdffefe73ced87b9ab88dfb7a8af3a6064d",
    "davis346_as_is": "29ef98cde1117e21f0262d3ccb0f729144acd2ddd247d566c2c66af2661521bc",
    "gen4": "1d9c2f762536b30f82655e806261db017a878851d28c29549806c27e0e9227b3",
    "noisy": "2d0459fdd63d16d4a2beba98468394ac685be9f8dcaf8755540487b91c90dd7e",
}


def run(case: str, kind: str) -> str:
    params = EventParams(**CASES[case])
    sim = EventSimulator(W, H, params, seed=11)
    table = log_intensity(np.arange(256, dtype=np.float32).reshape(1, -1) / 255.0, params.log_eps)
    h = hashlib.sha256()
    for frame, t in zip(codes_sequence(), times_us()):
        if kind == "linear":
            b = sim.step(frame.astype(np.float32) / np.float32(255.0), t)
        elif kind == "log":
            b = sim.step(np.take(table, frame), t, is_log=True)
        else:
            b = sim.step(CodedFrame(frame, table), t)
        for col in (b.x, b.y, b.t, b.p, b.signal, b.noise_kind):
            h.update(np.ascontiguousarray(col).tobytes())
    h.update(repr(sorted(sim.sensor_counts().items())).encode())
    return h.hexdigest()


@pytest.mark.parametrize("case", sorted(CASES))
@pytest.mark.parametrize("kind", KINDS)
def test_each_preset_gives_its_pinned_events(case, kind):
    assert run(case, kind) == REFERENCE[case]
