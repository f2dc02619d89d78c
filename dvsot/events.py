"""ESIM-style event generation: linear or log intensity frames in, timestamped polarity events out.

Semantics (after ESIM, Rebecq et al. 2018), per pixel:

* Input is linear-light intensity I (or log intensity with ``is_log=True``); L = log(I + eps).
  The first frame only sets each pixel's reference level ref = L and its last sample L0 = L.
* Between samples (t0, L0) and (t1, L1) the log intensity is interpolated linearly. With
  polarity pol = sign(L1 - L0) and u = pol * (L - ref), every level u = k*C (k >= 1) with
  u0 < k*C <= u1 is crossed once: an event at t0 + (k*C - u0) / (u1 - u0) * (t1 - t0)
  (microseconds, rounded to the nearest integer). A pixel may fire several times per interval; the
  reference moves by C per crossing (ref += pol * k_max * C).
* C+ and C- are separate (cp, cn). Threshold mismatch: with mismatch="fixed" (default) each pixel
  draws its own C+ ~ N(cp, sigma_cp) and C- ~ N(cn, sigma_cn) once, clamped to >= min_threshold;
  with mismatch="per_interval" they are drawn anew for every interval, as ESIM does (where a smaller
  draw leaves levels between ref and L0, they are skipped; ESIM's loop emits nothing then: docs/events.md).
* Refractory period R: a crossing closer than R to the pixel's last *emitted* event is dropped and the
  reference still advances (ESIM's behaviour); the test is on exact times, before rounding to 1 us. Crossings inside one interval are equally spaced in
  time (linear interpolation), so the kept ones are found in closed form: the first kept index
  j0 = ceil((R - (t_first - t_last)) / dt), then every m = ceil(R / dt)-th crossing.
* Noise beyond ESIM (flagged ``signal=False``; they do not move the reference): shot noise, events
  of random polarity at ``shot_noise_hz`` per pixel, and leak events, ON events at ``leak_hz`` per
  pixel (the visible effect of v2e's leaky reference), both as homogeneous Poisson processes with
  uniformly drawn pixels and times.
* Events of one interval are sorted by time, ties by pixel index (y * width + x), then by crossing
  order. The same frames, timestamps, parameters and seed give bit-identical events.

Everything is vectorised over pixels and events; only pixels that fire are touched after the first
few whole-frame operations.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from dvsot.errors import UserError


@dataclass(frozen=True)
class EventBatch:
    """Events in time order: x, y (pixels, u2), t (microseconds, i8), p (1 brighter, 0 darker, u1), signal (bool or None)."""

    x: np.ndarray
    y: np.ndarray
    t: np.ndarray
    p: np.ndarray
    signal: np.ndarray | None = None

    def __len__(self) -> int:
        return int(self.t.shape[0])

    @staticmethod
    def empty() -> "EventBatch":
        """A batch with no events."""
        return EventBatch(np.empty(0, np.uint16), np.empty(0, np.uint16), np.empty(0, np.int64),
                          np.empty(0, np.uint8), np.empty(0, bool))

    @staticmethod
    def concatenate(batches: list["EventBatch"]) -> "EventBatch":
        """Join batches in the given order (the caller keeps them time-ordered)."""
        if not batches:
            return EventBatch.empty()
        sig = None
        if all(b.signal is not None for b in batches):
            sig = np.concatenate([b.signal for b in batches])
        return EventBatch(np.concatenate([b.x for b in batches]), np.concatenate([b.y for b in batches]),
                          np.concatenate([b.t for b in batches]), np.concatenate([b.p for b in batches]), sig)

    def select(self, mask_or_index: np.ndarray) -> "EventBatch":
        """The events picked by a boolean mask or an index array."""
        sig = None if self.signal is None else self.signal[mask_or_index]
        return EventBatch(self.x[mask_or_index], self.y[mask_or_index], self.t[mask_or_index],
                          self.p[mask_or_index], sig)


class EventParams(BaseModel):
    """Event-generator parameters: contrast thresholds (log intensity), mismatch, refractory period (us), noise (Hz)."""

    # allow_inf_nan=False: an infinite threshold or rate passes gt/ge bounds yet silently means "no events"
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    cp: float = Field(0.2, gt=0, description="ON contrast threshold C+ (log intensity)")
    cn: float = Field(0.2, gt=0, description="OFF contrast threshold C- (log intensity)")
    sigma_cp: float = Field(0.0, ge=0, description="per-pixel std of C+ (log intensity)")
    sigma_cn: float = Field(0.0, ge=0, description="per-pixel std of C- (log intensity)")
    min_threshold: float = Field(0.01, gt=0, description="lower clamp of drawn thresholds")
    mismatch: Literal["fixed", "per_interval"] = "fixed"
    refractory_us: float = Field(0.0, ge=0, description="refractory period, microseconds")
    log_eps: float = Field(1e-3, gt=0, description="eps in L = log(I + eps)")
    shot_noise_hz: float = Field(0.0, ge=0, description="shot-noise events per pixel per second")
    leak_hz: float = Field(0.0, ge=0, description="leak (ON) events per pixel per second")

    @classmethod
    def parse(cls, values: dict, source: str = "event parameters") -> "EventParams":
        """Validated parameters; a bad field raises UserError naming it."""
        try:
            return cls(**values)
        except ValidationError as exc:
            err = exc.errors()[0]
            field = ".".join(str(p) for p in err["loc"]) or "?"
            raise UserError(f"{source}: field '{field}': {err['msg']}") from None


class EventSimulator:
    """Streaming ESIM-style simulator: feed frames one at a time, get the events since the previous frame."""

    def __init__(self, width: int, height: int, params: EventParams | None = None, seed: int = 0) -> None:
        if width <= 0 or height <= 0:
            raise UserError(f"event simulator: resolution must be positive, got {width}x{height}")
        self.width, self.height = int(width), int(height)
        self.params = params or EventParams()
        seeds = np.random.SeedSequence(int(seed)).spawn(2)
        self._rng_threshold = np.random.default_rng(seeds[0])
        self._rng_noise = np.random.default_rng(seeds[1])
        n = self.width * self.height
        self._cp, self._cn = self._draw_thresholds()
        self._ref = np.zeros(n, np.float64)
        self._last = np.zeros(n, np.float64)  # L at the previous sample
        self._last_event = np.full(n, -np.inf)  # time of the last emitted event, float microseconds
        self._t_prev: int | None = None
        self._buf = np.empty(n, np.float64)

    def _draw_thresholds(self) -> tuple[np.ndarray | float, np.ndarray | float]:
        p, n = self.params, self.width * self.height
        out = []
        for c, sigma in ((p.cp, p.sigma_cp), (p.cn, p.sigma_cn)):
            if sigma > 0:
                out.append(np.maximum(self._rng_threshold.normal(c, sigma, n), p.min_threshold))
            else:
                out.append(float(c))
        return out[0], out[1]

    @property
    def thresholds(self) -> tuple[np.ndarray, np.ndarray]:
        """Current per-pixel C+ and C- as (height, width) arrays (log intensity)."""
        shape = (self.height, self.width)
        return tuple(np.broadcast_to(np.asarray(c, np.float64), (self.width * self.height,)).reshape(shape)
                     for c in (self._cp, self._cn))

    def _log_frame(self, frame: np.ndarray, is_log: bool) -> np.ndarray:
        a = np.asarray(frame)
        if a.shape != (self.height, self.width):
            raise UserError(f"frame has shape {a.shape}, expected ({self.height}, {self.width})")
        if a.dtype.kind not in "fiu":
            raise UserError(f"frame has dtype {a.dtype}, expected a real number type")
        out = self._buf
        np.copyto(out, a.reshape(-1), casting="unsafe")
        total = out.sum()
        if not np.isfinite(total):
            raise UserError("frame contains NaN or infinite values")
        if is_log:
            return out
        if out.min() < 0:
            raise UserError("frame contains negative intensities")
        out += self.params.log_eps
        np.log(out, out=out)
        return out

    def step(self, frame: np.ndarray, t_us: int, is_log: bool = False) -> EventBatch:
        """Events (time-sorted) between the previous frame and this one, at t_us microseconds."""
        t_us = int(t_us)
        L1 = self._log_frame(frame, is_log)
        if self._t_prev is None:
            self._ref[:] = L1
            self._last[:] = L1
            self._t_prev = t_us
            return EventBatch.empty()
        if t_us <= self._t_prev:
            raise UserError(f"frame timestamps must increase: {t_us} us follows {self._t_prev} us")
        t0, t1 = self._t_prev, t_us
        p = self.params
        if p.mismatch == "per_interval" and (p.sigma_cp > 0 or p.sigma_cn > 0):
            self._cp, self._cn = self._draw_thresholds()
        signal = self._crossings(L1, float(t0), float(t1))
        noise = self._noise(t0, t1)
        self._last, self._buf = L1, self._last
        self._t_prev = t1
        return _sorted_batch(signal, noise, self.width, t0, t1)

    def _crossings(self, L1: np.ndarray, t0: float, t1: float) -> tuple[np.ndarray, ...]:
        """Pixel index, time (float us) and polarity of every emitted crossing; updates ref and last-event time."""
        ref = self._ref
        d = L1 - ref
        fire = (d >= self._cp) | (d <= -np.asarray(self._cn))
        idx = np.flatnonzero(fire)
        if idx.size == 0:
            return _empty_crossings()
        l0, l1, r = self._last[idx], L1[idx], ref[idx]
        pos = l1 >= l0
        pol = np.where(pos, 1.0, -1.0)
        c = np.where(pos, _take(self._cp, idx), _take(self._cn, idx))
        u0, u1 = pol * (l0 - r), pol * (l1 - r)
        k_lo = np.maximum(1.0, np.floor(u0 / c) + 1.0)
        k_hi = np.floor(u1 / c)
        n = np.maximum(k_hi - k_lo + 1.0, 0.0).astype(np.int64)
        # dropped (refractory) crossings still move the reference; n == 0 leaves it where it is
        ref[idx] += np.where(n > 0, pol * k_hi * c, 0.0)
        with np.errstate(divide="ignore", invalid="ignore"):  # u1 == u0 only where n == 0 (rounding at a level)
            span = (t1 - t0) / (u1 - u0)
        t_first = t0 + (k_lo * c - u0) * span
        dt = c * span  # time between consecutive crossings of one pixel
        R = self.params.refractory_us
        if R > 0:
            since = t_first - self._last_event[idx]
            j0 = np.maximum(np.ceil((R - since) / dt - 1e-9), 0.0)
            m = np.maximum(np.ceil(R / dt - 1e-9), 1.0)
            n_keep = np.where(j0 < n, (n - 1 - j0) // m + 1, 0).astype(np.int64)
        else:
            j0, m, n_keep = 0.0, 1.0, n
        total = int(n_keep.sum())
        if total == 0:
            return _empty_crossings()
        owner = np.repeat(np.arange(idx.size), n_keep)
        rank = np.arange(total, dtype=np.float64) - (np.cumsum(n_keep) - n_keep)[owner]
        if R > 0:
            j = j0[owner] + rank * m[owner]
            last_j = j0 + (n_keep - 1) * m
            emitted = n_keep > 0
            self._last_event[idx[emitted]] = (t_first + last_j * dt)[emitted]
        else:
            j = rank
        times = t_first[owner] + j * dt[owner]
        return idx[owner], times, pos[owner]

    def _noise(self, t0: int, t1: int) -> tuple[np.ndarray, ...]:
        """Shot-noise and leak events (pixel index, float us time, polarity) in (t0, t1]."""
        p, npix = self.params, self.width * self.height
        rng, seconds = self._rng_noise, (t1 - t0) * 1e-6
        parts = []
        for rate, on_only in ((p.shot_noise_hz, False), (p.leak_hz, True)):
            if rate <= 0:
                continue
            k = int(rng.poisson(rate * npix * seconds))
            pix = rng.integers(0, npix, k)
            times = t0 + (t1 - t0) * (1.0 - rng.random(k))  # in (t0, t1]
            pol = np.ones(k, bool) if on_only else rng.random(k) < 0.5
            parts.append((pix, times, pol))
        if not parts:
            return _empty_crossings()
        return tuple(np.concatenate(col) for col in zip(*parts))


def _take(c: np.ndarray | float, idx: np.ndarray) -> np.ndarray | float:
    return c[idx] if isinstance(c, np.ndarray) else c


def _empty_crossings() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return np.empty(0, np.int64), np.empty(0, np.float64), np.empty(0, bool)


def _sorted_batch(signal: tuple[np.ndarray, ...], noise: tuple[np.ndarray, ...], width: int, t0: int,
                  t1: int) -> EventBatch:
    """Signal and noise crossings as one EventBatch sorted by (integer time, pixel, crossing order)."""
    pix = np.concatenate([signal[0], noise[0]]) if noise[0].size else signal[0]
    if pix.size == 0:
        return EventBatch.empty()
    times = np.concatenate([signal[1], noise[1]]) if noise[0].size else signal[1]
    pol = np.concatenate([signal[2], noise[2]]) if noise[0].size else signal[2]
    flag = np.ones(pix.size, bool)
    flag[signal[0].size:] = False
    t_rel = np.rint(times - t0).astype(np.int64)
    if noise[0].size == 0 and t1 - t0 < 1 << 16:
        # signal crossings come out in pixel order already, so a stable sort on the time offset alone
        # gives (time, pixel, crossing) order; on uint16 keys numpy's stable sort is a radix sort.
        order = np.argsort(t_rel.astype(np.uint16), kind="stable")
    else:
        order = np.argsort(t_rel * (int(pix.max()) + 1) + pix, kind="stable")
    pix = pix[order]
    return EventBatch((pix % width).astype(np.uint16), (pix // width).astype(np.uint16), t_rel[order] + t0,
                      pol[order].astype(np.uint8), flag[order])
