"""Per-event features of a run: what a stick-slip record is compared by.

Each detected slip (:mod:`rigctl.records.events`) gets the features below, measured the same way on
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
``k_stick_N_per_m``       N/m     K(i) of the paper: dFt/d(delta) on the same part, as the
                                  ratio of the two line slopes in time, dFt/dt / d(delta)/dt
                                  (a post-slip ringing still alive in the window averages out)
``rounding``              -       slope of the last 15 % of the ramp / early slope (1 = straight)
``ring_N``                N       RMS of Ft about the settled line in the settle window, less
                                  the white noise (aliased ringing amplitude)
``step_frac``             -       largest one-sample fall in the drop / drop (drop sharpness)
``slip_m``                m       jump of delta across the event (settled lines)
``drop_delay_s``          s       time Ft crosses half-way between its peak and trough lines -
                                  the time delta crosses half-way between its settled lines:
                                  small for the mechanics (the force follows the slip within a
                                  small part of its duration), about ln 2 tau for a force
                                  sensor of time constant tau (``sensor_dynamics``)
``fn_swing_N``            N       Fn before the drop - Fn after (line fits)
``lag_m``                 m       x_stage (simplified drive) - delta at the drop, less its
                                  run median
========================  ======  ==========================================================

The initial-stage curve (paper Sec. 3.1, Fig. 6b) is summarised per run by the local stiffness
dFt/d(delta) in four bands of Ft (10-30, 30-50, 50-70, 70-90 % of the first peak): it falls across
the bands when the contact slips progressively (``stress_evolution``) and is flat otherwise.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from rigctl.records import window_reads
from rigctl.records.drive_profile import DriveProfile
from rigctl.records.events import DetectionSettings, SlipIndices, detect_slips
from rigctl.records.feature_info import EVENT_FEATURES, SE_FEATURES
from rigctl.records.signals import (
    FloatArray,
    median,
    noise_sigma,
    regress_slope,
)
from rigctl.records.time_base import TimeBase

COVARIATES: tuple[str, ...] = (
    "t_s", "cycle", "fn_N", "v_drive_m_per_s", "hold_s", "stick_time_s", "cum_slip_m", "ft_N",
    "dft_dt_N_per_s", "x_drive_m",
)
"""Per slip, what it may depend on. ``x_drive_m`` is the drive's position at the drop less its
position at the run's start: where the slider stands along the track, to within the spring's
stretch. The slider keeps up with the drive on average (over a cycle it advances what the drive
advanced), so the drive's position is its position along the track up to Ft / k, which changes
from slip to slip by one drop's worth; ``cum_slip_m`` (the sum of the global slips' jumps of delta)
misses what the slider advances between them (elements slipping alone, creep), on the paper's model
up to two thirds of each cycle's advance. A lead screw's pitch or a motor's cogging is periodic in
the drive's position itself."""
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


