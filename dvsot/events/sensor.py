"""The DVS pixel beyond ESIM's ideal one: photoreceptor, bandwidth, noise, latency and readout, as stages.

Each stage is a group of EventParams fields (physical units in their names) that is off at its default;
with every stage off (the `ideal` model) dvsot.events.EventSimulator runs alone and gives today's ESIM
events. With any stage on, a SensorModel wraps the simulator, in signal order:

1. Photoreceptor (`linlog_intensity`): linear below that intensity (1 = full scale), log above, joined
   with matching value and slope (v2e's lin-log joins a line through the origin at 20 DN).
2. Low-pass (`lowpass_order` 1 or 2, `lowpass_cutoff_hz` at full-scale intensity): v2e's IIR update
   once a frame, state += eps * (input - state) with eps = min(1, inten01 * dt / tau), tau = 1 / (2 pi
   f3dB) and inten01 = (I + dark) / (1 + dark), `dark_intensity` being the dark current's equivalent
   intensity: dim pixels lag. Order 2 cascades two such stages.
   Photoreceptor noise (`photoreceptor_noise_hz` > 0): Gaussian noise added to that output, low-passed
   at `lowpass_cutoff_hz` whatever the intensity (an Ornstein-Uhlenbeck process, updated exactly for any
   frame interval, started in its stationary state with the reference at its mean, the noise-free signal, as
   v2e's starts), its RMS set so that it alone gives that many noise
   events per pixel per second, ON and OFF together (`photoreceptor_noise_rms`: Graca and Delbruck's
   rate fit as v2e's `--photoreceptor_noise` uses it). Its events are level crossings like the signal's:
   they move the reference and cannot be told from signal, so they are flagged signal.
3. The level-crossing kernel on the filtered log signal, with today's thresholds, mismatch and
   refractory period.
4. Noise, flagged signal = False with its kind (event_batch.NOISE_KINDS); none moves the reference:
   shot noise at `shot_noise_hz` per pixel in the dark, scaled by (f - 1) * inten01 + 1 with
   f = `shot_noise_bright_factor` (v2e's shot-noise intensity factor), random polarity, Poisson;
   leak ON events at `leak_hz` per pixel, each pixel's rate log-normal around it
   (`leak_spread_decades`: the std of log10 of the rate) and its periods gamma-distributed with
   coefficient of variation `leak_period_cv` (1: Poisson, as the ideal model; 0: periodic);
   hot pixels (`hot_pixel_fraction` of the pixels, drawn once) firing ON at `hot_pixel_hz`, Poisson.
5. Latency: every event's timestamp is delayed by `latency_us` plus Gaussian jitter of std
   `latency_jitter_us` (a delay is never negative); events are re-sorted by time.
6. Readout: an arbiter passing at most `readout_limit_hz` events a second, first come first served;
   an event waits for the one before it, and with `readout_fifo_events` N > 0 an event that finds N
   events waiting is dropped (counted). 0 waits as long as it takes.

Events delayed past the current frame are held and handed out with a later frame, so every batch
stays time-ordered; those still held after the last frame are counted as `held_at_end`. All state is
per pixel (or per held event): memory does not grow with the number of frames.

After the first frame (fixed thresholds) the front end also runs the level-crossing kernel's first pass in
the same loop (front_end_pass, coded_front_end_pass: float32 log bounds per pixel, then the exact count),
and the simulator only times the crossings of the pixels it found; the events are those of the separate
passes, bit for bit.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numba
import numpy as np

from dvsot.core.errors import UserError
from dvsot.events.batch import NOISE_KINDS, EventBatch
from dvsot.events.kernel import crossed

if TYPE_CHECKING:
    from dvsot.events import EventSimulator

SHOT, LEAK, HOT = (NOISE_KINDS.index(k) for k in ("shot", "leak", "hot"))
_NONE = np.empty(0)  # no photoreceptor noise


@numba.njit(cache=True, nogil=True, inline="always")
def _front_end_pixel(i, v, lp1, lp2, first, knee_log, knee_slope, linlog_intensity, log_eps, order, dt_over_tau, dark):
    """One pixel of front_end: its photoreceptor and low-pass output for log intensity v (state in lp1, lp2)."""
    inten = max(math.exp(v) - log_eps, 0.0)
    if inten < linlog_intensity:  # linear below the knee, tangent to the log at it
        v = knee_log + (inten - linlog_intensity) * knee_slope
    if order > 0:
        if first:
            lp1[i] = v
            if order == 2:
                lp2[i] = v
        else:
            e = min(1.0, (inten + dark) / (1.0 + dark) * dt_over_tau)
            lp1[i] += e * (v - lp1[i])
            if order == 2:
                lp2[i] += e * (lp1[i] - lp2[i])
        v = lp1[i] if order == 1 else lp2[i]
    return v


@numba.njit(cache=True, nogil=True, inline="always")
def _knee(linlog_intensity, log_eps):
    """(log, slope) of the photoreceptor at its lin-log knee."""
    return (math.log(linlog_intensity + log_eps) if linlog_intensity > 0.0 else 0.0), 1.0 / (linlog_intensity + log_eps)


@numba.njit(cache=True, nogil=True)
def front_end(L, out, lp1, lp2, first, linlog_intensity, log_eps, order, dt_over_tau, dark):
    """Photoreceptor and low-pass of one frame: L (log(I + eps), flat float64) -> out, the low-pass state in lp1, lp2.

    first: the state starts at the input (steady state). dt_over_tau: the frame interval over the time
    constant at full-scale intensity; the step of a pixel is min(1, (I + dark) / (1 + dark) * dt_over_tau).
    """
    knee_log, knee_slope = _knee(linlog_intensity, log_eps)
    for i in range(L.shape[0]):
        out[i] = _front_end_pixel(i, L[i], lp1, lp2, first, knee_log, knee_slope, linlog_intensity, log_eps, order,
                                  dt_over_tau, dark)


@numba.njit(cache=True, nogil=True)
def front_end_pass(L, out, lp1, lp2, linlog_intensity, log_eps, order, dt_over_tau, dark, photo, last, lo_log, hi_log,
                   base, off, cp, cn, cand, l1c, l0c):
    """front_end after the first frame, plus photo (the photoreceptor noise; empty: none), fused with the level-crossing
    kernel's first pass on the simulator's state (kernel.crossed past the log bounds): (finite, n, levels in all),
    the pixels that may fire in cand[:n], their values now and before in l1c[:n], l0c[:n].

    With out empty (order 1, no noise) the output is lp1 itself and its value before the update the previous
    sample; else out is written and last holds the previous sample.
    """
    knee_log, knee_slope = _knee(linlog_intensity, log_eps)
    direct = out.shape[0] == 0
    noisy = photo.shape[0] > 0
    finite = True
    n = 0
    bound = 0
    for i in range(L.shape[0]):
        before = lp1[i] if direct else 0.0  # lp1 is empty without a low-pass
        v = _front_end_pixel(i, L[i], lp1, lp2, False, knee_log, knee_slope, linlog_intensity, log_eps, order,
                             dt_over_tau, dark)
        v, n, k = _candidate(i, v, before, direct, noisy, photo, out, last, lo_log, hi_log, base, off, cp, cn, cand,
                             l1c, l0c, n)
        finite &= abs(v) < np.inf  # False for NaN too
        bound += k
    return finite, n, bound


@numba.njit(cache=True, nogil=True, inline="always")
def _candidate(i, v, before, direct, noisy, photo, out, last, lo_log, hi_log, base, off, cp, cn, cand, l1c, l0c, n):
    """The fused passes' step after a pixel's front end: photo's noise added, the output kept, and the pixel put in
    cand if it crosses a level (kernel.crossed past the log bounds): (its value, candidates so far, its levels)."""
    if noisy:
        v = v + photo[i]
    if not direct:
        out[i] = v
    k = 0
    if (v >= hi_log[i]) | (v <= lo_log[i]):
        v0 = before if direct else last[i]
        k = crossed(i, v, v0, base, off, cp, cn)
        if k:
            cand[n] = i
            l1c[n] = v
            l0c[n] = v0
            n += 1
    return v, n, k


def photoreceptor(L: np.ndarray, linlog_intensity: float, log_eps: float) -> np.ndarray:
    """The photoreceptor's output for log intensities L = log(I + log_eps): L above the lin-log knee, its tangent
    below."""
    if linlog_intensity <= 0:
        return L
    inten = np.maximum(np.exp(L) - log_eps, 0.0)
    knee = linlog_intensity + log_eps
    return np.where(inten < linlog_intensity, np.log(knee) + (inten - linlog_intensity) / knee, L)


def photoreceptor_noise_rms(rate_hz: float, cutoff_hz: float, cp: float, cn: float, sigma_cp: float = 0.0,
                            sigma_cn: float = 0.0) -> float:
    """RMS (log intensity) of Gaussian photoreceptor noise low-passed at cutoff_hz (Hz) that gives rate_hz noise
    events per pixel per second, ON and OFF together, with thresholds C+ ~ N(cp, sigma_cp), C- ~ N(cn, sigma_cn).

    Graca and Delbruck's fit (dvsot.events.presets.PHOTORECEPTOR_NOISE_FIT) gives threshold / RMS for the ON rate
    per Hz of bandwidth; the threshold is the mean of the smaller of a pixel's two, as v2e takes it (in closed
    form here: the mean of the minimum of two Gaussians).
    """
    from dvsot.events.presets import PHOTORECEPTOR_NOISE_FIT

    x = math.log10(rate_hz / 2.0 / cutoff_hz)
    y = 0.0
    for c in PHOTORECEPTOR_NOISE_FIT:  # Horner: highest power first
        y = y * x + c
    spread = math.hypot(sigma_cp, sigma_cn)
    if spread > 0:
        z = (cn - cp) / spread
        cdf = 0.5 * (1.0 + math.erf(z / math.sqrt(2.0)))
        threshold = cp * cdf + cn * (1.0 - cdf) - spread * math.exp(-0.5 * z * z) / math.sqrt(2.0 * math.pi)
    else:
        threshold = min(cp, cn)
    return threshold / 10.0 ** y


@numba.njit(cache=True, nogil=True, inline="always")
def _coded_pixel(i, c, plog, inten01, lp1, lp2, first, order, dt_over_tau):
    """One pixel of coded_front_end: the low-pass output for code c (state in lp1, lp2)."""
    v = plog[c]
    if first:
        lp1[i] = v
        if order == 2:
            lp2[i] = v
    else:
        e = min(1.0, inten01[c] * dt_over_tau)
        lp1[i] += e * (v - lp1[i])
        if order == 2:
            lp2[i] += e * (lp1[i] - lp2[i])
    return lp1[i] if order == 1 else lp2[i]


@numba.njit(cache=True, nogil=True)
def coded_front_end(codes, plog, inten01, out, lp1, lp2, first, order, dt_over_tau):
    """front_end for a frame of integer codes: plog[c] the photoreceptor's output and inten01[c] the relative
    intensity of code c (tables made once per code table), the low-pass as front_end's."""
    for i in range(codes.shape[0]):
        out[i] = _coded_pixel(i, codes[i], plog, inten01, lp1, lp2, first, order, dt_over_tau)


