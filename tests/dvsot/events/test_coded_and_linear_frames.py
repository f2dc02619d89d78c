"""Coded frames (codes into a log table) and linear frames give the events of their log intensities, in every mode."""

from __future__ import annotations

import numpy as np
import pytest

from dvsot.core.errors import UserError
from dvsot.events import CodedFrame, EventParams, EventSimulator
from dvsot.events.frame_sources import _log_table

W, H = 40, 30


def _frames(dtype, n: int, seed: int) -> list[np.ndarray]:
    """8/16-bit frames that drift, jump and return to earlier values (ties on whole levels)."""
    rng = np.random.default_rng(seed)
    top = np.iinfo(dtype).max
    base = rng.integers(top // 8, top // 2, (H, W))
    out = []
    for i in range(n):
        step = rng.choice([-2, -1, 0, 1, 2], (H, W)) * (top // 40)
        base = np.clip(base + step * (rng.random((H, W)) < 0.3), 0, top)
        out.append((base if i % 5 else base[:, ::-1]).astype(dtype))  # mirrored frames: large jumps
    return out


def _run(frames, params, coded_at, table, seed=7):
    sim = EventSimulator(W, H, params, seed)
    out = []
    for i, f in enumerate(frames):
        frame = CodedFrame(f, table) if coded_at(i) else np.take(table, f)
        b = sim.step(frame, i * 997, is_log=True)
        out.append(np.stack([b.x.astype(np.int64), b.y, b.t, b.p, b.signal]))
    return np.concatenate(out, axis=1)


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16])
@pytest.mark.parametrize("params", [
    EventParams(),
    EventParams(cp=0.15, cn=0.25, sigma_cp=0.03, sigma_cn=0.03, refractory_us=300),
    EventParams(sigma_cp=0.05, sigma_cn=0.05, mismatch="per_interval"),
    EventParams(cp=0.1, cn=0.1, shot_noise_hz=500, leak_hz=200),
], ids=["default", "mismatch-refractory", "per-interval", "noise"])
def test_coded_frames_give_the_events_of_their_log_intensities(dtype, params):
    frames = _frames(dtype, 40, seed=np.dtype(dtype).itemsize)
    table = _log_table(np.dtype(dtype).str, 1e-3)
    want = _run(frames, params, lambda i: False, table)
    assert want.shape[1] > 1000
    assert np.array_equal(_run(frames, params, lambda i: True, table), want)
    # coded and float frames mixed: the state carries over both ways
    assert np.array_equal(_run(frames, params, lambda i: (i // 3) % 2 == 0, table), want)


def test_a_new_table_is_used_from_its_first_frame():
    frames = _frames(np.uint8, 12, seed=5)
    t1, t2 = _log_table("|u1", 1e-3), _log_table("|u1", 1e-2)
    sim_c, sim_f = EventSimulator(W, H, seed=1), EventSimulator(W, H, seed=1)
    for i, f in enumerate(frames):
        table = t1 if i < 6 else t2
        bc, bf = sim_c.step(CodedFrame(f, table), i * 1000), sim_f.step(np.take(table, f), i * 1000, is_log=True)
        assert np.array_equal(bc.t, bf.t) and np.array_equal(bc.x, bf.x) and np.array_equal(bc.p, bf.p)


def test_bad_coded_frames_are_refused():
    sim = EventSimulator(W, H)
    table = _log_table("|u1", 1e-3)
    with pytest.raises(UserError, match="shape"):
        sim.step(CodedFrame(np.zeros((H, W + 1), np.uint8), table), 0)
    with pytest.raises(UserError, match="uint8 or uint16"):
        sim.step(CodedFrame(np.zeros((H, W), np.int16), table), 0)
    with pytest.raises(UserError, match="256 float64"):
        sim.step(CodedFrame(np.zeros((H, W), np.uint8), table[:200]), 0)
    with pytest.raises(UserError, match="increasing"):
        sim.step(CodedFrame(np.zeros((H, W), np.uint8), table[::-1].copy()), 0)
    with pytest.raises(UserError, match="its table 256"):
        sim.step(CodedFrame(np.zeros((H, W), np.uint8), table), 0)
        sim.step(CodedFrame(np.zeros((H, W), np.uint16), table), 1000)


def _linear_frames(dtype, n: int, seed: int) -> list[np.ndarray]:
    """Linear frames of several types: smooth drifts, jumps, exact returns, zeros."""
    rng = np.random.default_rng(seed)
    ints = _frames(np.uint8, n, seed)
    if np.dtype(dtype).kind == "u":
        return [f.astype(dtype) for f in ints]
    return [(f / 255.0 * (1 + 0.01 * rng.standard_normal((H, W))) * (rng.random((H, W)) > 0.02)).astype(dtype)
            for f in ints]


@pytest.mark.parametrize("dtype", [np.float32, np.float64, np.uint8])
@pytest.mark.parametrize("params", [
    EventParams(),
    EventParams(cp=0.15, cn=0.25, sigma_cp=0.03, sigma_cn=0.03, refractory_us=300, log_eps=1e-2),
    EventParams(sigma_cp=0.05, sigma_cn=0.05, mismatch="per_interval"),
    EventParams(cp=0.1, cn=0.1, shot_noise_hz=500, leak_hz=200),
], ids=["default", "mismatch-refractory-eps", "per-interval", "noise"])
def test_linear_frames_give_the_events_of_their_log_intensities(dtype, params):
    frames = _linear_frames(dtype, 40, seed=11)
    eps = params.log_eps

    def run(mode):
        sim = EventSimulator(W, H, params, 7)
        out = []
        for i, f in enumerate(frames):
            if mode(i) == "log":
                b = sim.step(np.log(np.add(f, eps, dtype=np.float64)), i * 997, is_log=True)
            elif mode(i) == "coded" and f.dtype == np.uint8:  # a table of I + eps, as the linear frame means
                b = sim.step(CodedFrame(f, np.log(np.arange(256.0) + eps)), i * 997)
            else:
                b = sim.step(f, i * 997)
            out.append(np.stack([b.x.astype(np.int64), b.y, b.t, b.p, b.signal]))
        return np.concatenate(out, axis=1)

    want = run(lambda i: "log")
    assert want.shape[1] > 500
    assert np.array_equal(run(lambda i: "linear"), want)
    assert np.array_equal(run(lambda i: ("linear", "log", "coded")[(i // 3) % 3]), want)


def test_bad_linear_frames_are_refused_as_before_and_change_nothing():
    sim = EventSimulator(W, H)
    ok = np.full((H, W), 0.5, np.float32)
    sim.step(ok, 0)
    for value, message in ((np.nan, "NaN or infinite"), (np.inf, "NaN or infinite"), (-1.0, "negative")):
        bad = ok.copy()
        bad[3, 4] = value
        with pytest.raises(UserError, match=message):
            sim.step(bad, 1000)
    both = ok.copy()
    both[0, 0], both[1, 1] = -1.0, np.nan  # NaN hides the negative value from min(), as it always did
    with pytest.raises(UserError, match="NaN or infinite"):
        sim.step(both, 1000)
    neg = ok.copy()
    neg[0, 0] = -1.0
    with pytest.raises(UserError, match="negative"):  # before the timestamp is looked at
        sim.step(neg, 0)
    assert len(sim.step(ok * 2, 1000)) == W * H * 3  # log(2) / 0.2: three levels each, nothing lost above
