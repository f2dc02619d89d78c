"""ESIM-style event generation: linear or log intensity frames in, timestamped polarity events out.

Semantics (after ESIM, Rebecq et al. 2018), per pixel:

* Input is linear-light intensity I (or log intensity with ``is_log=True``); L = log(I + eps).
  The first frame only sets each pixel's reference level ref = L and its last sample L0 = L.
* Between samples (t0, L0) and (t1, L1) the log intensity is interpolated linearly. With
  polarity pol = sign(L1 - L0) and u = pol * (L - ref), every level u = k*C (k >= 1) with
  u0 < k*C <= u1 is crossed once: an event at t0 + (k*C - u0) / (u1 - u0) * (t1 - t0)
  (microseconds, rounded to the nearest integer). A pixel may fire several times per interval; the
  reference moves by C per crossing (ref += pol * k_max * C).
* Ties are exact: the reference is kept as an offset from the first frame's L (a sum of whole
  thresholds, so a return to the first frame's value is compared against 0 exactly), and levels are
  counted as floor(u / C + 1e-9) (dvsot.events.kernel.TIE_TOL), so a sample that returns to a level it
  fired from, which exact arithmetic puts on the level, counts as on it whatever the rounding of u.
* C+ and C- are separate (cp, cn). Threshold mismatch: with mismatch="fixed" (default) each pixel
  draws its own C+ ~ N(cp, sigma_cp) and C- ~ N(cn, sigma_cn) once, clamped to >= min_threshold;
  with mismatch="per_interval" they are drawn anew for every interval, as ESIM does (where a smaller
  draw leaves levels between ref and L0, they are skipped; ESIM's loop emits nothing then: docs/events.md).
* Refractory period R: a crossing closer than R to the pixel's last *emitted* event is dropped and the
  reference still advances (ESIM's behaviour); the test is on exact times, before rounding to 1 us. Crossings inside one
  interval are equally spaced in time (linear interpolation), so the kept ones are found in closed form: the first kept
  index j0 = ceil((R - (t_first - t_last)) / dt), then every m = ceil(R / dt)-th crossing.
* Noise beyond ESIM (flagged ``signal=False``; they do not move the reference): shot noise, events
  of random polarity at ``shot_noise_hz`` per pixel, and leak events, ON events at ``leak_hz`` per
  pixel (the visible effect of v2e's leaky reference), both as homogeneous Poisson processes with
  uniformly drawn pixels and times.
* Events of one interval are sorted by time, ties by pixel index (y * width + x), then by crossing
  order. The same frames, timestamps, parameters and seed give bit-identical events.

The per-pixel work is compiled (dvsot.events.kernel) and emits each interval's events already in time
order. Its first pass finds the few pixels that may fire: for log frames by comparing L with the
reference; for linear frames (after the first) and CodedFrames (8/16-bit images with a table of their
log intensities) by comparing the value as given with per-pixel bounds kept for the current reference,
so that only those pixels get a log. Every input kind gives the events its log intensities would.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from dvsot.core.bounds import MAX_CONTRAST, MAX_DURATION_US
from dvsot.core.errors import UserError
from dvsot.events.batch import STRUCTURED_DTYPE, EventBatch  # noqa: F401  (re-exported: dvsot.events.EventBatch)

MAX_NOISE_EVENTS = 5e7  # shot-noise or leak events drawn for one interval between frames (1.2 GB of arrays)


# The kernel's first pass compares L1 - ref with float32 gates this much inside the pixel's thresholds:
# far more than the rounding of ref or of the float32, so no pixel that fires is skipped.
GATE_MARGIN = 1e-6


_LINEAR = object()  # EventSimulator._bounds_for when the first pass's bounds are linear intensities
_LOG = object()  # ... when they are log intensities (the sensor model's fused front ends)


@dataclass(frozen=True)
class CodedFrame:
    """A frame as integer codes into a table: codes (height, width) u1 or u2; table[c] the log intensity of code c.

    table is float64, one entry per value of the code type, increasing (dvsot.events.frame_sources makes it for 8/16-bit
    images). The simulator then reads a byte or two a pixel where a float frame costs eight.
    """

    codes: np.ndarray
    table: np.ndarray


class EventParams(BaseModel):
    """Event-generator parameters: contrast thresholds (log intensity), mismatch, refractory period (us), noise (Hz)."""

    # allow_inf_nan=False: an infinite threshold or rate passes gt/ge bounds yet silently means "no events"
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    cp: float = Field(0.2, gt=0, le=MAX_CONTRAST, description="ON contrast threshold C+ (log intensity)")
    cn: float = Field(0.2, gt=0, le=MAX_CONTRAST, description="OFF contrast threshold C- (log intensity)")
    sigma_cp: float = Field(0.0, ge=0, le=MAX_CONTRAST, description="per-pixel std of C+ (log intensity)")
    sigma_cn: float = Field(0.0, ge=0, le=MAX_CONTRAST, description="per-pixel std of C- (log intensity)")
    min_threshold: float = Field(0.01, gt=0, le=MAX_CONTRAST, description="lower clamp of drawn thresholds")
    mismatch: Literal["fixed", "per_interval"] = "fixed"
    refractory_us: float = Field(0.0, ge=0, le=MAX_DURATION_US, description="refractory period, microseconds")
    log_eps: float = Field(1e-3, gt=0, description="eps in L = log(I + eps)")
    shot_noise_hz: float = Field(0.0, ge=0, description="shot-noise events per pixel per second (in the dark)")
    leak_hz: float = Field(0.0, ge=0, description="leak (ON) events per pixel per second (the median pixel's)")
    # the sensor model's stages (dvsot.events.sensor), each off at its default: the ideal model
    preset: str = Field("ideal", description="sensor model the other fields start from (dvsot.events.presets.PRESETS)")
    linlog_intensity: float = Field(0.0, ge=0, le=1, description="intensity (1 = full scale) below which the "
                                    "photoreceptor is linear; 0 = log everywhere")
    lowpass_order: Literal[0, 1, 2] = Field(0, description="photoreceptor low-pass: 0 off, 1 or 2 stages")
    lowpass_cutoff_hz: float = Field(0.0, ge=0, description="low-pass 3 dB cutoff at full-scale intensity, Hz")
    photoreceptor_noise_hz: float = Field(0.0, ge=0, description="noise events per pixel per second (ON and OFF) "
                                          "wanted from Gaussian noise on the log photoreceptor output, low-passed "
                                          "at lowpass_cutoff_hz; 0 = off")
    dark_intensity: float = Field(20 / 255, gt=0, le=1, description="dark current as an intensity (1 = full scale): "
                                  "the low-pass's bandwidth and the shot noise scale with (I + dark) / (1 + dark)")
    shot_noise_bright_factor: float = Field(1.0, ge=0, le=100, description="shot-noise rate at full-scale intensity "
                                            "over the rate in the dark")
    leak_spread_decades: float = Field(0.0, ge=0, le=3, description="std of log10 of the pixels' leak rates, decades")
    leak_period_cv: float = Field(1.0, ge=0, le=10, description="coefficient of variation of a pixel's leak periods "
                                  "(1 = Poisson, 0 = periodic)")
    hot_pixel_fraction: float = Field(0.0, ge=0, le=1, description="fraction of pixels that are hot")
    hot_pixel_hz: float = Field(0.0, ge=0, description="events per second of a hot pixel (ON, Poisson)")
    latency_us: float = Field(0.0, ge=0, le=1e6, description="delay of every event, microseconds")
    latency_jitter_us: float = Field(0.0, ge=0, le=1e6, description="std of the delay, microseconds")
    readout_limit_hz: float = Field(0.0, ge=0, description="events per second the readout passes; 0 = unlimited")
    readout_fifo_events: int = Field(0, ge=0, description="events waiting for the readout before new ones are "
                                     "dropped; 0 = none dropped, all delayed")

    @model_validator(mode="before")
    @classmethod
    def _preset(cls, values):
        """The named preset's fields under the ones given (dvsot.events.presets.expand_preset)."""
        from dvsot.events.presets import expand_preset

        return expand_preset(values) if isinstance(values, dict) else values

    @model_validator(mode="after")
    def _stages(self) -> EventParams:
        if self.lowpass_order and self.lowpass_cutoff_hz <= 0:
            raise ValueError(f"lowpass_cutoff_hz {self.lowpass_cutoff_hz:g} Hz: must be > 0 Hz with lowpass_order "
                             f"{self.lowpass_order}")
        if self.photoreceptor_noise_hz > 0:
            from dvsot.events.presets import PHOTORECEPTOR_NOISE_FIT_RANGE

            if not self.lowpass_order:
                raise ValueError(f"photoreceptor_noise_hz {self.photoreceptor_noise_hz:g} Hz: needs lowpass_order 1 "
                                 "or 2 (the noise's bandwidth is lowpass_cutoff_hz); lowpass_order is 0")
            lo, hi = (2 * r * self.lowpass_cutoff_hz for r in PHOTORECEPTOR_NOISE_FIT_RANGE)
            if not lo <= self.photoreceptor_noise_hz <= hi:
                raise ValueError(f"photoreceptor_noise_hz {self.photoreceptor_noise_hz:g} Hz: must be 0 (off) or "
                                 f"within {lo:g}..{hi:g} events per pixel per second with lowpass_cutoff_hz "
                                 f"{self.lowpass_cutoff_hz:g} Hz ({2 * PHOTORECEPTOR_NOISE_FIT_RANGE[0]:g} to "
                                 f"{2 * PHOTORECEPTOR_NOISE_FIT_RANGE[1]:g} times the cutoff: the range of the "
                                 "rate's fit)")
        if 0 < self.readout_limit_hz < 1:
            raise ValueError(f"readout_limit_hz {self.readout_limit_hz:g} events/s: must be 0 (unlimited) or >= 1")
        return self

    @classmethod
    def parse(cls, values: dict, source: str = "event parameters") -> EventParams:
        """Validated parameters; a bad field raises UserError naming it, with its unit and range."""
        try:
            return cls(**values)
        except ValidationError as exc:
            raise UserError(f"{source}: {param_problem(exc)}") from None


