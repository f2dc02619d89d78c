"""The compiled level-crossing kernel of dvsot.events: one interval of every pixel, events out in time order.

The semantics are dvsot.events' (and docs/events.md's). This module only holds the numba code that
implements them, so that the simulator's Python side stays a thin driver: a first pass over the
pixels lists those that may fire, a second counts and times their crossings (pixel order), a counting
sort on the whole-microsecond time offset puts them in (time, pixel, crossing) order without a
comparison sort. All release the GIL, so frame decoding and file writing threads run beside them.
Three first passes, one per input kind: log frames (interval_events), codes into a log table
(coded_interval_events) and linear frames (linear_candidates, then linear_interval_events on the
candidates' logs, which numpy computes: numba's log differs from numpy's in the last bit).
"""

from __future__ import annotations

import numba
import numpy as np

# Level crossings are counted in units of the threshold: floor(u / C + TIE_TOL). A sample that lies on
# a level up to TIE_TOL * C below it in floating point counts as on it (see docs/events.md, "Ties").
TIE_TOL = 1e-9
# Refractory test slack, microseconds: crossings R apart in exact arithmetic are not dropped by rounding.
REFRACTORY_SLACK_US = 1e-6
# Intervals longer than this (microseconds) are time-ordered by a stable merge sort instead of a
# counting sort over every microsecond of the interval.
MAX_COUNTING_US = 1 << 22
# Log bounds (the sensor model's front ends) are put this far (log intensity) inside the gates: far more than the
# rounding of v - ref, so a pixel that passes a gate is past its bound.
LOG_SLACK = 1e-9
# Buckets of the index that turns a pixel's reference into the codes it may fire at (code_index): finer
# than an 8-bit log table's steps, so its bounds are a code or two wider than the exact ones.
CODE_BUCKETS = 4096


@numba.njit(cache=True, nogil=True, inline="always")
def _levels(l1, l0, base, off, cp, cn):
    """(rising, C, u0, u1, k_lo, k_hi) of one pixel: levels k_lo..k_hi of C are crossed (none if k_hi < k_lo)."""
    rising = l1 >= l0
    c = cp if rising else cn
    rel1 = (l1 - base) - off  # L1 relative to the reference
    u1 = rel1 if rising else -rel1
    k_hi = np.floor(u1 / c + TIE_TOL)
    if k_hi < 1.0:
        return rising, c, 0.0, u1, 1.0, k_hi
    rel0 = (l0 - base) - off
    u0 = rel0 if rising else -rel0
    return rising, c, u0, u1, max(1.0, np.floor(u0 / c + TIE_TOL) + 1.0), k_hi


@numba.njit(cache=True, nogil=True)
def interval_events(L1, last, base, off, ref, gate_on, gate_off, cp, cn, last_event, refractory_us, t0, t1, width,
                    scratch):
    """Crossings of every pixel between samples last (t0) and L1 (t1): finite, then x, y, t (us), p in time order.

    finite is False (and nothing is changed) if L1 holds NaN or an infinity.

    L1, last and base are log intensities (float64, one per pixel); off is the reference minus base and
    ref = base + off (updated in place, with last_event in us); cp and cn the per-pixel thresholds,
    gate_on and gate_off float32s just below them; scratch an int32 array of one entry per pixel.
    """
    # pass 1 reads 24 bytes a pixel: one that has not moved a threshold from its reference cannot fire;
    # for the few that have, the crossings are counted (before the refractory test: room for every event)
    n_cand = 0
    bound = 0
    finite = True
    for i in range(L1.shape[0]):
        li = L1[i]
        d = li - ref[i]
        finite &= abs(li) < np.inf  # False for NaN too
        if (d >= gate_on[i]) | (d <= -gate_off[i]):
            _, _, _, _, k_lo, k_hi = _levels(li, last[i], base[i], off[i], cp[i], cn[i])
            if k_hi >= k_lo:
                scratch[n_cand] = i
                n_cand += 1
                bound += int(k_hi - k_lo) + 1
    if not finite:
        return False, *_time_ordered(scratch[:0].astype(np.int64), scratch[:0].astype(np.int64), t0, 0, width)
    return True, *candidate_events(scratch[:n_cand], bound, L1, last, base, off, ref, cp, cn, last_event,
                                   refractory_us, t0, t1, width)