def _stick_durations(drive: DriveProfile, t_prev: FloatArray,
                     t_drop: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Stick durations at the drive velocity of each drop, and the time the stage rested in each
    stick (seconds of hold between ``t_prev`` and ``t_drop``).

    A stick's duration is the stage travel since the previous drop (or the start of motion)
    divided by the velocity at the drop. At constant velocity this is the time between the drops;
    across a velocity step or a hold it measures the loading the stick took, whatever the phase of
    the cycle at the step (the time would jump with it). Falls back to the time when the stage
    rests at the drop."""
    k = drive.segment_index(t_drop)
    v = np.abs(drive.phase_velocity[k])
    # seconds of each drive segment inside each stick (DriveProfile.travel_between, for all)
    within = (np.clip(drive.t_s[1:], t_prev[:, None], t_drop[:, None])
              - np.clip(drive.t_s[:-1], t_prev[:, None], t_drop[:, None]))
    travel = np.sum(np.abs(drive.velocity_m_per_s) * within, axis=1)
    hold = np.sum(within[:, drive.is_hold], axis=1)
    by_time = drive.phase_is_hold[k] | (v <= 0.0) | (travel <= 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        stick: FloatArray = np.where(by_time, t_drop - t_prev, travel / v)
    return stick, hold


def _stick_duration(drive: DriveProfile, t_prev: float, t_drop: float) -> float:
    """:func:`_stick_durations` of one stick."""
    return float(_stick_durations(drive, np.array([t_prev]), np.array([t_drop]))[0][0])


def extract_events(
    t_s: FloatArray,
    ft_N: FloatArray,
    delta_m: FloatArray,
    fn_N: FloatArray,
    drive: DriveProfile,
    settings: ReadSettings,
    slips: SlipIndices | None = None,
    delta_valid: np.ndarray | None = None,
    time_base: TimeBase | None = None,
) -> EventTable:
    """Detect the slips of a record and measure their features (times relative to t_s[0]).

    ``delta_valid`` (per sample, :mod:`rigctl.records.probe_range`): where False a probe was over
    range, and the delta features whose windows include such samples are left NaN (not compared).
    ``time_base``: what is read from ``t_s`` and ``drive`` alone, made once for records sampled on
    the same times (:mod:`rigctl.records.time_base`); one made for other times is not used.

    Steps: detect the slips; refine their drop times; each slip's stick and the windows its
    features are read over (:func:`_windows`); the levels at the drop, the loading ramp and the
    drop's shape read in them (:func:`_read`, compiled: :mod:`rigctl.records.window_reads`); the
    stick durations and the covariates; then the load-change slips left out
    (:func:`_leave_out_load_changes`) and the initial-stage curve.
    """
    if time_base is None or not time_base.fits(t_s, drive):
        time_base = TimeBase.of(t_s, drive)
    t = time_base.t_s
    rec = _Record(time_base, ft_N, delta_m, fn_N, settings, delta_valid)
    if slips is None:
        slips = detect_slips(t, rec.ft_N, rec.delta_m, settings.detection, delta_valid,
                             v_drive_m_s=time_base.v_sliding_m_per_s,
                             v_moving_m_s=time_base.v_moving_m_per_s, fn_N=rec.fn_N,
                             dt_s=rec.dt if t.size > 1 else None,
                             delta_noise_m=rec.sigma_d if delta_valid is None else None)
    n_ev = slips.n
    t_drop = (window_reads.drop_times(t, rec.ft_N, slips.i_peak.astype(np.intp),
                                      slips.i_end.astype(np.intp), slips.sign.astype(np.int64))
              if n_ev else np.zeros(0))
    feats = {name: np.full(n_ev, np.nan) for name in EVENT_FEATURES}
    se = {name: np.full(n_ev, np.nan) for name in SE_FEATURES}
    cov = {name: np.full(n_ev, np.nan) for name in COVARIATES}
    stage = np.ones(n_ev, dtype=np.int8)
    segment = drive.segment_index(t_drop) if n_ev else np.zeros(0, np.intp)
    if n_ev:
        win = _windows(rec, slips, t_drop)
        fn_peak = _read(rec, slips, t_drop, win, feats, se)
        feats["stick_s"], cov["hold_s"] = _stick_durations(drive, win.prev_td, t_drop)
        cov["t_s"] = t_drop.copy()
        cov["cycle"] = np.arange(n_ev, dtype=np.float64)
        cov["fn_N"] = fn_peak
        cov["stick_time_s"] = t_drop - win.prev_td
        cov["ft_N"] = feats["peak_N"].copy()
        cov["dft_dt_N_per_s"] = feats["rate_N_per_s"].copy()
        cov["v_drive_m_per_s"] = np.abs(drive.velocity_at(t_drop))
        slips_m = np.nan_to_num(feats["slip_m"], nan=0.0)
        cov["cum_slip_m"] = np.concatenate([[0.0], np.cumsum(slips_m)[:-1]])
        cov["x_drive_m"] = drive.x_at(t_drop) - float(drive.x_stage_m[0])
        finite = np.isfinite(feats["lag_m"])
        if finite.any():
            feats["lag_m"] = feats["lag_m"] - median(feats["lag_m"][finite])
        _leave_out_load_changes(drive, t_drop, feats)

    init_k = np.full(len(INIT_BANDS), np.nan)
    if n_ev:
        i_m = rec.idx(rec.t_motion)
        f0 = median(ft_N[max(0, i_m - 20) : i_m + 1])
        peak0 = float(feats["peak_N"][0])
        if np.isfinite(peak0) and abs(f0) < 0.1 * abs(peak0):
            stage[0] = 0
            init_k = _initial_curve(ft_N, delta_m, i_m, int(slips.i_peak[0]), peak0, f0,
                                    rec.sigma_f, delta_valid)
    return EventTable(t_drop, segment, stage, feats, cov, init_k, slips.i_peak.copy(), se)


class _Record:
    """One record's signals and what every step of :func:`extract_events` reads from them (times
    relative to the first sample)."""

    def __init__(self, time_base: TimeBase, ft_N: FloatArray, delta_m: FloatArray,
                 fn_N: FloatArray, settings: ReadSettings,
                 delta_valid: np.ndarray | None) -> None:
        self.time_base = time_base
        self.t = time_base.t_s
        drive = time_base.drive
        self.ft_N = np.ascontiguousarray(ft_N, dtype=np.float64)
        self.delta_m = np.ascontiguousarray(delta_m, dtype=np.float64)
        self.fn_N = np.ascontiguousarray(fn_N, dtype=np.float64)
        self.drive, self.settings, self.delta_valid = drive, settings, delta_valid
        self.dt = time_base.dt_s
        self.sigma_f = noise_sigma(ft_N)
        self.sigma_d = noise_sigma(delta_m)
        self.t_motion = drive.motion_start_s()
        self.drop_window = settings.detection.drop_window(self.dt)
        """Samples a drop is read over (as the slip detection reads it)."""

    @property
    def x_drive(self) -> FloatArray:
        """Stage position (simplified drive) at every sample."""
        return self.time_base.x_drive_m

    def idx(self, time: float) -> int:
        """Index of the first sample at or after ``time``."""
        return int(np.searchsorted(self.t, time))

    def indices(self, times: FloatArray) -> np.ndarray:
        """:meth:`idx` of each time."""
        return np.searchsorted(self.t, times)


@dataclass(frozen=True)
class _Windows:
    """Each slip's stick before it and the windows its features are read over (arrays, one entry
    per slip; sample indices into the record)."""

    prev_td: FloatArray
    """Previous drop (the start of motion for the first)."""
    length: FloatArray
    """Loading time up to the drop: from the start of this stick's loading (after the settle
    time, not before the drive's last change)."""
    xs_td: FloatArray
    """Stage position (simplified drive) at the drop."""
    use_x: np.ndarray
    """The settled post-slip line is fitted against the stage position, not time."""
    i_pre0: np.ndarray
    """Pre-drop ramp: from here to the peak."""
    i_post0: np.ndarray
    """Settled post-slip stick: [i_post0, i_post1); empty when the record ends too soon."""
    i_post1: np.ndarray
    i_prev: np.ndarray
    """First sample at or after the previous drop."""
    i_early0: np.ndarray
    """Early loading ramp: [i_early0, i_early1)."""
    i_early1: np.ndarray
    i_end0: np.ndarray
    """Last part of the ramp (rounding): from here to the peak."""
    i_ring0: np.ndarray
    """Ringing read: [i_ring0, i_post0)."""