def param_problem(exc: ValidationError, names: dict[str, str] | None = None) -> str:
    """One line for the first error of an EventParams validation: the field (or its flag in names), unit and range."""
    err = exc.errors()[0]
    loc = [str(p) for p in err["loc"]]
    if not loc:  # a model-level check (a preset, the low-pass, the readout): its message names the field itself
        msg = str(err["msg"]).removeprefix("Value error, ")
        field = msg.split(" ", 1)[0]
        return (names or {}).get(field, field) + msg[len(field):] if field in (names or {}) else msg
    if names and loc[-1] in names:  # a flag: its value as given
        return f"{names[loc[-1]]} {err.get('input')!r}: {field_message(err)}"
    return f"field '{'.'.join(loc)}': {field_message(err)}"


def field_message(err: dict) -> str:
    """What an EventParams field's validation error err (pydantic's) asks for: its range and, in brackets, its unit."""
    info = EventParams.model_fields.get(str(err["loc"][-1])) if err["loc"] else None
    if info is None or err["type"] not in ("greater_than", "greater_than_equal", "less_than", "less_than_equal"):
        return str(err["msg"]).removeprefix("Value error, ")
    bounds = [f"{op} {getattr(m, attr):g}" for m in info.metadata for attr, op in
              (("gt", ">"), ("ge", ">="), ("lt", "<"), ("le", "<=")) if getattr(m, attr, None) is not None]
    unit = f"; {info.description}" if info.description else ""
    return f"{err['msg']} (range {' and '.join(bounds)}{unit})"


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
        self._set_thresholds(*self._draw_thresholds())
        self._scratch = np.empty(n, np.int32)  # the kernel's list of pixels that may fire
        self._base = np.zeros(n, np.float64)  # L of the first frame: the origin of each pixel's levels
        self._off = np.zeros(n, np.float64)  # reference level minus base (a sum of whole thresholds)
        self._ref = np.zeros(n, np.float64)  # base + off: the kernel's quick test of which pixels may fire
        self._last = np.zeros(n, np.float64)  # L at the previous sample
        self._last_is_ours = True  # False while _last is a caller's frame (step with copy=False)
        self._last_event = np.full(n, -np.inf)  # time of the last emitted event, float microseconds
        self._t_prev: int | None = None
        self._buf = np.empty(n, np.float64)
        # the previous frame as given, when it was coded or linear ("codes"/"linear"; _last is stale then) or None
        self._last_kind: str | None = None
        self._last_src = np.empty(0)  # its codes or linear values, flat
        self._table: np.ndarray | None = None  # the table of codes in _last_src
        # what the per-pixel bounds of the first pass are for: a table (_lo_code/_hi_code), _LINEAR, _LOG, or None
        # (stale)
        self._bounds_for: object = None
        self._lo_code = self._hi_code = np.empty(0, np.int16)
        self._lo_lin = self._hi_lin = np.empty(0, np.float32)
        self._lo_log = self._hi_log = np.empty(0, np.float32)
        self._index: tuple = (None,)  # (table, its bucket index: dvsot.events.kernel.code_index)
        self._checked_tables: list[np.ndarray] = []
        self._sensor = None  # the stages beyond the ideal pixel (dvsot.events.sensor), when any is on
        self._in_sensor = False
        from dvsot.events.presets import sensor_on

        if sensor_on(self.params):
            from dvsot.events.sensor import SensorModel

            self._sensor = SensorModel(self, seed)

    def sensor_counts(self) -> dict | None:
        """The sensor model's counts (readout drops, events held after the last frame), or None for the ideal model."""
        return None if self._sensor is None else self._sensor.counts()

    def _draw_thresholds(self) -> tuple[np.ndarray | float, np.ndarray | float]:
        p, n = self.params, self.width * self.height
        out = []
        for c, sigma in ((p.cp, p.sigma_cp), (p.cn, p.sigma_cn)):
            if sigma > 0:
                out.append(np.maximum(self._rng_threshold.normal(c, sigma, n), p.min_threshold))
            else:
                out.append(float(c))
        return out[0], out[1]

    def _set_thresholds(self, cp: np.ndarray | float, cn: np.ndarray | float) -> None:
        """Use these C+ and C- (scalars or one per pixel); the kernel gets one float64 per pixel and the minima."""
        n = self.width * self.height
        self._cp, self._cn = cp, cn
        self._bounds_for = None  # the first pass's bounds follow the gates
        self._cp_px, self._cn_px = (c if isinstance(c, np.ndarray) else np.full(n, float(c)) for c in (cp, cn))
        self._gate_on, self._gate_off = ((c * (1 - GATE_MARGIN)).astype(np.float32) for c in (self._cp_px, self._cn_px))

    @property
    def thresholds(self) -> tuple[np.ndarray, np.ndarray]:
        """Current per-pixel C+ and C- as (height, width) arrays (log intensity)."""
        return self._cp_px.reshape(self.height, self.width), self._cn_px.reshape(self.height, self.width)

    def _log_frame(self, frame: np.ndarray, is_log: bool, copy: bool) -> np.ndarray:
        """The frame as flat float64 log intensity: in self._buf, or the frame itself (is_log, float64, copy=False).

        The first frame is checked here in full; later ones for negative intensities only (NaN and
        infinities are found by the kernel's first pass).
        """
        a = np.asarray(frame)
        if a.shape != (self.height, self.width):
            raise UserError(f"frame has shape {a.shape}, expected ({self.height}, {self.width})")
        if a.dtype.kind not in "fiu":
            raise UserError(f"frame has dtype {a.dtype}, expected a real number type")
        first = self._t_prev is None
        if not is_log:
            if first:
                return log_intensity(a, self.params.log_eps, self._buf)
            if a.min() < 0:  # NaN and inf are left to the kernel
                raise UserError("frame contains negative intensities")
            np.add(a.reshape(-1), self.params.log_eps, out=self._buf, dtype=np.float64, casting="unsafe")
            return np.log(self._buf, out=self._buf)
        if not copy and a.dtype == np.float64 and a.flags.c_contiguous:
            out = a.reshape(-1)
        else:
            out = self._buf
            np.copyto(out, a.reshape(-1), casting="unsafe")
        if first and not np.isfinite(out.sum()):
            raise UserError("frame contains NaN or infinite values")
        return out

    def step(self, frame: np.ndarray | CodedFrame, t_us: int, is_log: bool = False, copy: bool = True) -> EventBatch:
        """Events (time-sorted) between the previous frame and this one, at t_us microseconds.

        frame is linear intensity, log intensity (is_log=True), or a CodedFrame (is_log is then ignored);
        a CodedFrame gives the same events as its log intensities table[codes] would.

        With is_log=True and copy=False a float64 frame is kept, not copied, until the next step: the
        caller must not change it in between (dvsot.simulate_frames hands over fresh frames).
        """
        t_us = int(t_us)
        if self._sensor is not None and not self._in_sensor:  # the stages call back here with their filtered frame
            self._in_sensor = True
            try:
                return self._sensor.step(frame, t_us, is_log)
            finally:
                self._in_sensor = False
        if isinstance(frame, CodedFrame):
            return self._step_coded(frame, t_us, copy)
        if not is_log and self._t_prev is not None and not self._redraws():
            return self._step_linear(frame, t_us, copy)
        self._log_last()
        L1 = self._log_frame(frame, is_log, copy)
        if self._t_prev is None:
            self._base[:] = L1
            self._ref[:] = L1
            self._last[:] = L1
            self._t_prev = t_us
            return EventBatch.empty()
        if t_us <= self._t_prev:
            raise UserError(f"frame timestamps must increase: {t_us} us follows {self._t_prev} us")
        t0, t1 = self._t_prev, t_us
        p = self.params
        self._check_noise(t0, t1)  # before the kernel and any array: a refused interval costs nothing
        if self._redraws():
            self._set_thresholds(*self._draw_thresholds())
        from dvsot.events.kernel import interval_events  # numba: imported when the first events are due

        finite, x, y, t, pol = interval_events(L1, self._last, self._base, self._off, self._ref, self._gate_on,
                                               self._gate_off, self._cp_px, self._cn_px, self._last_event,
                                               float(p.refractory_us), t0, t1, self.width, self._scratch)
        if not finite:  # found before the kernel changed anything
            raise UserError("frame contains NaN or infinite values")
        self._bounds_for = None  # references moved outside the kernels that keep bounds
        signal = EventBatch(x, y, t, pol, np.ones(t.shape[0], bool))
        noise = self._noise(t0, t1)
        self._keep_last(L1)
        self._t_prev = t1
        return signal if noise[0].size == 0 else _merge_noise(signal, noise, self.width, t0)

    def _fresh_log_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(lo, hi) float32 log bounds of every pixel for its reference (kernel.log_bounds), computed if stale."""
        if self._bounds_for is not _LOG:
            from dvsot.events.kernel import log_bounds

            if self._lo_log.shape != self._ref.shape:
                self._lo_log, self._hi_log = (np.empty(self._ref.shape, np.float32) for _ in range(2))
            log_bounds(self._ref, self._gate_on, self._gate_off, self._lo_log, self._hi_log)
            self._bounds_for = _LOG
        return self._lo_log, self._hi_log

    def _step_candidates(self, n: int, bound: int, l1c: np.ndarray, l0c: np.ndarray, last: np.ndarray,
                         t_us: int) -> EventBatch:
        """step() for a frame whose first pass the caller has run (dvsot.events.sensor's fused front ends, on the log
        bounds of `_fresh_log_bounds`): the n pixels that may fire in self._scratch[:n], crossing `bound` levels in
        all, their log intensities now and before in l1c[:n] and l0c[:n]; `last` (flat float64, kept, not copied)
        is the frame's log intensity as the next interval starts from.

        Only after the first frame, with fixed thresholds, and with the interval checked (`_interval`) first.
        """
        from dvsot.events.kernel import candidate_value_events

        t0, t1 = self._t_prev, int(t_us)
        x, y, t, pol = candidate_value_events(self._scratch[:n], l1c[:n], l0c[:n], bound, self._base, self._off,
                                              self._ref, self._lo_log, self._hi_log, self._gate_on, self._gate_off,
                                              self._cp_px, self._cn_px, self._last_event,
                                              float(self.params.refractory_us), t0, t1, self.width)
        self._keep_last(last)
        self._t_prev = t1
        return EventBatch(x, y, t, pol, np.ones(t.shape[0], bool))

    def _redraws(self) -> bool:
        """True if the thresholds are drawn anew for every interval (then only the float kernel runs)."""
        p = self.params
        return p.mismatch == "per_interval" and (p.sigma_cp > 0 or p.sigma_cn > 0)

    def _log_last(self) -> np.ndarray:
        """The previous frame's log intensities (_last), computed now if it came coded or linear."""
        if self._last_kind == "codes":
            self._last = np.take(self._table, self._last_src)
        elif self._last_kind == "linear":  # as _log_frame computes them
            self._last = np.log(np.add(self._last_src, self.params.log_eps, dtype=np.float64))
        if self._last_kind is not None:
            self._last_is_ours, self._last_kind = True, None
        return self._last

    def _interval(self, t_us: int) -> tuple[int, int]:
        """(t0, t1) of the interval up to t_us; UserError if time does not increase or the noise would be too much."""
        if t_us <= self._t_prev:
            raise UserError(f"frame timestamps must increase: {t_us} us follows {self._t_prev} us")
        self._check_noise(self._t_prev, t_us)
        return self._t_prev, t_us

    def _finish(self, x, y, t, pol, t0: int, t1: int, kind: str | None, src: np.ndarray) -> EventBatch:
        """The interval's signal events and noise as one batch; src (kind "codes"/"linear"; None: _last) is kept."""
        signal = EventBatch(x, y, t, pol, np.ones(t.shape[0], bool))
        noise = self._noise(t0, t1)
        self._last_kind, self._last_src, self._t_prev = kind, src, t1
        return signal if noise[0].size == 0 else _merge_noise(signal, noise, self.width, t0)

    def _step_coded(self, frame: CodedFrame, t_us: int, copy: bool) -> EventBatch:
        """step() for a CodedFrame: the coded kernel, or the float one where it cannot serve (see below)."""
        codes, table = self._codes(frame), frame.table
        if self._t_prev is None:
            L1 = np.take(table, codes)
            self._base[:] = L1
            self._ref[:] = L1
            self._last[:] = L1
            self._last_kind, self._last_src, self._table = "codes", (codes.copy() if copy else codes), table
            self._t_prev = t_us
            return EventBatch.empty()
        if self._redraws() or self._last_kind != "codes" or table is not self._table:
            # gates drawn anew every interval (the bounds would be recomputed for every pixel), or the previous
            # frame not coded with this table: the same events from the float kernel
            batch = self.step(np.take(table, codes).reshape(self.height, self.width), t_us, is_log=True, copy=False)
            self._last_kind, self._last_src, self._table = "codes", (codes.copy() if copy else codes), table
            return batch
        t0, t1 = self._interval(t_us)
        from dvsot.events.kernel import code_bounds, code_index, coded_interval_events

        if self._index[0] is not table:
            self._index = (table, *code_index(table))
        if self._bounds_for is not table:
            dtype = np.int16 if table.shape[0] <= 1 << 15 else np.int32
            if self._lo_code.shape != codes.shape or self._lo_code.dtype != dtype:
                self._lo_code, self._hi_code = np.empty(codes.shape, dtype), np.empty(codes.shape, dtype)
            code_bounds(self._ref, self._gate_on, self._gate_off, *self._index[1:], self._lo_code, self._hi_code)
            self._bounds_for = table
        x, y, t, pol = coded_interval_events(codes, table, self._last_src, self._base, self._off, self._ref,
                                             self._lo_code, self._hi_code, *self._index[1:], self._gate_on,
                                             self._gate_off,
                                             self._cp_px, self._cn_px, self._last_event,
                                             float(self.params.refractory_us), t0, t1, self.width, self._scratch)
        return self._finish(x, y, t, pol, t0, t1, "codes", codes.copy() if copy else codes)

    def _step_linear(self, frame: np.ndarray, t_us: int, copy: bool) -> EventBatch:
        """step() for a linear frame after the first, fixed thresholds: only the pixels past their bounds get a log."""
        a = np.asarray(frame)
        if a.shape != (self.height, self.width):
            raise UserError(f"frame has shape {a.shape}, expected ({self.height}, {self.width})")
        if a.dtype.kind not in "fiu":
            raise UserError(f"frame has dtype {a.dtype}, expected a real number type")
        from dvsot.events.kernel import linear_bounds, linear_candidates, linear_interval_events

        eps = self.params.log_eps
        if self._bounds_for is not _LINEAR:
            if self._lo_lin.shape != self._ref.shape:
                self._lo_lin, self._hi_lin = (np.empty(self._ref.shape, np.float32) for _ in range(2))
            linear_bounds(self._ref, self._gate_on, self._gate_off, eps, self._lo_lin, self._hi_lin)
            self._bounds_for = _LINEAR
        flat = np.ascontiguousarray(a).reshape(-1)
        problem, n = linear_candidates(flat, self._lo_lin, self._hi_lin, self._scratch)
        if problem == 2:  # the float path's order: negative values first, then time, noise, NaN and infinities
            raise UserError("frame contains negative intensities")
        t0, t1 = self._interval(t_us)
        if problem:
            raise UserError("frame contains NaN or infinite values")
        cand = self._scratch[:n]
        dense = n > flat.size // 8  # most pixels pass: the whole frame's log, as the float path, kept for the next
        if dense:
            L1 = np.log(np.add(flat, eps, out=self._buf, dtype=np.float64, casting="unsafe"), out=self._buf)
            L1c = L1[cand]
        else:
            L1c = np.log(np.add(flat[cand], eps, dtype=np.float64))  # numpy's log, as the float path's (not numba's)
        if self._last_kind == "linear":
            L0c = np.log(np.add(self._last_src[cand], eps, dtype=np.float64))
        else:
            L0c = self._log_last()[cand]
        x, y, t, pol = linear_interval_events(cand, L1c, L0c, self._base, self._off, self._ref, self._lo_lin,
                                              self._hi_lin, self._gate_on, self._gate_off, self._cp_px, self._cn_px,
                                              self._last_event, float(self.params.refractory_us), t0, t1,
                                              self.width, eps)
        if dense:
            self._keep_last(L1)
            return self._finish(x, y, t, pol, t0, t1, None, self._last_src)
        return self._finish(x, y, t, pol, t0, t1, "linear", flat.copy() if copy else flat)

    def _codes(self, frame: CodedFrame) -> np.ndarray:
        """The frame's codes, flat; the shape, the code type and (once per table) the table checked."""
        a = np.asarray(frame.codes)
        if a.shape != (self.height, self.width):
            raise UserError(f"frame has shape {a.shape}, expected ({self.height}, {self.width})")
        if a.dtype not in (np.uint8, np.uint16):
            raise UserError(f"coded frame has dtype {a.dtype}, expected uint8 or uint16")
        table = frame.table
        if not any(table is t for t in self._checked_tables):
            size = np.iinfo(a.dtype).max + 1
            if not (isinstance(table, np.ndarray) and table.dtype == np.float64 and table.shape == (size,)):
                raise UserError(f"coded frame's table must be {size} float64 values for {a.dtype} codes")
            if not (np.isfinite(table).all() and np.all(np.diff(table) > 0)):
                raise UserError("coded frame's table must be finite and increasing")
            self._checked_tables = self._checked_tables[-3:] + [table]
        elif a.dtype.itemsize != (1 if table.shape[0] == 256 else 2):
            raise UserError(f"coded frame has dtype {a.dtype}, its table {table.shape[0]} entries")
        return np.ascontiguousarray(a).reshape(-1)

    def _keep_last(self, L1: np.ndarray) -> None:
        """L1 becomes the previous sample; the simulator's own buffers are reused, a caller's array never written."""
        self._last_kind = None
        if L1 is self._buf:
            if self._last_is_ours:
                self._last, self._buf = L1, self._last
            else:
                self._last, self._buf = L1, np.empty_like(L1)
            self._last_is_ours = True
        else:
            self._last, self._last_is_ours = L1, False

    def _check_noise(self, t0: int, t1: int) -> None:
        """UserError if shot noise or leak would draw more than MAX_NOISE_EVENTS events in (t0, t1] (us)."""
        problem = noise_rate_problem(self.params, self.width, self.height, t1 - t0)
        if problem:
            raise UserError(problem)

    def _noise(self, t0: int, t1: int) -> tuple[np.ndarray, ...]:
        """Shot-noise and leak events (pixel index, float us time, polarity) in (t0, t1]."""
        p, npix = self.params, self.width * self.height
        rng, seconds = self._rng_noise, (t1 - t0) * 1e-6
        parts = []
        if self._sensor is not None:  # the sensor model draws its own noise
            return _empty_crossings()
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


