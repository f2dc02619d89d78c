"""The sensor model's stages against closed forms: photoreceptor, low-pass step response, noise rates and their
spread, hot pixels, latency, the readout limit; presets, overrides, bad values and the file's noise kinds."""

from __future__ import annotations

import math

import h5py
import numpy as np
import pytest

from dvsot.core.errors import UserError
from dvsot.events import EventParams, EventSimulator
from dvsot.events.batch import NOISE_KINDS, EventBatch
from dvsot.events.presets import PRESETS, sensor_on
from dvsot.events.sensor import front_end, readout


def run(params: EventParams, frames, times, width: int, height: int = 1, seed: int = 0, is_log: bool = True):
    sim = EventSimulator(width, height, params, seed)
    batches = [
        sim.step(np.asarray(f, np.float64).reshape(height, width), t, is_log=is_log) for f, t in zip(frames, times)
    ]
    return EventBatch.concatenate(batches), sim


def test_ideal_is_the_default_and_every_stage_is_off_in_it():
    assert EventParams().preset == "ideal" and not sensor_on(EventParams())
    assert EventParams(preset="ideal") == EventParams()
    for name in PRESETS:
        if name != "ideal":
            assert sensor_on(EventParams(preset=name)), name


def test_a_preset_field_is_overridden_one_by_one():
    p = EventParams(preset="davis346", leak_hz=2.5)
    assert p.leak_hz == 2.5 and p.cp == PRESETS["davis346"]["cp"] and p.latency_us == PRESETS["davis346"]["latency_us"]
    assert EventParams(**p.model_dump()) == p  # a dump (the file's attributes) reads back as the same model


def test_linlog_photoreceptor_is_linear_below_the_knee_and_log_above():
    eps, knee = 1e-3, 0.08
    inten = np.array([0.0, 0.02, 0.05, 0.08, 0.2, 0.9])
    L = np.log(inten + eps)
    out = np.empty_like(L)
    front_end(L, out, np.empty(0), np.empty(0), True, knee, eps, 0, 0.0, 0.05)
    below = inten < knee
    expected = np.where(below, math.log(knee + eps) + (inten - knee) / (knee + eps), L)
    np.testing.assert_allclose(out, expected, rtol=0, atol=1e-12)


@pytest.mark.parametrize("order", [1, 2])
@pytest.mark.parametrize("inten", [0.05, 0.3, 1.0])
def test_lowpass_step_response_is_the_iir_closed_form(order, inten):
    eps, dark, cutoff, dt_s = 1e-3, 20 / 255, 50.0, 1e-4
    a0, a1 = math.log(inten / 4 + eps), math.log(inten + eps)  # a step up by a factor 4 to intensity inten
    lp1, lp2, out = np.empty(1), np.empty(1), np.empty(1)
    front_end(np.array([a0]), out, lp1, lp2, True, 0.0, eps, order, 0.0, dark)
    e = (inten + dark) / (1 + dark) * dt_s * 2 * math.pi * cutoff
    a = 1 - e
    for n in range(1, 200):
        front_end(np.array([a1]), out, lp1, lp2, False, 0.0, eps, order, dt_s * 2 * math.pi * cutoff, dark)
        y = 1 - a ** n if order == 1 else (1 - a ** n) - n * e * a ** n
        assert out[0] == pytest.approx(a0 + (a1 - a0) * y, abs=1e-12)


