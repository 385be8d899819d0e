"""Per-event features of a run: what a stick-slip record is compared by.

Each detected slip (:mod:`rigctl.workbench.events`) gets the features below, measured the same way on
a measured record and on a simulated one. Levels are read from straight-line fits over windows of
the stick on either side of the drop, evaluated at the drop time, never from single samples: the
peak from the last part of the loading ramp, the trough as the *settled* post-slip level (the line
through the stick after the ringing, extrapolated back to the drop). This makes them insensitive to
sensor noise and to the aliased 1 kHz ringing right after a slip (docs/model.md).

========================  ======  ==========================================================
feature                   unit    definition
========================  ======  ==========================================================
``peak_N``                N       Ft at the drop from the pre-drop ramp line
``trough_N``              N       settled post-slip Ft line at the drop
``drop_N``                N       peak - trough
``stick_s``               s       stick duration: stage travel since the previous drop (the
                                  first event: since the start of motion) / drive velocity
                                  at the drop (= the recurrence time at constant velocity)
``rate_N_per_s``          N/s     stick loading rate dFt/dt (early part of the loading ramp)
``k_stick_N_per_m``       N/m     K(i) of the paper: dFt/d(delta) on the same part, from the
                                  regression of delta on Ft (Ft is the less noisy variable)
``rounding``              -       slope of the last 15 % of the ramp / early slope (1 = straight)
``ring_N``                N       RMS of Ft about the settled line in the settle window, less
                                  the white noise (aliased ringing amplitude)
``step_frac``             -       largest one-sample fall in the drop / drop (drop sharpness)
``slip_m``                m       jump of delta across the event (settled lines)
``fn_swing_N``            N       Fn before the drop - Fn after (line fits)
``lag_m``                 m       x_stage (simplified drive) - delta at the drop, less its
                                  run median
========================  ======  ==========================================================

The initial-stage curve (paper Sec. 3.1, Fig. 6b) is summarised per run by the local stiffness
dFt/d(delta) in four bands of Ft (10-30, 30-50, 50-70, 70-90 % of the first peak): it falls across
the bands when the contact slips progressively (``stress_evolution``) and is flat otherwise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from rigctl.workbench.drive_profile import DriveProfile
from rigctl.workbench.events import DetectionSettings, SlipIndices, detect_slips
from rigctl.workbench.signals import (
    FloatArray,
    line_fit,
    noise_sigma,
    regress_slope,
    slope_se,
)

EVENT_FEATURES: tuple[str, ...] = (
    "peak_N", "trough_N", "drop_N", "stick_s", "rate_N_per_s", "k_stick_N_per_m", "rounding",
    "ring_N", "step_frac", "slip_m", "fn_swing_N", "lag_m",
)
COVARIATES: tuple[str, ...] = (
    "t_s", "cycle", "fn_N", "v_drive_m_per_s", "hold_s", "stick_time_s", "cum_slip_m", "ft_N",
    "dft_dt_N_per_s",
)
MAX_ATTENUATION = 0.1
"""K(i) is read only where the force noise attenuates the fitted compliance by at most 10 % before
correction (the force range of the window at least about 11 noise RMS)."""
SE_FEATURES: tuple[str, ...] = ("rate_N_per_s", "rounding", "k_stick_N_per_m")
"""Features read from a fitted slope, whose per-event standard error :class:`EventTable` keeps."""
INIT_BANDS: tuple[tuple[float, float], ...] = ((0.1, 0.3), (0.3, 0.5), (0.5, 0.7), (0.7, 0.9))


@dataclass(frozen=True)
class ReadSettings:
    """How a run is read: slip detection and the post-slip settle time (fixed per campaign)."""

    detection: DetectionSettings
    settle_s: float = 0.08


@dataclass
class EventTable:
    """Features and covariates of the slips of one run (arrays of equal length)."""

    t_drop_s: FloatArray
    """Drop times relative to the run's first sample."""
    segment: np.ndarray
    """Drive segment of each event."""
    stage: np.ndarray
    """0 for the event that ends an initial stage loaded from rest, else 1."""
    features: dict[str, FloatArray]
    covariates: dict[str, FloatArray]
    init_k_N_per_m: FloatArray = field(default_factory=lambda: np.full(len(INIT_BANDS), np.nan))
    """Initial-stage stiffness in the bands of INIT_BANDS (NaN if the run starts loaded)."""
    i_peak: np.ndarray = field(default_factory=lambda: np.zeros(0, np.intp))
    se: dict[str, FloatArray] = field(default_factory=dict)
    """Per feature (those read from a fitted slope: the loading ramp), each event's own standard
    error from the record's white noise (ln units for log features); NaN where not measured.
    Large only where the window is short (a stick cut short by a velocity step)."""

    @property
    def n(self) -> int:
        return int(self.t_drop_s.shape[0])

    def first_in_segment(self) -> np.ndarray:
        """True for the first event of each drive segment."""
        out = np.ones(self.n, dtype=bool)
        out[1:] = self.segment[1:] != self.segment[:-1]
        return out