@numba.njit(cache=True, nogil=True)
def coded_front_end_pass(codes, plog, inten01, out, lp1, lp2, order, dt_over_tau, photo, last, lo_log, hi_log, base,
                         off, cp, cn, cand, l1c, l0c):
    """coded_front_end after the first frame, plus photo, fused with the kernel's first pass as front_end_pass is:
    (n, levels in all); the codes' tables are finite, so is the output."""
    direct = out.shape[0] == 0
    noisy = photo.shape[0] > 0
    n = 0
    bound = 0
    for i in range(codes.shape[0]):
        before = lp1[i] if direct else 0.0  # lp1 is empty without a low-pass
        v = _coded_pixel(i, codes[i], plog, inten01, lp1, lp2, False, order, dt_over_tau)
        _, n, k = _candidate(i, v, before, direct, noisy, photo, out, last, lo_log, hi_log, base, off, cp, cn, cand,
                             l1c, l0c, n)
        bound += k
    return n, bound


@numba.njit(cache=True, nogil=True)
def readout(t_in, period_us, fifo, state):
    """The arbiter over time-ordered arrival times t_in (int us): (kept mask, output times, dropped count).

    state[0] is the time (float us) the arbiter is free again, carried between calls. An event is read
    at max(arrival, free) and keeps the arbiter for period_us; with fifo > 0 one that arrives while fifo
    events wait (arrived, not yet read) is dropped.
    """
    n = t_in.shape[0]
    keep = np.ones(n, np.bool_)
    t_out = np.empty(n, np.int64)
    free = state[0]
    dropped = 0
    for j in range(n):
        t = float(t_in[j])
        start = max(t, free)
        if fifo > 0 and start > t:
            waiting = math.ceil((start - t) / period_us - 1e-9) - 1  # read after this arrival, before this event
            if waiting >= fifo:
                keep[j] = False
                dropped += 1
                t_out[j] = t_in[j]
                continue
        t_out[j] = np.int64(math.floor(start + 0.5))
        free = start + period_us
    state[0] = free
    return keep, t_out, dropped


