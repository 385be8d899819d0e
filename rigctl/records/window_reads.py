"""The per-slip reads of :mod:`rigctl.records.features`, compiled: line fits, crossings, spreads.

:func:`rigctl.records.features.extract_events` works out, from the drive, each slip's windows
(the pre-drop ramp, the settled post-slip stick, the early loading ramp, the axis the post-slip
line is fitted against); :func:`read_windows` reads the samples in them, with the formulas of
:mod:`rigctl.records.signals` (``line_fit``, ``slope_se``) and :mod:`rigctl.records.features`
(``_crossing_time``, ``_drop_times``, the levels, the loading ramp, the drop's shape), over every
slip of a record in one call. The Python loop of thousands of small numpy calls cost more than the
model's integration on each evaluation of a fit (docs/performance.md, "Evaluation"). Sums are
numpy's (:mod:`rigctl.records.sample_stats`) and dot products pairwise sums of the products (numpy
hands them to BLAS, whose order is its own and whose threads, woken for windows over 10,000
samples, took the second core from a parallel worker), so the features are numpy's to rounding
(tests/records/test_compiled_reading.py).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from rigctl.records.sample_stats import np_dot, np_sum, np_var

# columns of read_windows' output
PEAK, TROUGH, DROP, SLIP, DELAY, FN_SWING, LAG = 0, 1, 2, 3, 4, 5, 6
RATE, ROUNDING, K_STICK, RING, STEP_FRAC = 7, 8, 9, 10, 11
SE_RATE, SE_ROUNDING, SE_K, FN_PEAK = 12, 13, 14, 15
N_COLUMNS = 16

DELAY_MIN_SLIP_NOISE = 10.0
"""``drop_delay_s`` is read only for a slip of at least 10 delta noise RMS: its half-way level then
lies 5 RMS from either settled line, beyond the noise's reach before the slip."""
MAX_NOISE_SHARE = 0.1
"""K(i) is read only where the force noise makes at most 10 % of Ft's variance in the window (the
force range of the window at least about 11 noise RMS)."""
MIN_RAMP_SAMPLES = 20  # a stick shorter than this many samples has no loading ramp read
RAMP_EARLY = (0.1, 0.6)  # the early part of the ramp, as fractions of the loading time
RAMP_END = 0.15  # the last part of the ramp (rounding), as a fraction of the loading time


@njit(cache=True)
def line_fit(x: np.ndarray, y: np.ndarray, i0: int, i1: int,
             x_eval: float) -> tuple[float, float]:
    """signals.line_fit: least-squares line through samples [i0, i1): (value at x_eval, slope)."""
    i0 = max(i0, 0)
    i1 = min(i1, x.shape[0])
    if i1 - i0 < 3:
        return math.nan, math.nan
    n = i1 - i0
    x0 = x[i0]
    tt = x[i0:i1] - x0
    yy = np.ascontiguousarray(y[i0:i1])
    st = np_sum(tt)
    sy = np_sum(yy)
    sxx = np_dot(tt, tt) - st * st / n
    if sxx <= 0.0:
        return sy / n, math.nan
    slope = (np_dot(tt, yy) - st * sy / n) / sxx
    return sy / n + slope * (x_eval - x0 - st / n), slope


@njit(cache=True)
def slope_se(x: np.ndarray, i0: int, i1: int, sigma_y: float) -> float:
    """signals.slope_se over x[i0:i1]."""
    n = i1 - i0
    if n < 3:
        return math.nan
    seg = np.ascontiguousarray(x[i0:i1])
    dx = seg - np_sum(seg) / n
    sxx = np_dot(dx, dx)
    return sigma_y / math.sqrt(sxx) if sxx > 0.0 else math.nan


@njit(cache=True)
def crossing_time(t: np.ndarray, y: np.ndarray, i0: int, i1: int, level: float,
                  rising: bool) -> float:
    """features._crossing_time: first time in [i0, i1) at which y reaches level (interpolated);
    NaN where it is there at i0 already or never gets there."""
    sgn = 1.0 if rising else -1.0
    for k in range(max(i1 - i0, 0)):
        if sgn * (y[i0 + k] - level) >= 0.0:
            if k == 0:
                return math.nan
            y0 = sgn * (y[i0 + k - 1] - level)
            y1 = sgn * (y[i0 + k] - level)
            t0, t1 = t[i0 + k - 1], t[i0 + k]
            return t0 + (-y0) / (y1 - y0) * (t1 - t0)
    return math.nan