LOAD_CHANGE_WINDOW_S = 0.25
LOAD_CHANGE_FRACTION = 0.25
"""A slip where the drive's normal force changes by more than this fraction within
+-LOAD_CHANGE_WINDOW_S is a load-change slip (release, re-loading): its features are not compared.
Normal-force swings of the slips themselves (normal coupling, a few %) stay well below."""


def _drop_time(t: FloatArray, f: FloatArray, i_pk: int, i_end: int, level: float, s: int) -> float:
    """First crossing of ``level`` after the peak, linearly interpolated between samples."""
    seg = s * f[i_pk : i_end + 1]
    below = np.flatnonzero(seg < s * level)
    if below.size == 0 or below[0] == 0:
        return float(t[i_pk])
    k = i_pk + int(below[0])
    y0, y1 = s * f[k - 1], s * f[k]
    frac = (y0 - s * level) / (y0 - y1) if y0 != y1 else 0.0
    return float(t[k - 1] + frac * (t[k] - t[k - 1]))


def _stick_duration(drive: DriveProfile, t_prev: float, t_drop: float) -> float:
    """Stick duration at the drive velocity of the drop: the stage travel since the previous drop
    (or the start of motion) divided by that velocity. At constant velocity this is the time
    between the drops; across a velocity step or a hold it measures the loading the stick took,
    whatever the phase of the cycle at the step (the time would jump with it). Falls back to the
    time when the stage rests at the drop."""
    k = int(drive.segment_index(np.array([t_drop]))[0])
    v = abs(float(drive.phase_velocity[k]))
    travel = drive.travel_between(t_prev, t_drop)
    if drive.phase_is_hold[k] or v <= 0.0 or travel <= 0.0:
        return t_drop - t_prev
    return travel / v