@numba.njit(cache=True, nogil=True)
def merge_sorted(sx, sy, st, sp, width, n_pix, nkey, npix, nt, npol, nkind):
    """Signal events (sorted by time, then pixel) and noise events sorted by nkey = time * n_pix + pixel as one
    sequence in that order, a signal event before noise of the same key: x, y, t, p and kind (0 for signal)."""
    ns, nn = st.shape[0], nkey.shape[0]
    total = ns + nn
    x = np.empty(total, np.uint16)
    y = np.empty(total, np.uint16)
    t = np.empty(total, np.int64)
    p = np.empty(total, np.uint8)
    kind = np.zeros(total, np.uint8)
    i = 0
    j = 0
    for k in range(total):
        if j < nn and (i >= ns or nkey[j] < st[i] * n_pix + (np.int64(sy[i]) * width + sx[i])):
            x[k] = npix[j] % width
            y[k] = npix[j] // width
            t[k] = nt[j]
            p[k] = npol[j]
            kind[k] = nkind[j]
            j += 1
        else:
            x[k] = sx[i]
            y[k] = sy[i]
            t[k] = st[i]
            p[k] = sp[i]
            i += 1
    return x, y, t, p, kind


# below this many keys stable_order calls a merge sort: a radix pass costs a 2^16-entry histogram
RADIX_MIN_KEYS = 4096