@njit(cache=True)
def drop_times(t: np.ndarray, ft: np.ndarray, i_peak: np.ndarray, i_end: np.ndarray,
               sign: np.ndarray) -> np.ndarray:
    """features._drop_times: where Ft crosses half-way down each slip's fall."""
    out = np.empty(i_peak.shape[0])
    for j in range(i_peak.shape[0]):
        i_pk, i_e, s = i_peak[j], i_end[j], sign[j]
        lowest = s * ft[i_pk]
        for i in range(i_pk + 1, i_e + 1):
            v = s * ft[i]
            if math.isnan(v) or v < lowest:
                lowest = v
        size0 = s * ft[i_pk] - lowest
        level = ft[i_pk] - s * 0.5 * size0
        c = crossing_time(t, ft, i_pk, i_e + 1, level, s < 0)
        out[j] = c if math.isfinite(c) else t[i_pk]
    return out


@njit(cache=True)
def _valid(mask: np.ndarray, i0: int, i1: int) -> bool:
    """_Record.d_ok: delta within range over [i0, i1) (no mask: always)."""
    if mask.shape[0] == 0:
        return True
    i, stop = max(i0, 0), min(max(i1, 0), mask.shape[0])
    while i < stop and mask[i]:
        i += 1
    return i >= stop