def extract_events(
    t_s: FloatArray,
    ft_N: FloatArray,
    delta_m: FloatArray,
    fn_N: FloatArray,
    drive: DriveProfile,
    settings: ReadSettings,
    slips: SlipIndices | None = None,
    delta_valid: np.ndarray | None = None,
) -> EventTable:
    """Detect the slips of a record and measure their features (times relative to t_s[0]).

    ``delta_valid`` (per sample, :mod:`rigctl.workbench.probe_range`): where False a probe was over
    range, and the delta features whose windows include such samples are left NaN (not compared).
    """
    t = t_s - t_s[0]
    if slips is None:
        slips = detect_slips(t, ft_N, delta_m, settings.detection, delta_valid,
                             v_drive_m_s=drive.sliding_velocity_at(t), fn_N=fn_N)

    def d_ok(i0: int, i1: int) -> bool:
        return delta_valid is None or bool(delta_valid[max(i0, 0) : max(i1, 0)].all())
    n_ev = slips.n
    dt = float(np.median(np.diff(t))) if t.size > 1 else 1.0
    n = t.shape[0]
    settle = settings.settle_s
    sigma_f = noise_sigma(ft_N)
    t_motion = drive.motion_start_s()

    # drop times, refined between samples
    t_drop = np.empty(n_ev)
    size0 = np.empty(n_ev)
    for j in range(n_ev):
        i_pk, i_end, s = int(slips.i_peak[j]), int(slips.i_end[j]), int(slips.sign[j])
        size0[j] = s * ft_N[i_pk] - float(np.min(s * ft_N[i_pk : i_end + 1]))
        t_drop[j] = _drop_time(t, ft_N, i_pk, i_end, ft_N[i_pk] - s * 0.5 * size0[j], s)

    feats = {name: np.full(n_ev, np.nan) for name in EVENT_FEATURES}
    se = {name: np.full(n_ev, np.nan) for name in SE_FEATURES}
    sigma_d = noise_sigma(delta_m)
    cov = {name: np.full(n_ev, np.nan) for name in COVARIATES}
    stage = np.ones(n_ev, dtype=np.int8)
    segment = drive.segment_index(t_drop) if n_ev else np.zeros(0, np.intp)

    def idx(time: float) -> int:
        return int(np.searchsorted(t, time))

    t_run_end = float(t[-1])
    x_drive = drive.x_at(t)
    # the last slip's settled level needs at least half a typical cycle of record after it
    min_tail = 0.5 * float(np.median(np.diff(t_drop))) if n_ev >= 3 else 0.3
    for j in range(n_ev):
        td = float(t_drop[j])
        s = int(slips.sign[j])
        i_pk = int(slips.i_peak[j])
        prev_td = float(t_drop[j - 1]) if j > 0 else t_motion
        a = prev_td + settle if j > 0 else t_motion
        a_load = max(a, drive.last_change_before(td))
        length = td - a_load
        nxt = float(t_drop[j + 1]) if j + 1 < n_ev else t_run_end
        after_len = min(0.4 * (nxt - td - settle), 1.0)
        if j + 1 == n_ev and nxt - td - settle < min_tail:
            after_len = 0.0  # the record ends before the stick after the last slip is seen

        # levels at the drop: pre-drop ramp and settled post-slip line
        pre_len = min(0.15 * length, 0.3) if length > 0 else 0.0
        i_pre0, i_pre1 = idx(td - max(pre_len, 8 * dt)), i_pk + 1
        i_post0, i_post1 = idx(td + settle), idx(td + settle + after_len)
        # the settled post-slip line is read against the stage position when the stage changes
        # velocity inside the window (stick loading is linear in stage travel, not in time), and
        # up to the change when it stops or reverses there: a line in time across a velocity step
        # would bend the extrapolated trough by where in the cycle the step fell
        # the stage from the simplified drive (the encoder's quantisation steps would otherwise
        # show as a slow sawtooth in the lag)
        xs_td = float(drive.x_at(np.array([td]))[0])
        post_axis, post_at = t, td
        k_td = int(drive.segment_index(np.array([td]))[0])
        if i_post1 > i_post0 and int(drive.segment_index(t[i_post1 - 1 : i_post1])[0]) != k_td:
            if drive.steady_slide_between(td, float(t[i_post1 - 1])):
                post_axis, post_at = x_drive, xs_td
            else:
                i_post1 = min(i_post1, idx(drive.phase_end(td)))
        peak, _ = line_fit(t, ft_N, i_pre0, i_pre1, td)
        trough, slope_after = line_fit(post_axis, ft_N, i_post0, i_post1, post_at)
        d_pk, _ = line_fit(t, delta_m, i_pre0, i_pre1, td)
        d_after, _ = line_fit(post_axis, delta_m, i_post0, i_post1, post_at)
        fn_pk, _ = line_fit(t, fn_N, i_pre0, i_pre1, td)
        fn_after, _ = line_fit(post_axis, fn_N, i_post0, i_post1, post_at)
        feats["peak_N"][j] = peak
        feats["trough_N"][j] = trough
        feats["drop_N"][j] = s * (peak - trough)
        feats["stick_s"][j] = _stick_duration(drive, prev_td, td)
        if d_ok(i_pre0, i_pre1) and d_ok(i_post0, i_post1):
            feats["slip_m"][j] = s * (d_after - d_pk)
        feats["fn_swing_N"][j] = fn_pk - fn_after
        if d_ok(i_pre0, i_pre1):
            feats["lag_m"][j] = xs_td - d_pk

        # loading ramp: early slope, K(i), rounding
        if length > 20 * dt:
            i_e0, i_e1 = idx(a_load + 0.1 * length), idx(a_load + 0.6 * length)
            i_n0 = idx(td - 0.15 * length)
            _, rate = line_fit(t, ft_N, i_e0, i_e1, td)
            _, rate_end = line_fit(t, ft_N, i_n0, i_pk + 1, td)
            feats["rate_N_per_s"][j] = s * rate
            se_rate = slope_se(t[i_e0:i_e1], sigma_f)
            se_end = slope_se(t[i_n0 : i_pk + 1], sigma_f)
            if rate != 0.0 and np.isfinite(rate):
                feats["rounding"][j] = rate_end / rate
                se["rate_N_per_s"][j] = se_rate / abs(rate)
                se["rounding"][j] = math.hypot(se_end, abs(rate_end) * se_rate / abs(rate)) \
                    / abs(rate)
            f_seg = ft_N[i_e0:i_e1]
            # Ft is noisy too: the least-squares slope of delta on Ft is attenuated by the
            # reliability ratio 1 - sigma_f^2 / var(Ft) (errors in variables; Fuller, Measurement
            # Error Models, 1987, Sec. 1.1). The noise-free model's is not, so a short window
            # (a stick cut short by a velocity step) would read stiffer than the model: correct
            # for it, and only where it is under MAX_ATTENUATION
            var_f = float(np.var(f_seg)) if f_seg.size > 3 else 0.0
            reliability = 1.0 - sigma_f**2 / var_f if var_f > 0.0 else 0.0
            if f_seg.size > 3 and reliability >= 1.0 - MAX_ATTENUATION and d_ok(i_e0, i_e1):
                compliance = regress_slope(f_seg, delta_m[i_e0:i_e1]) / reliability
                if np.isfinite(compliance) and compliance > 0.0:
                    feats["k_stick_N_per_m"][j] = 1.0 / compliance
                    se["k_stick_N_per_m"][j] = slope_se(f_seg, sigma_d) / compliance

        # the drop itself: ringing about the settled line and sharpness
        if np.isfinite(trough) and np.isfinite(feats["drop_N"][j]) and feats["drop_N"][j] > 0:
            i_r0, i_r1 = idx(td + dt), idx(td + settle)
            if i_r1 - i_r0 >= 4 and np.isfinite(slope_after):
                tr = t[i_r0:i_r1]
                dev = ft_N[i_r0:i_r1] - (trough + slope_after * (post_axis[i_r0:i_r1] - post_at))
                # weights ramp up over one sample from td + 1.5 dt, so the window start moves
                # continuously with the drop time instead of jumping a whole sample
                wgt = np.clip((tr - td - 1.5 * dt) / dt, 0.0, 1.0)
                ms = float(wgt @ dev**2) / max(float(wgt.sum()), 1e-12)
                feats["ring_N"][j] = float(np.sqrt(max(ms - sigma_f**2, 0.0)))
            w = max(2, round(settings.detection.drop_window_s / dt))
            falls = s * (ft_N[i_pk : min(i_pk + w, n - 1)] - ft_N[i_pk + 1 : min(i_pk + w + 1, n)])
            if falls.size:
                feats["step_frac"][j] = float(np.max(falls)) / feats["drop_N"][j]

        cov["t_s"][j] = td
        cov["cycle"][j] = j
        cov["fn_N"][j] = fn_pk
        cov["hold_s"][j] = drive.hold_time_between(prev_td, td)
        cov["stick_time_s"][j] = td - prev_td
        cov["ft_N"][j] = peak
        cov["dft_dt_N_per_s"][j] = feats["rate_N_per_s"][j]
    if n_ev:
        cov["v_drive_m_per_s"] = np.abs(drive.velocity_at(t_drop))
        slips_m = np.nan_to_num(feats["slip_m"], nan=0.0)
        cov["cum_slip_m"] = np.concatenate([[0.0], np.cumsum(slips_m)[:-1]])
        finite = np.isfinite(feats["lag_m"])
        if finite.any():
            feats["lag_m"] = feats["lag_m"] - float(np.median(feats["lag_m"][finite]))

    if n_ev:
        # slips set off by a change of the normal load (a release under tangential load, a
        # re-loading) are not stick-slip cycles: they are paired, but not compared
        fn_a = drive.fn_at(np.clip(t_drop - LOAD_CHANGE_WINDOW_S, 0.0, None))
        fn_b = drive.fn_at(t_drop + LOAD_CHANGE_WINDOW_S)
        changing = np.abs(fn_b - fn_a) > LOAD_CHANGE_FRACTION * np.maximum(fn_a, fn_b)
        for name in feats:
            feats[name][changing] = np.nan

    init_k = np.full(len(INIT_BANDS), np.nan)
    if n_ev:
        i_m = idx(t_motion)
        f0 = float(np.median(ft_N[max(0, i_m - 20) : i_m + 1]))
        peak0 = float(feats["peak_N"][0])
        if np.isfinite(peak0) and abs(f0) < 0.1 * abs(peak0):
            stage[0] = 0
            init_k = _initial_curve(ft_N, delta_m, i_m, int(slips.i_peak[0]), peak0, f0, sigma_f,
                                    delta_valid)
    return EventTable(t_drop, segment, stage, feats, cov, init_k, slips.i_peak.copy(), se)


def _initial_curve(
    ft: FloatArray, delta: FloatArray, i0: int, i1: int, peak: float, f0: float, sigma: float,
    delta_valid: np.ndarray | None = None,
) -> FloatArray:
    """Local stiffness dFt/d(delta) of the initial loading in the bands of INIT_BANDS (NaN for a
    band with a sample where delta is not valid)."""
    out = np.full(len(INIT_BANDS), np.nan)
    f = ft[i0 : i1 + 1]
    d = delta[i0 : i1 + 1]
    ok = np.ones(f.shape[0], dtype=bool) if delta_valid is None else delta_valid[i0 : i1 + 1]
    span = peak - f0
    for b, (lo, hi) in enumerate(INIT_BANDS):
        sel = (f - f0 >= lo * span) & (f - f0 <= hi * span) if span > 0 else \
            (f - f0 <= lo * span) & (f - f0 >= hi * span)
        if np.count_nonzero(sel) < 5 or float(np.ptp(f[sel])) < 6.0 * sigma or not ok[sel].all():
            continue
        c = regress_slope(f[sel], d[sel])
        if np.isfinite(c) and c != 0.0:
            out[b] = 1.0 / c
    return out