@numba.njit(cache=True, nogil=True)
def stable_order(key):
    """np.argsort(key, kind="stable") of int64 keys: a least-significant-digit radix sort, 16 bits a pass, over the
    keys' range (the stable order is unique, whichever stable sort finds it)."""
    n = key.shape[0]
    if n < RADIX_MIN_KEYS:
        return np.argsort(key, kind="mergesort")
    lo = key.min()
    span = key.max() - lo
    order = np.arange(n)
    rel = key - lo
    rel_out = np.empty(n, np.int64)
    order_out = np.empty(n, np.int64)
    start = np.empty(65537, np.int64)
    shift = 0
    while True:
        start[:] = 0
        for j in range(n):
            start[((rel[j] >> shift) & 0xFFFF) + 1] += 1
        for b in range(1, 65537):
            start[b] += start[b - 1]
        for j in range(n):
            d = (rel[j] >> shift) & 0xFFFF
            k = start[d]
            start[d] = k + 1
            rel_out[k] = rel[j]
            order_out[k] = order[j]
        rel, rel_out = rel_out, rel
        order, order_out = order_out, order
        shift += 16
        if (span >> shift) == 0:
            return order


@numba.njit(cache=True, nogil=True)
def delayed(t, x, y, width, n_pix, n_held, z, latency_us, jitter_us, ordered):
    """The latency stage's times and order: events [n_held:] delayed by latency_us plus jitter_us * z (never by less
    than 0, rounded to 1 us), [:n_held] already; with `ordered`, sorted by (time, pixel) stably. (times, order)."""
    n = t.shape[0]
    t_new = np.empty(n, np.int64)
    for j in range(n_held):
        t_new[j] = t[j]
    for j in range(n_held, n):
        d = latency_us
        if jitter_us > 0.0:
            d = max(d + jitter_us * z[j - n_held], 0.0)
        t_new[j] = t[j] + np.int64(np.rint(d))
    if not ordered:
        return t_new, np.arange(n)
    key = np.empty(n, np.int64)
    for j in range(n):
        key[j] = t_new[j] * n_pix + (np.int64(y[j]) * width + x[j])
    order = stable_order(key)
    return t_new[order], order


@numba.njit(cache=True, nogil=True)
def due(next_us, among, t1, scratch):
    """The number of the processes `among` (increasing indices) whose next event is at or before t1 (us), their
    indices in scratch[:n], in the same order: one pass."""
    n = 0
    for j in range(among.shape[0]):
        i = among[j]
        if next_us[i] <= t1:
            scratch[n] = i
            n += 1
    return n


# Renewal processes list those due within this many frame intervals, then test only them frame by frame
SOON_INTERVALS = 64