@njit(cache=True)
def read_windows(
    t: np.ndarray, ft: np.ndarray, delta: np.ndarray, fn: np.ndarray, delta_valid: np.ndarray,
    x_drive: np.ndarray, i_peak: np.ndarray, sign: np.ndarray, td: np.ndarray,
    use_x: np.ndarray, xs_td: np.ndarray, i_pre0: np.ndarray, i_post0: np.ndarray,
    i_post1: np.ndarray, i_prev: np.ndarray, length: np.ndarray, i_e0: np.ndarray,
    i_e1: np.ndarray, i_n0: np.ndarray, i_ring0: np.ndarray, dt: float, sigma_f: float,
    sigma_d: float, drop_window: int,
) -> np.ndarray:
    """Each slip's read features (one row per slip, columns above; NaN where not read).

    Per slip: the drop time ``td``; the windows' sample indices: the pre-drop ramp from
    ``i_pre0`` to the peak, the settled stick [``i_post0``, ``i_post1``), the first sample after
    the previous drop ``i_prev``, the early ramp [``i_e0``, ``i_e1``), the ramp's end from
    ``i_n0``, the ringing from ``i_ring0``; the loading time ``length``; the stage position at
    the drop ``xs_td``; ``use_x`` where the post-slip line is fitted against the stage position
    ``x_drive`` instead of time. ``delta_valid`` empty: delta valid throughout."""
    n_ev = i_peak.shape[0]
    n = t.shape[0]
    out = np.full((n_ev, N_COLUMNS), np.nan)
    for j in range(n_ev):
        i_pk, s, t_d = i_peak[j], sign[j], td[j]
        a0, a1 = i_pre0[j], i_pk + 1
        p0, p1 = i_post0[j], i_post1[j]
        axis = x_drive if use_x[j] else t
        at = xs_td[j] if use_x[j] else t_d
        # levels at the drop
        peak, _ = line_fit(t, ft, a0, a1, t_d)
        trough, slope_after = line_fit(axis, ft, p0, p1, at)
        d_pk, _ = line_fit(t, delta, a0, a1, t_d)
        d_after, _ = line_fit(axis, delta, p0, p1, at)
        fn_pk, _ = line_fit(t, fn, a0, a1, t_d)
        fn_after, _ = line_fit(axis, fn, p0, p1, at)
        out[j, PEAK] = peak
        out[j, TROUGH] = trough
        drop = s * (peak - trough)
        out[j, DROP] = drop
        out[j, FN_PEAK] = fn_pk
        if _valid(delta_valid, a0, a1) and _valid(delta_valid, p0, p1):
            out[j, SLIP] = s * (d_after - d_pk)
            if abs(d_after - d_pk) > DELAY_MIN_SLIP_NOISE * sigma_d:
                # half-way between the settled line levels, not from the peak sample: the time
                # then moves continuously with the signal instead of with the sampling phase
                i0 = max(i_pk - drop_window, i_prev[j] + 1, 1)
                if _valid(delta_valid, i0, p0):
                    out[j, DELAY] = (
                        crossing_time(t, ft, i0, p0, 0.5 * (peak + trough), trough > peak)
                        - crossing_time(t, delta, i0, p0, 0.5 * (d_pk + d_after),
                                        d_after > d_pk))
        out[j, FN_SWING] = fn_pk - fn_after
        if _valid(delta_valid, a0, a1):
            out[j, LAG] = xs_td[j] - d_pk
        # the loading ramp
        if length[j] > MIN_RAMP_SAMPLES * dt:
            e0, e1, n0 = i_e0[j], i_e1[j], i_n0[j]
            _, rate = line_fit(t, ft, e0, e1, t_d)
            _, rate_end = line_fit(t, ft, n0, i_pk + 1, t_d)
            out[j, RATE] = s * rate
            c0, c1 = min(e0, n), min(e1, n)
            se_rate = slope_se(t, c0, c1, sigma_f)
            se_end = slope_se(t, min(n0, n), min(i_pk + 1, n), sigma_f)
            if rate != 0.0 and math.isfinite(rate):
                out[j, ROUNDING] = rate_end / rate
                out[j, SE_RATE] = se_rate / abs(rate)
                out[j, SE_ROUNDING] = math.hypot(se_end,
                                                 abs(rate_end) * se_rate / abs(rate)) / abs(rate)
            # K(i) is read only where the window's force range stands well above the force
            # noise: the share of Ft's variance that is noise (1 - reliability ratio; Fuller,
            # Measurement Error Models, 1987, Sec. 1.1) at most MAX_NOISE_SHARE
            m = max(c1 - c0, 0)
            var_f = np_var(np.ascontiguousarray(ft[c0:c1])) if m > 3 else 0.0
            reliability = 1.0 - sigma_f**2 / var_f if var_f > 0.0 else 0.0
            if m > 3 and reliability >= 1.0 - MAX_NOISE_SHARE and _valid(delta_valid, e0, e1):
                # dFt/d(delta) as the ratio of the two slopes in time. Regressing delta on Ft
                # instead would mix in a post-slip ringing that has not died out: in it Ft and
                # delta swing in opposition on the drive spring (dFt = -K0 d(delta)), and a slowly
                # decaying ringing (a light, lightly damped slider) read the stiffness several
                # times too high. A line in time averages the ringing out over the window's
                # cycles; noise in either channel only adds scatter, no bias of first order
                _, rate_d = line_fit(t, delta, e0, e1, t_d)
                k_i = rate / rate_d if rate_d != 0.0 else math.nan
                if math.isfinite(k_i) and k_i > 0.0:
                    out[j, K_STICK] = k_i
                    out[j, SE_K] = k_i * math.hypot(se_rate / abs(rate),
                                                    slope_se(t, c0, c1, sigma_d) / abs(rate_d))
        # the drop's shape: ringing about the settled line (less the white noise), sharpness
        # (the largest one-sample fall over the drop window)
        if not (math.isfinite(trough) and math.isfinite(drop) and drop > 0):
            continue
        r0, r1 = i_ring0[j], p0
        if r1 - r0 >= 4 and math.isfinite(slope_after):
            wgt = np.empty(r1 - r0)
            dev2 = np.empty(r1 - r0)
            for k in range(r1 - r0):
                i = r0 + k
                dev = ft[i] - (trough + slope_after * (axis[i] - at))
                dev2[k] = dev**2
                # weights ramp up over one sample from td + 1.5 dt (features._drop_shape)
                wgt[k] = min(max((t[i] - t_d - 1.5 * dt) / dt, 0.0), 1.0)
            ms = np_dot(wgt, dev2) / max(np_sum(wgt), 1e-12)
            out[j, RING] = math.sqrt(max(ms - sigma_f**2, 0.0))
        f1 = min(i_pk + drop_window, n - 1)
        if f1 > i_pk:
            biggest = s * (ft[i_pk] - ft[i_pk + 1])
            for i in range(i_pk + 1, f1):
                v = s * (ft[i] - ft[i + 1])
                if math.isnan(v) or math.isnan(biggest):
                    biggest = math.nan
                elif v > biggest:
                    biggest = v
            out[j, STEP_FRAC] = biggest / drop
    return out