@pytest.mark.parametrize("inten", [0.1, 0.4, 1.0])
def test_lowpass_delays_the_first_event_by_tau_over_intensity(inten):
    """First ON event after a step: the continuous-time delay -tau_I ln(1 - C / A), within one frame interval."""
    eps, dark, cutoff, c = 1e-3, 20 / 255, 100.0, 0.2
    params = EventParams(cp=c, cn=c, lowpass_order=1, lowpass_cutoff_hz=cutoff, dark_intensity=dark, log_eps=eps)
    dt_us, n = 20, 2000
    lo, hi = math.log(inten / 3 + eps), math.log(inten + eps)
    frames = [lo] + [hi] * n  # the step at 0 us: the first update sees it after one frame interval
    times = [k * dt_us for k in range(n + 1)]
    ev, _ = run(params, frames, times, 1)
    tau_i = 1 / (2 * math.pi * cutoff) / ((inten + dark) / (1 + dark))
    expected_us = 1e6 * -tau_i * math.log(1 - c / (hi - lo))
    assert ev.p[0] == 1 and abs(ev.t[0] - expected_us) <= dt_us
    assert len(ev) == int((hi - lo) / c)  # the filter settles: every level of the step, once


def poisson_ok(count: int, mean: float) -> bool:
    return abs(count - mean) <= 5 * math.sqrt(mean)


@pytest.mark.parametrize("factor", [1.0, 0.25, 3.0])
@pytest.mark.parametrize("inten", [0.02, 0.3, 1.0])
def test_shot_noise_rate_depends_on_intensity_as_set(factor, inten):
    w, h, rate, dark = 200, 100, 20.0, 20 / 255
    params = EventParams(shot_noise_hz=rate, shot_noise_bright_factor=factor, dark_intensity=dark)
    frames = [np.full(w * h, math.log(inten + 1e-3))] * 11
    ev, _ = run(params, frames, [k * 100_000 for k in range(11)], w, h, seed=1)
    inten01 = (inten + dark) / (1 + dark)
    mean = rate * ((factor - 1) * inten01 + 1) * w * h * 1.0
    assert poisson_ok(len(ev), mean), (len(ev), mean)
    assert not ev.signal.any()
    assert ev.noise_kind is None if factor == 1 else np.all(ev.noise_kind == NOISE_KINDS.index("shot"))
    assert poisson_ok(int(ev.p.sum()), mean / 2)


def counts_per_pixel(params: EventParams, n: int, seconds: float, seed: int = 0) -> np.ndarray:
    frames = [np.zeros(n)] * 21
    ev, _ = run(params, frames, [int(k * seconds * 1e6 / 20) for k in range(21)], n, seed=seed)
    assert np.all(ev.p == 1)
    return np.bincount(ev.x, minlength=n)


def test_leak_rates_spread_log_normally_around_the_set_rate():
    n, rate, spread, seconds = 6_000, 10.0, 0.3, 20.0
    counts = counts_per_pixel(EventParams(leak_hz=rate, leak_spread_decades=spread, leak_period_cv=0.0), n, seconds)
    log_rates = np.log10(np.maximum(counts, 0.5) / seconds)
    assert 10 ** np.median(log_rates) == pytest.approx(rate, rel=0.03)
    assert np.std(log_rates) == pytest.approx(spread, rel=0.05)


@pytest.mark.parametrize("cv", [0.0, 0.5, 1.0])
def test_leak_periods_have_the_set_variation(cv):
    """A renewal process's counts over a long window have mean rate * T and Fano factor cv**2 (1: Poisson)."""
    n, rate, seconds = 6_000, 5.0, 40.0
    counts = counts_per_pixel(EventParams(leak_hz=rate, leak_period_cv=cv), n, seconds, seed=2)
    assert counts.mean() == pytest.approx(rate * seconds, rel=0.01)
    assert counts.var() / counts.mean() == pytest.approx(cv ** 2, abs=0.06)


def test_hot_pixels_are_the_set_fraction_at_the_set_rate():
    n, frac, rate = 50_000, 0.002, 200.0
    ev, sim = run(EventParams(hot_pixel_fraction=frac, hot_pixel_hz=rate), [np.zeros(n)] * 11,
                  [k * 100_000 for k in range(11)], n, seed=3)
    hot = np.unique(ev.x)
    assert len(hot) == round(frac * n) and np.all(ev.noise_kind == NOISE_KINDS.index("hot"))
    assert poisson_ok(len(ev), frac * n * rate * 1.0)