class Renewal:
    """Per-pixel renewal processes (leak, hot pixels): event times with gamma periods of a given rate and CV."""

    def __init__(self, pixels: np.ndarray, rate_hz: np.ndarray, cv: float, rng: np.random.Generator) -> None:
        self.pixels, self.rate_hz, self.cv, self._rng = pixels, rate_hz, float(cv), rng
        self._next_us = np.empty(0)

    def _periods_us(self, idx: np.ndarray, length_biased: bool = False) -> np.ndarray:
        """Periods (us) of the processes idx: gamma of mean 1 / rate and CV cv (length-biased: shape + 1)."""
        mean = 1e6 / self.rate_hz[idx]
        if self.cv == 0:
            return mean
        shape = 1.0 / self.cv ** 2
        return self._rng.gamma(shape + (1.0 if length_biased else 0.0), 1.0 / shape, idx.size) * mean

    def start(self, t_us: float) -> None:
        """Stationary start at t_us: the time to each first event is the residual of a length-biased period."""
        idx = np.arange(self.pixels.size)
        self._next_us = t_us + self._rng.random(idx.size) * self._periods_us(idx, length_biased=True)
        self._scratch = np.empty(idx.size, np.int64)
        self._t_last = float(t_us)
        self._horizon = -math.inf  # the processes due by then are in _soon (all others' next events come later)
        self._soon = idx

    def events(self, t1: float) -> tuple[np.ndarray, np.ndarray]:
        """(pixel, float us time) of the events up to t1, the processes moved past t1."""
        if t1 > self._horizon:  # a process's next event only moves later: one outside _soon stays outside
            self._horizon = t1 + SOON_INTERVALS * max(t1 - self._t_last, 1.0)
            self._soon = np.flatnonzero(self._next_us <= self._horizon)
        self._t_last = t1
        pix, times = [], []
        now = self._scratch[:due(self._next_us, self._soon, t1, self._scratch)].copy()
        while now.size:
            pix.append(self.pixels[now])
            times.append(self._next_us[now])
            self._next_us[now] += self._periods_us(now)
            now = now[self._next_us[now] <= t1]
        if not pix:
            return np.empty(0, np.int64), np.empty(0)
        return np.concatenate(pix).astype(np.int64), np.concatenate(times)