def log_intensity(frame: np.ndarray, log_eps: float, out: np.ndarray | None = None) -> np.ndarray:
    """L = log(I + log_eps) of a linear-intensity frame, flattened to float64; NaN, inf or I < 0 raise UserError."""
    a = np.asarray(frame)
    lo, hi = a.min(), a.max()  # checked on the frame as given (float32 from the readers: half of float64's bytes)
    if not (np.isfinite(lo) and np.isfinite(hi)):  # NaN propagates into both
        raise UserError("frame contains NaN or infinite values")
    if lo < 0:
        raise UserError("frame contains negative intensities")
    out = np.empty(a.size, np.float64) if out is None else out
    np.add(a.reshape(-1), log_eps, out=out, dtype=np.float64, casting="unsafe")
    return np.log(out, out=out)


def _empty_crossings() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return np.empty(0, np.int64), np.empty(0, np.float64), np.empty(0, bool)


def _merge_noise(signal: EventBatch, noise: tuple[np.ndarray, ...], width: int, t0: int) -> EventBatch:
    """Time-ordered signal events and noise (pixel, float us, polarity) as one batch sorted by (time, pixel), signal
    first."""
    pix_n, times, pol_n = noise
    pix = np.concatenate([signal.y.astype(np.int64) * width + signal.x, pix_n])
    t_rel = np.concatenate([signal.t - t0, np.rint(times - t0).astype(np.int64)])
    pol = np.concatenate([signal.p, pol_n.astype(np.uint8)])
    flag = np.concatenate([signal.signal, np.zeros(pix_n.size, bool)])
    order = np.argsort(t_rel * (int(pix.max()) + 1) + pix, kind="stable")
    pix = pix[order]
    return EventBatch((pix % width).astype(np.uint16), (pix // width).astype(np.uint16), t_rel[order] + t0,
                      pol[order], flag[order])


def noise_rate_problem(params: EventParams, width: int, height: int, interval_us: float) -> str | None:
    """Why shot noise or leak at `params`' rates would draw more than MAX_NOISE_EVENTS events over a width x height
    sensor between frames interval_us microseconds apart, or None."""
    for field in ("shot_noise_hz", "leak_hz"):
        rate = getattr(params, field)
        mean = rate * width * height * interval_us * 1e-6
        if mean > MAX_NOISE_EVENTS:
            return (f"{field} {rate:g} over {width}x{height} px gives {mean:.3g} noise events between frames "
                    f"{interval_us / 1000:g} ms apart, more than the bound of {MAX_NOISE_EVENTS:g}")
    return None