def _windows(rec: _Record, slips: SlipIndices, t_drop: FloatArray) -> _Windows:
    """The windows of every slip, from the drop times and the drive."""
    t, drive, dt, td = rec.t, rec.drive, rec.dt, t_drop
    settle = rec.settings.settle_s
    n_ev = td.shape[0]
    # the last slip's settled level needs at least half a typical cycle of record after it
    min_tail = 0.5 * median(np.diff(td)) if n_ev >= 3 else 0.3
    prev_td = np.concatenate([[rec.t_motion], td[:-1]])
    start = np.concatenate([[rec.t_motion], td[:-1] + settle])
    k_td = drive.segment_index(td)
    a_load = np.maximum(start, drive.t_s[drive.phase_knots[k_td]])
    nxt = np.concatenate([td[1:], [float(t[-1])]])
    after_len = np.minimum(0.4 * (nxt - td - settle), 1.0)
    if nxt[-1] - td[-1] - settle < min_tail:
        after_len[-1] = 0.0  # the record ends before the stick after the last slip is seen
    length = td - a_load
    pre_len = np.where(length > 0, np.minimum(0.15 * length, 0.3), 0.0)
    i_post0, i_post1 = rec.indices(td + settle), rec.indices(td + settle + after_len)
    # the settled post-slip line is read against the stage position when the stage changes
    # velocity inside the window (stick loading is linear in stage travel, not in time), and
    # up to the change when it stops or reverses there: a line in time across a velocity step
    # would bend the extrapolated trough by where in the cycle the step fell
    use_x = np.zeros(n_ev, dtype=np.bool_)
    crosses = i_post1 > i_post0
    crosses[crosses] = drive.segment_index(t[i_post1[crosses] - 1]) != k_td[crosses]
    for j in np.flatnonzero(crosses):
        if drive.steady_slide_between(float(td[j]), float(t[i_post1[j] - 1])):
            use_x[j] = True
        else:
            i_post1[j] = min(int(i_post1[j]), int(rec.idx(drive.phase_end(float(td[j])))))
    return _Windows(
        prev_td=prev_td, length=length,
        # the stage from the simplified drive (the encoder's quantisation steps would otherwise
        # show as a slow sawtooth in the lag)
        xs_td=drive.x_at(td), use_x=use_x,
        i_pre0=rec.indices(td - np.maximum(pre_len, 8 * dt)), i_post0=i_post0, i_post1=i_post1,
        i_prev=rec.indices(prev_td), i_early0=rec.indices(a_load + 0.1 * length),
        i_early1=rec.indices(a_load + 0.6 * length), i_end0=rec.indices(td - 0.15 * length),
        i_ring0=rec.indices(td + dt))