class SensorModel:
    """The stages around an EventSimulator: frames in (as EventSimulator.step takes them), time-ordered events out."""

    def __init__(self, sim: EventSimulator, seed: int) -> None:
        self.sim, self.params = sim, sim.params
        p, n = self.params, sim.width * sim.height
        # children 0 and 1 are the simulator's; a stage added later takes the next child, leaving the others' draws
        rng_leak, rng_shot, rng_hot, rng_time, rng_photo = (np.random.default_rng(s) for s in
                                                            np.random.SeedSequence(int(seed)).spawn(7)[2:])
        self._rng_shot, self._rng_time, self._rng_photo = rng_shot, rng_time, rng_photo
        self._photo_rms = 0.0
        if p.photoreceptor_noise_hz > 0:
            self._photo_rms = photoreceptor_noise_rms(p.photoreceptor_noise_hz, p.lowpass_cutoff_hz, p.cp, p.cn,
                                                      p.sigma_cp, p.sigma_cn)
            self._photo = np.empty(n)  # the noise now, log intensity
            self._photo_draw = np.empty(n, np.float32)
        self._lp1 = np.empty(n) if p.lowpass_order else np.empty(0)
        self._lp2 = np.empty(n) if p.lowpass_order == 2 else np.empty(0)
        self._raw = np.empty(n)
        self._l1c = self._l0c = _NONE  # the fused passes' candidate values, made at their first use
        self._outs = (np.empty(n), np.empty(n))  # the simulator keeps the previous one: written in turn
        self._frames = 0
        self._tables: tuple = (None,)  # (code table, photoreceptor table, inten01 table, intensity table)
        self._inten_now: tuple = (None, None)  # (codes, intensity table) or (log intensities, None) of this frame
        self._t_prev: int | None = None
        self._leak = self._hot = None
        if p.leak_hz > 0:
            rate = np.full(n, p.leak_hz)
            if p.leak_spread_decades > 0:
                rate *= 10.0 ** (p.leak_spread_decades * rng_leak.standard_normal(n))
            self._leak = Renewal(np.arange(n), rate, p.leak_period_cv, rng_leak)
        n_hot = int(round(p.hot_pixel_fraction * n))
        if n_hot and p.hot_pixel_hz > 0:
            hot = np.sort(rng_hot.choice(n, n_hot, replace=False))
            self._hot = Renewal(hot, np.full(n_hot, p.hot_pixel_hz), 1.0, rng_hot)
        self._held = _with_kinds(EventBatch.empty())  # delayed past the last frame, not yet at the arbiter
        self._read = _with_kinds(EventBatch.empty())  # read out for after the last frame
        self._arbiter = np.zeros(1)
        self.dropped = 0

    @property
    def held(self) -> int:
        """Events delayed past the last frame so far (latency or readout), not handed out yet."""
        return len(self._held) + len(self._read)

    def _log(self, frame, is_log: bool) -> np.ndarray:
        """The frame as flat float64 log intensity log(I + log_eps), checked as the simulator checks it."""
        from dvsot.events import CodedFrame, log_intensity

        sim = self.sim
        if isinstance(frame, CodedFrame):
            return np.take(frame.table, sim._codes(frame), out=self._raw)
        a = np.asarray(frame)
        if a.shape != (sim.height, sim.width):
            raise UserError(f"frame has shape {a.shape}, expected ({sim.height}, {sim.width})")
        if a.dtype.kind not in "fiu":
            raise UserError(f"frame has dtype {a.dtype}, expected a real number type")
        if not is_log:
            return log_intensity(a, self.params.log_eps, self._raw)
        np.copyto(self._raw, a.reshape(-1), casting="unsafe")
        if not np.isfinite(self._raw.sum()):
            raise UserError("frame contains NaN or infinite values")
        return self._raw

    def step(self, frame, t_us: int, is_log: bool = False) -> EventBatch:
        """Events handed out up to t_us (microseconds): signal and noise of the interval, delayed and read out."""
        p, sim = self.params, self.sim
        t_us = int(t_us)
        if self._t_prev is not None and t_us <= self._t_prev:
            raise UserError(f"frame timestamps must increase: {t_us} us follows {self._t_prev} us")
        first = self._t_prev is None
        if not first:  # before any state changes: a refused interval leaves the model as it was
            self._check_hot(self._t_prev, t_us)
        dt_over_tau = 0.0 if first else (t_us - self._t_prev) * 1e-6 * 2 * math.pi * p.lowpass_cutoff_hz
        from dvsot.events import CodedFrame

        # after the first frame, with fixed thresholds: the front end and the kernel's first pass in one loop
        fused = not first and not sim._redraws()
        if fused:
            sim._interval(t_us)  # the simulator's own checks, before any state changes
        photo = self._photoreceptor_noise(first, t_us)
        if isinstance(frame, CodedFrame):  # by code tables: no log or exp per pixel
            codes = sim._codes(frame)
            plog, inten01, inten = self._code_tables(frame.table)
            self._inten_now = (codes, inten)
            if p.lowpass_order == 0:  # the photoreceptor alone is another code table: the simulator's coded path
                signal = sim.step(CodedFrame(codes.reshape(sim.height, sim.width), plog), t_us)
            elif fused:
                out, last = self._pass_output(photo)
                n, bound = coded_front_end_pass(codes, plog, inten01, out, self._lp1, self._lp2, p.lowpass_order,
                                                dt_over_tau, photo, *self._pass_state())
                signal = sim._step_candidates(n, bound, self._l1c, self._l0c, last, t_us)
            else:
                out = self._outs[self._frames % 2]
                coded_front_end(codes, plog, inten01, out, self._lp1, self._lp2, first, p.lowpass_order, dt_over_tau)
                signal = sim.step(np.add(out, photo, out=out).reshape(sim.height, sim.width) if photo.size else
                                  out.reshape(sim.height, sim.width), t_us, is_log=True, copy=False)
        else:
            raw = self._log(frame, is_log)
            self._inten_now = (raw, None)
            if fused:
                out, last = self._pass_output(photo)
                finite, n, bound = front_end_pass(raw, out, self._lp1, self._lp2, p.linlog_intensity, p.log_eps,
                                                  p.lowpass_order, dt_over_tau, p.dark_intensity, photo,
                                                  *self._pass_state())
                if not finite:
                    raise UserError("frame contains NaN or infinite values")
                signal = sim._step_candidates(n, bound, self._l1c, self._l0c, last, t_us)
            else:
                out = self._outs[self._frames % 2]
                front_end(raw, out, self._lp1, self._lp2, first, p.linlog_intensity, p.log_eps, p.lowpass_order,
                          dt_over_tau, p.dark_intensity)
                signal = sim.step(np.add(out, photo, out=out).reshape(sim.height, sim.width) if photo.size else
                                  out.reshape(sim.height, sim.width), t_us, is_log=True, copy=False)
        self._frames += 1
        if first:
            self._t_prev = t_us
            for proc in (self._leak, self._hot):
                if proc is not None:
                    proc.start(t_us)
            return _with_kinds(EventBatch.empty())
        t0, self._t_prev = self._t_prev, t_us
        batch = self._merge(signal, self._noise(t0, t_us))
        return self._deliver(batch, t_us)

    def _photoreceptor_noise(self, first: bool, t_us: int) -> np.ndarray:
        """The photoreceptor noise to add to the low-pass output at t_us (log intensity, one per pixel); empty if off
        and at the first frame.

        The noise is an Ornstein-Uhlenbeck process of stationary RMS `_photo_rms` and time constant
        1 / (2 pi lowpass_cutoff_hz): n <- a n + sqrt(1 - a^2) rms z with a = exp(-dt / tau), exact for any dt.
        """
        if not self._photo_rms:
            return _NONE
        z = self._rng_photo.standard_normal(self._photo.size, np.float32, out=self._photo_draw)
        if first:  # the noise in its stationary state; the reference at the noise-free signal, the noise's mean
            np.multiply(z, self._photo_rms, out=self._photo)
            return _NONE
        a = math.exp(-(t_us - self._t_prev) * 1e-6 * 2 * math.pi * self.params.lowpass_cutoff_hz)
        self._photo *= a
        self._photo += math.sqrt(1.0 - a * a) * self._photo_rms * z
        return self._photo

    def _pass_output(self, photo: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(out, the frame's output as the simulator keeps it) for a fused pass: out empty when the low-pass state lp1
        is the output itself (order 1, no photoreceptor noise), else this frame's buffer."""
        if self.params.lowpass_order == 1 and not photo.size:
            return _NONE, self._lp1
        out = self._outs[self._frames % 2]
        return out, out

    def _pass_state(self) -> tuple:
        """What the fused first passes read and write beside the front end: the simulator's previous sample, log
        bounds, base, offset and thresholds; the candidates and their values now and before."""
        sim = self.sim
        n = sim.width * sim.height
        if self._l1c.size != n:
            self._l1c, self._l0c = np.empty(n), np.empty(n)
        return (sim._log_last(), *sim._fresh_log_bounds(), sim._base, sim._off, sim._cp_px, sim._cn_px, sim._scratch,
                self._l1c, self._l0c)

    def _check_hot(self, t0: int, t1: int) -> None:
        """UserError if the hot pixels or the brightest shot noise would draw too many events in (t0, t1] (us)."""
        from dvsot.events.simulator import MAX_NOISE_EVENTS

        p, seconds = self.params, (t1 - t0) * 1e-6
        n_hot = 0 if self._hot is None else self._hot.pixels.size
        for field, mean in (("hot_pixel_hz", p.hot_pixel_hz * n_hot * seconds),
                            ("shot_noise_bright_factor", p.shot_noise_hz * max(1.0, p.shot_noise_bright_factor)
                             * self.sim.width * self.sim.height * seconds)):
            if mean > MAX_NOISE_EVENTS:
                raise UserError(f"{field} {getattr(p, field):g} gives {mean:.3g} noise events between frames "
                                f"{(t1 - t0) / 1000:g} ms apart, more than the bound of {MAX_NOISE_EVENTS:g}")

    def _code_tables(self, table: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(photoreceptor output, inten01, intensity) per code of a table of log intensities; kept for the last
        table."""
        if self._tables[0] is not table:
            p = self.params
            inten = np.maximum(np.exp(table) - p.log_eps, 0.0)
            plog = photoreceptor(table, p.linlog_intensity, p.log_eps)
            self._tables = (table, plog, (inten + p.dark_intensity) / (1.0 + p.dark_intensity), inten)
        return self._tables[1], self._tables[2], self._tables[3]

    def _intensity(self, pix: np.ndarray) -> np.ndarray:
        """The current frame's linear intensity (1 = full scale) at pixels pix."""
        values, inten = self._inten_now
        if inten is not None:
            return inten[values[pix]]
        return np.maximum(np.exp(values[pix]) - self.params.log_eps, 0.0)

    def _noise(self, t0: int, t1: int) -> list[tuple[np.ndarray, ...]]:
        """Shot, leak and hot-pixel events in (t0, t1] as (pixel, float us, polarity, kind) parts."""
        p, n = self.params, self.sim.width * self.sim.height
        parts = []
        if p.shot_noise_hz > 0:
            rng, f = self._rng_shot, p.shot_noise_bright_factor
            top = max(1.0, f)  # the largest factor over intensities: drawn at that rate, thinned per pixel
            k = rng.poisson(p.shot_noise_hz * top * n * (t1 - t0) * 1e-6)
            pix = rng.integers(0, n, k)
            times = t1 - rng.random(k) * (t1 - t0)  # in (t0, t1]
            pol = rng.random(k) < 0.5
            if f != 1.0:
                inten = self._intensity(pix)
                inten01 = np.minimum((inten + p.dark_intensity) / (1.0 + p.dark_intensity), 1.0)
                keep = rng.random(k) * top < (f - 1.0) * inten01 + 1.0
                pix, times, pol = pix[keep], times[keep], pol[keep]
            parts.append((pix, times, pol, SHOT))
        for proc, kind in ((self._leak, LEAK), (self._hot, HOT)):
            if proc is not None:
                pix, times = proc.events(float(t1))
                parts.append((pix, times, np.ones(pix.size, bool), kind))
        return parts

    def _merge(self, signal: EventBatch, noise: list[tuple[np.ndarray, ...]]) -> EventBatch:
        """Signal events and noise parts as one batch sorted by (time, pixel), signal first among equals."""
        w, n_pix = self.sim.width, self.sim.width * self.sim.height
        npix = np.concatenate([part[0] for part in noise]) if noise else np.empty(0, np.int64)
        if npix.size == 0:
            return _with_kinds(signal)
        nt = np.concatenate([np.rint(part[1]).astype(np.int64) for part in noise])
        npol = np.concatenate([part[2].astype(np.uint8) for part in noise])
        nkind = np.concatenate([np.full(part[0].size, part[3], np.uint8) for part in noise])
        # the signal events are in (time, pixel) order already: the few noise events are sorted and merged in
        nkey = nt * n_pix + npix
        order = np.argsort(nkey, kind="stable")
        x, y, t, pol, kind = merge_sorted(signal.x, signal.y, signal.t, signal.p, w, n_pix, nkey[order], npix[order],
                                          nt[order], npol[order], nkind[order])
        return EventBatch(x, y, t, pol, kind == 0, kind)

    def _deliver(self, batch: EventBatch, t1: int) -> EventBatch:
        """Latency and readout applied to the interval's events; those at or before t1 (us) handed out, the rest held.

        The stages work on times and an index into the interval's events; each column is gathered once, at the end.
        """
        p, sim = self.params, self.sim
        src, idx, t = batch, None, batch.t
        if p.latency_us > 0 or p.latency_jitter_us > 0:
            z = self._rng_time.standard_normal(len(batch)) if p.latency_jitter_us > 0 else _NONE
            src = EventBatch.concatenate([self._held, batch]) if len(self._held) else batch
            # nearly sorted after a constant delay with nothing held: the order stays
            t, idx = delayed(src.t, src.x, src.y, sim.width, sim.width * sim.height, len(self._held), z,
                             float(p.latency_us), float(p.latency_jitter_us),
                             p.latency_jitter_us > 0 or len(self._held) > 0)
            cut = int(np.searchsorted(t, t1, side="right"))
            self._held = _gather(src, idx[cut:], t[cut:])
            idx, t = idx[:cut], t[:cut]
        if p.readout_limit_hz > 0:
            keep, t_out, dropped = readout(t, 1e6 / p.readout_limit_hz, int(p.readout_fifo_events), self._arbiter)
            self.dropped += int(dropped)
            if dropped:
                idx = np.flatnonzero(keep) if idx is None else idx[keep]
                t_out = t_out[keep]
            out = _gather(src, idx, t_out)
            if len(self._read):
                out = EventBatch.concatenate([self._read, out])
            cut = int(np.searchsorted(out.t, t1, side="right"))
            batch, self._read = out.select(slice(0, cut)), out.select(slice(cut, None))
            return batch
        return _gather(src, idx, t)

    def counts(self) -> dict:
        """What the readout dropped and what is still held after the last frame (events)."""
        return {"readout_dropped": int(self.dropped), "held_at_end": int(self.held)}


def _gather(src: EventBatch, idx: np.ndarray | None, t: np.ndarray) -> EventBatch:
    """The events idx of src (all, in order, if None) with the times t."""
    if idx is None:
        return EventBatch(src.x, src.y, t, src.p, src.signal, src.noise_kind)
    return EventBatch(src.x[idx], src.y[idx], t, src.p[idx], src.signal[idx], src.noise_kind[idx])


def _with_kinds(batch: EventBatch) -> EventBatch:
    """The batch with signal flags and noise kinds (all signal if it had none)."""
    n = len(batch)
    sig = batch.signal if batch.signal is not None else np.ones(n, bool)
    kind = batch.noise_kind if batch.noise_kind is not None else np.where(sig, 0, SHOT).astype(np.uint8)
    return EventBatch(batch.x, batch.y, batch.t, batch.p, sig, kind)