@numba.njit(cache=True, nogil=True)
def candidate_events(cand, bound, L1, last, base, off, ref, cp, cn, last_event, refractory_us, t0, t1, width):
    """interval_events' second pass: the crossings of the pixels cand (pixel order) that a first pass found, bound
    the number of their levels crossed; x, y, t (us), p in time order, the references moved (arguments as there)."""
    code = np.empty(bound, np.int64)  # pixel * 2 + polarity
    trel = np.empty(bound, np.int64)  # whole microseconds after t0
    ne = 0
    for j in range(cand.shape[0]):
        i = cand[j]
        ne = _emit(i, L1[i], last[i], base, off, ref, cp, cn, last_event, refractory_us, t0, t1, code, trel, ne)
    return _time_ordered(code[:ne], trel[:ne], t0, t1 - t0, width)


@numba.njit(cache=True, nogil=True, inline="always")
def _emit(i, l1, l0, base, off, ref, cp, cn, last_event, refractory_us, t0, t1, code, trel, ne):
    """Pixel i's crossings from l0 (t0) to l1 (t1) into code and trel from index ne, its reference moved; the new ne."""
    rising, c, u0, u1, k_lo, k_hi = _levels(l1, l0, base[i], off[i], cp[i], cn[i])
    if k_hi < k_lo:
        return ne
    # the reference moves to the last level crossed, also past crossings the refractory period drops
    off[i] += k_hi * c if rising else -k_hi * c
    ref[i] = base[i] + off[i]
    span_us = float(t1 - t0)
    per_unit = span_us / (u1 - u0)  # u1 > u0 here: k_hi >= k_lo > u0 / C + TIE_TOL
    k = k_lo
    while k <= k_hi:
        dt = min(max((k * c - u0) * per_unit, 0.0), span_us)  # the tolerance may reach past t1
        k += 1.0
        if refractory_us > 0.0:
            t_abs = t0 + dt
            if t_abs - last_event[i] < refractory_us - REFRACTORY_SLACK_US:
                continue
            last_event[i] = t_abs
        code[ne] = 2 * i + (1 if rising else 0)
        trel[ne] = np.int64(np.rint(dt))
        ne += 1
    return ne


@numba.njit(cache=True, nogil=True, inline="always")
def _log_bounds(r, g_on, g_off):
    """(lo, hi) float32: a log intensity v can pass a gate of reference r (v - r >= g_on or <= -g_off) only if v <= lo
    or v >= hi. LOG_SLACK inside the gates, then rounded outwards past float32's rounding (6e-8 of the value)."""
    hi = r + g_on - LOG_SLACK
    lo = r - g_off + LOG_SLACK
    return np.float32(lo + abs(lo) * 2.5e-7), np.float32(hi - abs(hi) * 2.5e-7)


@numba.njit(cache=True, nogil=True)
def log_bounds(ref, gate_on, gate_off, lo_log, hi_log):
    """Every pixel's log bounds for reference ref (see _log_bounds), in place."""
    for i in range(ref.shape[0]):
        lo_log[i], hi_log[i] = _log_bounds(ref[i], gate_on[i], gate_off[i])


@numba.njit(cache=True, nogil=True, inline="always")
def crossed(i, v, v0, base, off, cp, cn):
    """The number of levels pixel i crosses from v0 to v (0: none): for the compiled loops of dvsot.events.sensor,
    which make v themselves and test it against the log bounds first (a superset of the gates, which every
    crossing passes)."""
    _, _, _, _, k_lo, k_hi = _levels(v, v0, base[i], off[i], cp[i], cn[i])
    return int(k_hi - k_lo) + 1 if k_hi >= k_lo else 0


@numba.njit(cache=True, nogil=True)
def candidate_value_events(cand, l1c, l0c, bound, base, off, ref, lo_log, hi_log, gate_on, gate_off, cp, cn,
                           last_event, refractory_us, t0, t1, width):
    """candidate_events for pixels given with their values now (l1c) and before (l0c); the log bounds of the pixels
    whose reference moves are updated."""
    code = np.empty(bound, np.int64)
    trel = np.empty(bound, np.int64)
    ne = 0
    for j in range(cand.shape[0]):
        i = cand[j]
        ne = _emit(i, l1c[j], l0c[j], base, off, ref, cp, cn, last_event, refractory_us, t0, t1, code, trel, ne)
        lo_log[i], hi_log[i] = _log_bounds(ref[i], gate_on[i], gate_off[i])
    return _time_ordered(code[:ne], trel[:ne], t0, t1 - t0, width)