_ALL_VALID = np.zeros(0, dtype=np.bool_)
_COLUMNS = {"peak_N": window_reads.PEAK, "trough_N": window_reads.TROUGH,
            "drop_N": window_reads.DROP, "slip_m": window_reads.SLIP,
            "drop_delay_s": window_reads.DELAY, "fn_swing_N": window_reads.FN_SWING,
            "lag_m": window_reads.LAG, "rate_N_per_s": window_reads.RATE,
            "rounding": window_reads.ROUNDING, "k_stick_N_per_m": window_reads.K_STICK,
            "ring_N": window_reads.RING, "step_frac": window_reads.STEP_FRAC}
_SE_COLUMNS = {"rate_N_per_s": window_reads.SE_RATE, "rounding": window_reads.SE_ROUNDING,
               "k_stick_N_per_m": window_reads.SE_K}


def _read(rec: _Record, slips: SlipIndices, t_drop: FloatArray, win: _Windows,
          feats: dict[str, FloatArray], se: dict[str, FloatArray]) -> FloatArray:
    """Levels at each drop (line fits over the pre-drop ramp and the settled post-slip stick),
    the loading ramp (early rate, K(i), rounding, their standard errors) and the drop's shape
    (ringing about the settled line, sharpness), read by :func:`window_reads.read_windows`;
    returns Fn at each drop."""
    valid = (_ALL_VALID if rec.delta_valid is None
             else np.ascontiguousarray(rec.delta_valid, dtype=np.bool_))
    out = window_reads.read_windows(
        rec.t, rec.ft_N, rec.delta_m, rec.fn_N, valid,
        rec.x_drive if win.use_x.any() else rec.t, slips.i_peak.astype(np.intp),
        slips.sign.astype(np.int64), t_drop, win.use_x, win.xs_td,
        win.i_pre0, win.i_post0, win.i_post1, win.i_prev, win.length, win.i_early0,
        win.i_early1, win.i_end0, win.i_ring0, rec.dt, rec.sigma_f, rec.sigma_d,
        rec.drop_window)
    for name, col in _COLUMNS.items():
        feats[name] = out[:, col].copy()
    for name, col in _SE_COLUMNS.items():
        se[name] = out[:, col].copy()
    fn_peak: FloatArray = out[:, window_reads.FN_PEAK].copy()
    return fn_peak


def _leave_out_load_changes(drive: DriveProfile, t_drop: FloatArray,
                            feats: dict[str, FloatArray]) -> None:
    """Slips set off by a change of the normal load (a release under tangential load, a
    re-loading) are not stick-slip cycles: they are paired, but not compared (features NaN)."""
    fn_a = drive.fn_at(np.clip(t_drop - LOAD_CHANGE_WINDOW_S, 0.0, None))
    fn_b = drive.fn_at(t_drop + LOAD_CHANGE_WINDOW_S)
    changing = np.abs(fn_b - fn_a) > LOAD_CHANGE_FRACTION * np.maximum(fn_a, fn_b)
    for name in feats:
        feats[name][changing] = np.nan


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
    g = f - f0
    for b, (lo, hi) in enumerate(INIT_BANDS):
        sel = (g >= lo * span) & (g <= hi * span) if span > 0 else \
            (g <= lo * span) & (g >= hi * span)
        if np.count_nonzero(sel) < 5 or float(np.ptp(f[sel])) < 6.0 * sigma or not ok[sel].all():
            continue
        c = regress_slope(f[sel], d[sel])
        if np.isfinite(c) and c != 0.0:
            out[b] = 1.0 / c
    return out