def moving_edge(n_frames: int = 40, w: int = 64):
    x = np.arange(w)
    return [np.log(np.where(x < 10 + k, 0.8, 0.1) + 1e-3) for k in range(n_frames)], [k * 1000 for k in range(n_frames)]


def test_latency_shifts_every_timestamp_by_its_constant():
    frames, times = moving_edge()
    ideal, _ = run(EventParams(), frames, times, 64)
    late, sim = run(EventParams(latency_us=250), frames, times, 64)
    kept = ideal.select(ideal.t + 250 <= times[-1])
    assert len(kept) > 20 and len(late) == len(kept)
    np.testing.assert_array_equal(late.t, kept.t + 250)
    np.testing.assert_array_equal(late.x, kept.x)
    np.testing.assert_array_equal(late.p, kept.p)
    assert sim.sensor_counts() == {"readout_dropped": 0, "held_at_end": len(ideal) - len(kept)}


def test_latency_jitter_keeps_time_order_and_never_goes_back():
    frames, times = moving_edge()
    ev, _ = run(EventParams(latency_us=100, latency_jitter_us=80, shot_noise_hz=50.0), frames, times, 64, seed=4)
    assert np.all(np.diff(ev.t) >= 0)
    ideal, _ = run(EventParams(), frames, times, 64)
    assert ev.select(ev.signal).t.min() >= ideal.t.min()


def test_readout_limit_delays_a_burst_by_one_period_each():
    state = np.zeros(1)
    keep, t_out, dropped = readout(np.zeros(10, np.int64), 100.0, 0, state)
    assert keep.all() and dropped == 0
    np.testing.assert_array_equal(t_out, np.arange(10) * 100)
    assert state[0] == 1000.0  # carried: the next event waits for the arbiter


@pytest.mark.parametrize("fifo", [1, 5, 30])
def test_readout_fifo_drops_what_does_not_fit(fifo):
    """A burst of M at once through a FIFO of N: one read at once, N waiting, the other M - N - 1 dropped."""
    m = 50
    keep, t_out, dropped = readout(np.full(m, 7, np.int64), 10.0, fifo, np.zeros(1))
    assert dropped == m - fifo - 1 and keep.sum() == fifo + 1
    np.testing.assert_array_equal(t_out[keep], 7 + np.arange(fifo + 1) * 10)


def test_readout_limit_caps_the_event_rate_and_counts_drops():
    w, h = 100, 100
    frames = [np.zeros(w * h), np.full(w * h, 1.0), np.zeros(w * h)]  # 5 ON and 5 OFF levels in every pixel
    times = [0, 1000, 1_000_000]
    ideal, _ = run(EventParams(), frames, times, w, h)
    limit, fifo = 20_000.0, 100
    ev, sim = run(EventParams(readout_limit_hz=limit, readout_fifo_events=fifo), frames, times, w, h)
    counts = sim.sensor_counts()
    assert len(ev) + counts["readout_dropped"] + counts["held_at_end"] == len(ideal)
    # over the second: at most limit * span + 1 events read out
    assert len(ev) <= limit * (ev.t[-1] - ev.t[0]) / 1e6 + 1
    assert counts["readout_dropped"] > 0 and np.all(np.diff(ev.t) >= int(1e6 / limit) - 1)