@numba.njit(cache=True, nogil=True)
def coded_interval_events(codes, table, last_codes, base, off, ref, lo_code, hi_code, first_ge, last_le, t_lo, inv_w,
                          gate_on, gate_off, cp, cn, last_event, refractory_us, t0, t1, width, scratch):
    """interval_events for frames given as integer codes into table (log intensity per code): x, y, t (us), p.

    codes and last_codes are this and the previous frame (flat uint8 or uint16). A pixel can fire only if
    its code lies outside (lo_code, hi_code), codes whose log intensity is within the gates of its
    reference (code_bounds, from the table's bucket index first_ge, last_le, t_lo, inv_w: code_index); so
    the first pass reads a few bytes a pixel and no log intensity. The bounds of the pixels that fire
    are updated here.
    """
    n_cand = 0
    bound = 0
    for i in range(codes.shape[0]):
        ci = codes[i]
        if (ci >= hi_code[i]) | (ci <= lo_code[i]):
            _, _, _, _, k_lo, k_hi = _levels(table[ci], table[last_codes[i]], base[i], off[i], cp[i], cn[i])
            if k_hi >= k_lo:
                scratch[n_cand] = i
                n_cand += 1
                bound += int(k_hi - k_lo) + 1
    code = np.empty(bound, np.int64)
    trel = np.empty(bound, np.int64)
    ne = 0
    for j in range(n_cand):
        i = scratch[j]
        ne = _emit(i, table[codes[i]], table[last_codes[i]], base, off, ref, cp, cn, last_event, refractory_us, t0,
                   t1, code, trel, ne)
        lo_code[i], hi_code[i] = _code_bounds(ref[i], gate_on[i], gate_off[i], first_ge, last_le, t_lo, inv_w)
    return _time_ordered(code[:ne], trel[:ne], t0, t1 - t0, width)


def code_index(table: np.ndarray) -> tuple[np.ndarray, np.ndarray, float, float]:
    """(first_ge, last_le, t_lo, inv_w): a bucket index of an increasing table for _code_bounds (numpy, once per table).

    CODE_BUCKETS equal buckets of log intensity span the table; first_ge[b] is the first code whose value
    is at least the bucket's start t_lo + b / inv_w, last_le[b] the last code at most that value.
    """
    t_lo, t_hi = float(table[0]), float(table[-1])
    inv_w = CODE_BUCKETS / max(t_hi - t_lo, 1e-300)
    starts = t_lo + np.arange(CODE_BUCKETS + 2) / inv_w
    first_ge = np.searchsorted(table, starts, side="left").astype(np.int32)
    last_le = (np.searchsorted(table, starts, side="right") - 1).astype(np.int32)
    return first_ge, last_le, t_lo, inv_w


@numba.njit(cache=True, nogil=True, inline="always")
def _code_bounds(r, g_on, g_off, first_ge, last_le, t_lo, inv_w):
    """(lo, hi) codes for reference r: a pixel whose code c has table[c] - r >= g_on has c >= hi, one with
    table[c] - r <= -g_off has c <= lo.

    Bounds from the bucket index (code_index), two buckets outside the gates: wider than the exact ones by
    those buckets (the first pass then tests a few more pixels), never narrower, whatever the rounding.
    """
    top = first_ge.shape[0] - 1
    b_hi = min(max(np.floor((r + g_on - t_lo) * inv_w) - 2.0, 0.0), float(top))
    b_lo = min(max(np.floor((r - g_off - t_lo) * inv_w) + 3.0, 0.0), float(top))
    return last_le[int(b_lo)], first_ge[int(b_hi)]


@numba.njit(cache=True, nogil=True)
def code_bounds(ref, gate_on, gate_off, first_ge, last_le, t_lo, inv_w, lo_code, hi_code):
    """Every pixel's (lo_code, hi_code) for reference ref (see coded_interval_events), in place."""
    for i in range(ref.shape[0]):
        lo_code[i], hi_code[i] = _code_bounds(ref[i], gate_on[i], gate_off[i], first_ge, last_le, t_lo, inv_w)