def test_noise_kinds_are_written_and_read_back(tmp_path):
    from dvsot.dataset import Dataset
    from dvsot.pipeline.simulate import simulate_file

    rng = np.random.default_rng(0)
    stack = np.clip(0.3 + 0.05 * rng.standard_normal((8, 24, 32)), 0, 1).astype(np.float32)
    np.save(tmp_path / "f.npy", stack)
    params = EventParams(preset="davis346", shot_noise_hz=200.0, hot_pixel_fraction=0.01, hot_pixel_hz=2000.0)
    summary = simulate_file(tmp_path / "f.npy", tmp_path / "o.h5", params, 1, fps=1000, segment_us=5000)
    assert summary["preset"] == "davis346" and "readout_dropped" in summary
    with h5py.File(tmp_path / "o.h5") as f:
        assert "noise_kind" in f["events"]
    with Dataset(tmp_path / "o.h5") as ds:
        assert ds.attrs["sensor_counts"]["readout_dropped"] == summary["readout_dropped"]
        batch = EventBatch.concatenate(list(ds.chunks()))
    assert batch.noise_kind is not None and np.array_equal(batch.signal, batch.noise_kind == 0)
    assert {NOISE_KINDS.index("shot"), NOISE_KINDS.index("hot")} <= set(np.unique(batch.noise_kind))
    from dvsot.dataset.info import dataset_info

    info = dataset_info(tmp_path / "o.h5")
    by_kind = info["noise_events_by_kind"]
    assert sum(by_kind.values()) == info["noise_events"] and by_kind["hot"] == int(np.sum(batch.noise_kind == 3))
    assert info["sensor_counts"] == {k: summary[k] for k in ("readout_dropped", "held_at_end")}


@pytest.mark.parametrize("flags, words", [
    (["--preset", "davis"], ["--preset", "davis346", "ideal", "gen4"]),
    (["--lowpass-order", "1"], ["--lowpass-cutoff-hz", "Hz", "> 0"]),
    (["--leak-hz", "-1"], ["--leak-hz", ">= 0", "per second"]),
    (["--hot-pixel-fraction", "1.5"], ["--hot-pixel-fraction", "<= 1"]),
    (["--readout-limit-hz", "0.5"], ["--readout-limit-hz", "events/s", ">= 1"]),
    (["--lowpass-order", "1", "--lowpass-cutoff-hz", "30", "--photoreceptor-noise-hz", "100"],
     ["--photoreceptor-noise-hz 100 Hz", "0.0006..60 events per pixel per second"]),
])
def test_out_of_range_sensor_values_are_one_line_and_exit_2(tmp_path, capsys, flags, words):
    from dvsot.cli import main

    np.save(tmp_path / "f.npy", np.full((3, 8, 8), 0.5, np.float32))
    assert main(["simulate", str(tmp_path / "f.npy"), "--fps", "100", "-o", str(tmp_path / "o.h5"), "--quiet",
                 *flags]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and all(w in err[0] for w in words), err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f.npy"]


def test_scene_files_name_a_preset_and_override_its_fields():
    from dvsot.scene.loader import parse_scene
    from tests.synthetic import MINIMAL_SCENE

    cfg = parse_scene(MINIMAL_SCENE + "events: {preset: davis346, leak_hz: 0.3}\n")
    assert cfg.events.preset == "davis346" and cfg.events.leak_hz == 0.3 and cfg.events.latency_us == 20.0
    with pytest.raises(UserError, match="preset 'foo' is unknown .known: ideal, clean, noisy, davis346, gen4"):
        parse_scene(MINIMAL_SCENE + "events: {preset: foo}\n")
    with pytest.raises(UserError, match=r"events.hot_pixel_fraction.*range >= 0 and <= 1"):
        parse_scene(MINIMAL_SCENE + "events: {hot_pixel_fraction: 2}\n")


def test_every_sensor_field_has_a_simulate_flag():
    from dvsot.cli.simulate import _STAGE_FLAGS
    from dvsot.events.presets import SENSOR_FIELDS

    stage_fields = set(EventParams.model_fields) - set(EventParams.model_fields).intersection(
        ["cp", "cn", "sigma_cp", "sigma_cn", "min_threshold", "mismatch", "refractory_us", "log_eps",
         "shot_noise_hz", "leak_hz", "preset"])
    assert set(SENSOR_FIELDS) <= stage_fields == set(_STAGE_FLAGS)


@pytest.mark.parametrize("preset", ["clean", "noisy", "davis346"])
def test_coded_linear_and_log_frames_give_the_same_events(preset):
    """The code-table front end (8-bit images) and the per-pixel one (linear or log frames) agree event for event."""
    from dvsot.events import CodedFrame, log_intensity
    from tests.dvsot.events.test_sensor_ideal import H, W, codes_sequence, times_us

    table = log_intensity(np.arange(256, dtype=np.float32).reshape(1, -1) / 255.0, 1e-3)
    out = {}
    for kind in ("coded", "linear", "log"):
        sim = EventSimulator(W, H, EventParams(preset=preset), seed=3)
        batches = []
        for frame, t in zip(codes_sequence(), times_us()):
            f = {"coded": CodedFrame(frame, table), "linear": frame.astype(np.float32) / np.float32(255.0),
                 "log": np.take(table, frame)}[kind]
            batches.append(sim.step(f, t, is_log=kind == "log"))
        out[kind] = EventBatch.concatenate(batches)
    assert len(out["coded"]) > 1000
    for kind in ("linear", "log"):
        for col in ("x", "y", "t", "p", "noise_kind"):
            np.testing.assert_array_equal(getattr(out[kind], col), getattr(out["coded"], col))


def test_photoreceptor_noise_rms_is_the_rate_fit_over_the_smaller_threshold():
    from dvsot.events.sensor import photoreceptor_noise_rms

    # 60 events/s at 300 Hz: 30 ON events per second, x = log10(30 / 300) = -1, log10(C / rms) = 0.4825
    assert photoreceptor_noise_rms(60.0, 300.0, 0.2, 0.2) == pytest.approx(0.2 / 10 ** 0.4825, rel=1e-12)
    assert photoreceptor_noise_rms(60.0, 300.0, 0.2, 0.3) == photoreceptor_noise_rms(60.0, 300.0, 0.2, 0.2)
    # with mismatch: the mean of the smaller of the two thresholds (a Gaussian minimum, in closed form)
    rng = np.random.default_rng(0)
    smaller = np.minimum(rng.normal(0.134, 0.03, 1_000_000), rng.normal(0.203, 0.04, 1_000_000)).mean()
    assert photoreceptor_noise_rms(60.0, 300.0, 0.134, 0.203, 0.03, 0.04) == pytest.approx(
        smaller / 10 ** 0.4825, rel=1e-3)
    assert photoreceptor_noise_rms(600.0, 300.0, 0.2, 0.2) > photoreceptor_noise_rms(60.0, 300.0, 0.2, 0.2)


def test_photoreceptor_noise_is_a_stationary_low_passed_gaussian():
    """The noise of every pixel: RMS as set from the first frame on, correlation exp(-dt / tau) between frames."""
    from dvsot.events.sensor import photoreceptor_noise_rms

    n, cutoff, rate, dt_us = 20_000, 100.0, 20.0, 400
    params = EventParams(cp=50.0, cn=50.0, lowpass_order=1, lowpass_cutoff_hz=cutoff, photoreceptor_noise_hz=rate)
    sim = EventSimulator(n, 1, params, 5)
    rms = photoreceptor_noise_rms(rate, cutoff, 50.0, 50.0)
    frame = np.full((1, n), 0.5)
    states = []
    for k in range(3):
        sim.step(frame, k * dt_us)
        states.append(sim._sensor._photo.copy())
    for s in states:
        assert s.std() == pytest.approx(rms, rel=0.03) and abs(s.mean()) < 4 * rms / math.sqrt(n)
    a = math.exp(-dt_us * 1e-6 * 2 * math.pi * cutoff)
    assert np.corrcoef(states[0], states[1])[0, 1] == pytest.approx(a, abs=0.02)
    assert np.corrcoef(states[0], states[2])[0, 1] == pytest.approx(a * a, abs=0.02)


@pytest.mark.parametrize("rate", [50.0, 200.0])
def test_photoreceptor_noise_gives_the_set_event_rate_on_a_static_frame(rate):
    """Sampled finely (frames 1/100 of the time constant apart), a uniform static frame fires at the set rate, ON and
    OFF alike, every event a level crossing (flagged signal); sampled coarsely, crossings between frames are missed."""
    n, cutoff = 4_000, 300.0
    params = EventParams(lowpass_order=1, lowpass_cutoff_hz=cutoff, photoreceptor_noise_hz=rate)
    frame = np.full(n, math.log(0.5 + 1e-3))

    def measured(dt_us: int, seconds: float) -> tuple[float, EventBatch]:
        steps = int(seconds * 1e6 / dt_us)
        ev, _ = run(params, [frame] * (steps + 1), [k * dt_us for k in range(steps + 1)], n, seed=2)
        return len(ev) / n / seconds, ev

    fine, ev = measured(5, 0.01)  # dt / tau = 0.0094
    assert fine == pytest.approx(rate, rel=0.1)
    assert ev.p.mean() == pytest.approx(0.5, abs=0.03) and ev.signal.all()
    coarse, _ = measured(50, 0.02)  # dt / tau = 0.094
    assert coarse < 0.85 * fine


def test_photoreceptor_noise_is_seeded_and_off_leaves_every_other_draw():
    n, frames = 500, [np.full(500, math.log(0.3 + 1e-3))] * 40
    times = [k * 20 for k in range(40)]
    base = dict(preset="davis346", readout_limit_hz=0.0, latency_jitter_us=0.0, shot_noise_hz=2000.0)
    with_noise = EventParams(**base, photoreceptor_noise_hz=100.0)
    a, _ = run(with_noise, frames, times, n, seed=8)
    b, _ = run(with_noise, frames, times, n, seed=8)
    c, _ = run(with_noise, frames, times, n, seed=9)
    assert len(a) > 0 and np.array_equal(a.t, b.t) and np.array_equal(a.x, b.x) and not np.array_equal(a.x, c.x)
    # the shot noise draws its own stream: the same shot events with the photoreceptor noise on or off
    off, _ = run(EventParams(**base), frames, times, n, seed=8)
    shot = NOISE_KINDS.index("shot")
    on_shot, off_shot = a.select(a.noise_kind == shot), off.select(off.noise_kind == shot)
    for col in ("x", "t", "p"):
        assert np.array_equal(getattr(on_shot, col), getattr(off_shot, col))


@pytest.mark.parametrize("values, words", [
    (dict(photoreceptor_noise_hz=5.0), ["photoreceptor_noise_hz 5 Hz", "needs lowpass_order 1 or 2"]),
    (dict(photoreceptor_noise_hz=-1.0), ["photoreceptor_noise_hz", ">= 0", "events per pixel per second"]),
    (dict(lowpass_order=1, lowpass_cutoff_hz=30.0, photoreceptor_noise_hz=100.0),
     ["photoreceptor_noise_hz 100 Hz", "within 0.0006..60 events per pixel per second", "lowpass_cutoff_hz 30 Hz"]),
    (dict(lowpass_order=1, lowpass_cutoff_hz=30.0, photoreceptor_noise_hz=1e-4), ["within 0.0006..60"]),
])
def test_bad_photoreceptor_noise_is_one_line_naming_field_unit_and_range(values, words):
    with pytest.raises(UserError) as exc:
        EventParams.parse(values, "events")
    text = str(exc.value)
    assert "\n" not in text and all(w in text for w in words), text


@pytest.mark.parametrize("n, span", [(50, 10), (5_000, 3), (20_000, 2**20), (20_000, 2**40)])
def test_the_latency_stage_radix_sort_is_numpys_stable_order(n, span):
    from dvsot.events.sensor import stable_order

    key = np.random.default_rng(n).integers(-span, span, n, dtype=np.int64)  # few distinct keys: many ties
    np.testing.assert_array_equal(stable_order(key), np.argsort(key, kind="stable"))