@numba.njit(cache=True, nogil=True)
def _time_ordered(code, trel, t0, span, width):
    """Events given in (pixel, crossing) order (code = pixel * 2 + polarity) as x, y, t, p stably sorted by t."""
    n = code.shape[0]
    sorted_code = np.empty(n, np.int64)
    t = np.empty(n, np.int64)
    if span <= MAX_COUNTING_US:  # counting sort: one pass to count, one to place
        start = np.zeros(span + 2, np.int64)
        for j in range(n):
            start[trel[j] + 1] += 1
        for b in range(1, span + 2):
            start[b] += start[b - 1]
        for b in range(span + 1):
            t[start[b]:start[b + 1]] = t0 + b
        for j in range(n):
            k = start[trel[j]]
            start[trel[j]] += 1
            sorted_code[k] = code[j]
    else:
        order = np.argsort(trel, kind="mergesort")
        for k in range(n):
            sorted_code[k] = code[order[k]]
            t[k] = t0 + trel[order[k]]
    x = np.empty(n, np.uint16)
    y = np.empty(n, np.uint16)
    p = np.empty(n, np.uint8)
    for k in range(n):
        pixel = sorted_code[k] >> 1
        x[k] = pixel % width
        y[k] = pixel // width
        p[k] = sorted_code[k] & 1
    return x, y, t, p


# Linear bounds are put this far (log intensity) inside the gates, and their float32s rounded outwards, so
# that numpy's log of a value past a bound (which need not agree with numba's exp to the last bit) passes the gate.
LINEAR_SLACK = 1e-9


@numba.njit(cache=True, nogil=True)
def linear_candidates(frame, lo_lin, hi_lin, scratch):
    """(problem, n): pixels of a linear frame at or beyond their bounds (linear_bounds) into scratch[:n].

    problem is 0, 1 for a NaN (or an infinity, without a negative value), 2 for a negative value,
    ranked as the float path reports them; nothing is changed.
    """
    n = 0
    nan = False
    neg = False
    inf = False
    for i in range(frame.shape[0]):
        v = frame[i]
        nan |= v != v
        neg |= v < 0
        inf |= v == np.inf
        if (v >= hi_lin[i]) | (v <= lo_lin[i]):
            scratch[n] = i
            n += 1
    return (1 if nan else 2 if neg else 1 if inf else 0), n


@numba.njit(cache=True, nogil=True)
def linear_interval_events(cand, L1c, L0c, base, off, ref, lo_lin, hi_lin, gate_on, gate_off, cp, cn, last_event,
                           refractory_us, t0, t1, width, log_eps):
    """interval_events for the candidate pixels cand of a linear frame, given their log intensities now (L1c) and
    before (L0c): x, y, t (us), p in time order; the bounds of the pixels whose reference moves are updated."""
    bound = 0
    for j in range(cand.shape[0]):
        i = cand[j]
        _, _, _, _, k_lo, k_hi = _levels(L1c[j], L0c[j], base[i], off[i], cp[i], cn[i])
        if k_hi >= k_lo:
            bound += int(k_hi - k_lo) + 1
    code = np.empty(bound, np.int64)
    trel = np.empty(bound, np.int64)
    ne = 0
    for j in range(cand.shape[0]):
        i = cand[j]
        before = off[i]
        ne = _emit(i, L1c[j], L0c[j], base, off, ref, cp, cn, last_event, refractory_us, t0, t1, code, trel, ne)
        if off[i] != before:
            lo_lin[i], hi_lin[i] = _linear_bounds(ref[i], gate_on[i], gate_off[i], log_eps)
    return _time_ordered(code[:ne], trel[:ne], t0, t1 - t0, width)


@numba.njit(cache=True, nogil=True, inline="always")
def _linear_bounds(r, g_on, g_off, log_eps):
    """(lo, hi) float32: a linear value v can pass a gate of reference r (log(v + eps) - r >= g_on or <= -g_off) only if
    v <= lo or v >= hi."""
    hi = np.exp(r + g_on - LINEAR_SLACK) - log_eps
    lo = np.exp(r - g_off + LINEAR_SLACK) - log_eps
    # float32 rounding is at most 6e-8 of the value: these steps put the bounds outside the float64 ones
    return np.float32(lo + abs(lo) * 2.5e-7 + 1e-30), np.float32(hi - abs(hi) * 2.5e-7)


@numba.njit(cache=True, nogil=True)
def linear_bounds(ref, gate_on, gate_off, log_eps, lo_lin, hi_lin):
    """Every pixel's linear bounds for reference ref (see linear_candidates), in place."""
    for i in range(ref.shape[0]):
        lo_lin[i], hi_lin[i] = _linear_bounds(ref[i], gate_on[i], gate_off[i], log_eps)
