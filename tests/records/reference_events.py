"""The slip detector and feature reader as they were before they were compiled: the test oracle.

A frozen copy of ``rigctl/records/events.py`` (``detect_slips`` and its rules) and
``rigctl/records/features.py`` (``extract_events`` and its per-slip reads) at the commit before
the scan and the window reads moved into numba (:mod:`rigctl.records.slip_scan`,
:mod:`rigctl.records.window_reads`). tests/records/test_compiled_reading.py reads many records with
both and requires the same slips and the same features to rounding. Not used by rigctl itself: do
not change it to follow the library (that would test the library against itself).
"""

# ruff: noqa
# mypy: ignore-errors
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rigctl.records.drive_profile import DriveProfile
from rigctl.records.events import DetectionSettings, SlipIndices
from rigctl.records.feature_info import EVENT_FEATURES, SE_FEATURES
from rigctl.records.features import COVARIATES, INIT_BANDS, EventTable, ReadSettings
from rigctl.records.signals import (
    FloatArray, line_fit, noise_sigma, regress_slope, sliding_extreme, slope_se,
)

MAX_NOISE_SHARE = 0.1
DELAY_MIN_SLIP_NOISE = 10.0


def detect_slips(
    t_s: FloatArray,
    ft_N: FloatArray,
    delta_m: FloatArray | None,
    settings: DetectionSettings,
    delta_valid: np.ndarray | None = None,
    v_drive_m_s: FloatArray | None = None,
    fn_N: FloatArray | None = None,
) -> SlipIndices:
    """Find slip events in a force record (see the module docstring).

    Where ``delta_valid`` is False (a probe over range) delta cannot confirm a small drop, which is
    then judged by the force alone. ``v_drive_m_s`` (the stage velocity per sample, e.g. from the
    simplified drive) rejects drops while the stage moves against the force (stroke reversals),
    except where ``fn_N`` changes over the drop (a release of the normal load, which the
    workbench pairs as such: :mod:`rigctl.records.features`).
    """
    n = ft_N.shape[0]
    empty = SlipIndices(np.zeros(0, np.intp), np.zeros(0, np.intp), np.zeros(0, np.int8))
    if n < 8:
        return empty
    dt = float(np.median(np.diff(t_s)))
    w = settings.drop_window(dt)
    gap = max(w + 1, round(settings.merge_gap_s / dt))
    thr = settings.threshold_N
    fwd_min = sliding_extreme(ft_N, w, "min")
    fwd_max = sliding_extreme(ft_N, w, "max")
    sign = np.sign(ft_N)
    drop = np.where(sign > 0, ft_N - fwd_min, fwd_max - ft_N)
    cand = np.flatnonzero((drop > thr) & (np.abs(ft_N) > thr))
    if cand.size == 0:
        return empty
    breaks = np.flatnonzero(np.diff(cand) > gap) + 1
    clusters = split_ring_chains(np.split(cand, breaks), ft_N, w, gap)
    d_sigma, d_informative = 0.0, False
    if delta_m is not None:
        d_ok = _in_range(delta_m, delta_valid)
        d_sigma = max(noise_sigma(d_ok), settings.delta_sigma_m)
        d_informative = d_ok.size > 0 and float(np.ptp(d_ok)) > 20.0 * d_sigma
    v_ref = 0.0
    if v_drive_m_s is not None:
        moving = np.abs(v_drive_m_s[v_drive_m_s != 0.0])
        v_ref = float(np.median(moving)) if moving.size else 0.0
    peaks: list[int] = []
    ends: list[int] = []
    signs: list[int] = []
    prev_size = 0.0
    for c in clusters:
        c0, c1 = int(c[0]), int(c[-1])
        s = int(sign[c0])
        i_end = min(c1 + w, n - 1)
        seg = s * ft_N[c0 : min(c0 + w + 2, n)]
        # the peak is the last sample before the first clear one-sample fall (under noise the
        # highest sample may sit a few samples early); else the highest sample
        size_est = _run_size(c, ft_N, w, n)
        falls = np.flatnonzero(seg[:-1] - seg[1:] > max(0.5 * thr, 0.1 * size_est))
        i_pk = c0 + int(falls[0]) if falls.size else c0 + int(np.argmax(seg))
        if i_pk > i_end:
            # a lone candidate whose force is highest after its drop window: it rises on, no slip
            continue
        size = s * ft_N[i_pk] - float(np.min(s * ft_N[i_pk : i_end + 1]))
        if size <= thr:
            continue
        if (peaks and signs[-1] == s
                and is_ring_swing(s * ft_N, w, peaks[-1], prev_size, i_pk, i_end, size)):
            continue
        if (v_drive_m_s is not None and _against_the_force(v_drive_m_s, i_pk, i_end, s, v_ref)
                and not _load_changes(fn_N, i_pk - gap, i_end + gap)):
            continue
        if (size < settings.confirm_factor * thr and d_informative and delta_m is not None
                and (delta_valid is None
                     or delta_valid[max(0, i_pk - w) : min(n, i_end + gap)].all())):
            before = float(np.median(delta_m[max(0, i_pk - w) : i_pk + 1]))
            after = float(np.median(delta_m[i_end : min(n, i_end + gap)]))
            if s * (after - before) <= 3.0 * d_sigma:
                continue
        peaks.append(i_pk)
        ends.append(i_end)
        signs.append(s)
        prev_size = size
    return SlipIndices(
        np.array(peaks, dtype=np.intp), np.array(ends, dtype=np.intp), np.array(signs, np.int8)
    )


LONG_CHAIN_GAPS = 5
"""A cluster of drops longer than this many merge gaps is a chain of ring swings (swings closer
than the merge gap, ringing on above the threshold) that may hold the next slip."""
CHAIN_GROWTH = 1.5
"""In a chain, a drop this much larger than the one before it is not a swing of a decaying
ringing."""


def split_ring_chains(clusters: list[np.ndarray], ft_N: FloatArray, w: int,
                      gap: int) -> list[np.ndarray]:
    """Clusters of drop candidates, with every long chain cut before each slip in it.

    A lightly damped slider ringing faster than the merge gap, above the threshold until the next
    slip (a light slider, a low noise floor), chains every swing and that slip into one cluster,
    and the slip would be lost. A long cluster (over LONG_CHAIN_GAPS merge gaps) is cut into runs
    of consecutive drops (no gap larger than the drop window). A run starts a new slip when its
    drop exceeds RING_SIZE_FRACTION of the slip that opened its part of the chain and
    CHAIN_GROWTH times the run before it (a free oscillation's swings only shrink); the others
    stay with that slip. Where the chain opens with drops under RING_SIZE_FRACTION of a later one
    (the tail of an earlier ringing, a noise dip on the ramp), that later one is its slip, not a
    new one: the cluster reads as before.
    """
    out: list[np.ndarray] = []
    n = ft_N.shape[0]
    for c in clusters:
        if c.size == 0 or int(c[-1] - c[0]) <= LONG_CHAIN_GAPS * gap:
            out.append(c)
            continue
        runs = np.split(c, np.flatnonzero(np.diff(c) > w + 1) + 1)
        current = [runs[0]]
        opened = last = _run_size(runs[0], ft_N, w, n)
        for run in runs[1:]:
            size = _run_size(run, ft_N, w, n)
            if opened < RING_SIZE_FRACTION * size:
                current.append(run)
                opened = size
            elif size > RING_SIZE_FRACTION * opened and size > CHAIN_GROWTH * last:
                out.append(np.concatenate(current))
                current, opened = [run], size
            else:
                current.append(run)
            last = size
        out.append(np.concatenate(current))
    return out


def _run_size(run: np.ndarray, ft_N: FloatArray, w: int, n: int) -> float:
    """Force fall of a run of drop candidates in the direction of loading: the highest of its
    first samples down to the lowest until a drop window after it."""
    s = 1.0 if ft_N[int(run[0])] >= 0 else -1.0
    i0, i1 = int(run[0]), min(int(run[-1]) + w + 1, n)
    return float(np.max(s * ft_N[i0 : min(i0 + w + 2, n)]) - np.min(s * ft_N[i0:i1]))


def _in_range(delta_m: FloatArray, delta_valid: np.ndarray | None) -> FloatArray:
    """Delta where the probes were in range (all of it where no mask is given)."""
    return delta_m if delta_valid is None else delta_m[delta_valid]


RING_SIZE_FRACTION = 0.5
"""A ring swing is at most this fraction of the slip that set it ringing."""
RING_RISE_RANGE = (0.5, 3.0)
"""Just before a ring swing falls, the force rose by about as much as it then falls (a sinusoid's
halves are equal); before a slip it rose far less in the same time (the stick loading rate), or
far more (a stroke reversal loading the contact from the other side)."""
RING_LOOK_BACK = 3
"""The rise is read within this many times the drop's fall (peak to lowest sample, plus the
drop window) before its peak."""
RING_LOW_QUANTILE = 0.1
"""The level the force rose from: this quantile of the look-back (single-sample spikes of a
record do not count as a trough)."""
RING_RETURN = 0.75
"""After a swing the force comes back up: its median over the look-back after the drop lies
less than this fraction of the drop below the peak (about half way: the oscillation's centre),
where after a slip it stays down at the trough."""
RING_SPAN_OVER_ELAPSED = 0.5
"""The look-back is a small part of the time since the slip (several swings fit in it); in a
near-harmonic stick-slip each cycle is a single swing."""


def is_ring_swing(f: FloatArray, w: int, i_prev_peak: int, prev_size: float, i_pk: int,
                  i_end: int, size: float) -> bool:
    """A drop of ``size`` from ``i_pk`` to ``i_end`` is a swing of the ringing of the previous
    slip (peak at ``i_prev_peak``, drop ``prev_size``); ``f`` is the force in the direction of
    loading and ``w`` the drop window in samples.

    A decaying oscillation about the post-slip line has four features a slip lacks together:
    its swings are small against the slip that excited it (a free oscillation loses energy),
    the force rose just before each swing by about as much as it then falls, within a few fall
    times (a sinusoid's halves are equal, where a slip ends a stick ramp rising at the loading
    rate), it comes back up after the swing (where a slip leaves it at the trough), and several
    swings fit in the time since that slip. A slip of a near-harmonic stick-slip, a slip of
    comparable size, a slip after a stroke reversal and a slow slip starting at a spike each fail
    one.
    """
    if size > RING_SIZE_FRACTION * prev_size:
        return False
    i_min = i_pk + int(np.argmin(f[i_pk : i_end + 1]))
    look = RING_LOOK_BACK * (i_min - i_pk + w)
    if look > RING_SPAN_OVER_ELAPSED * (i_pk - i_prev_peak):
        return False
    before = f[max(i_pk - look, i_prev_peak) : i_pk]
    if before.size == 0:
        return False
    rise = f[i_pk] - float(np.quantile(before, RING_LOW_QUANTILE))
    lo, hi = RING_RISE_RANGE
    if not lo * size <= rise <= hi * size:
        return False
    after = f[i_end : i_end + look]
    return after.size > 0 and float(np.median(after)) > f[i_pk] - RING_RETURN * size


AGAINST_FRACTION = 0.1
"""A drop is an unloading when the stage moves against the force faster than this fraction of the
record's typical drive speed (a stage at rest, or a phase line drifting by its noise, is not)."""


def _against_the_force(v_drive_m_s: FloatArray, i_pk: int, i_end: int, sign: int,
                       v_ref: float) -> bool:
    """The stage moves against the force over the drop: an unloading by a stroke reversal (a slip
    happens while the drive pushes the way the force points)."""
    v = sign * v_drive_m_s[i_pk : i_end + 1]
    return bool(v.size) and float(np.mean(v)) < -AGAINST_FRACTION * v_ref


LOAD_CHANGE = 0.25
"""Relative change of Fn around a drop that makes it a load change (as the release rule of
:mod:`rigctl.records.features`), not a stroke reversal."""


def _load_changes(fn_N: FloatArray | None, i0: int, i1: int) -> bool:
    if fn_N is None:
        return False
    seg = np.abs(fn_N[max(i0, 0) : max(i1, 0) + 1])
    if seg.size == 0:
        return False
    top = float(np.max(seg))
    return top > 0.0 and float(np.max(seg) - np.min(seg)) > LOAD_CHANGE * top


LOAD_CHANGE_WINDOW_S = 0.25
LOAD_CHANGE_FRACTION = 0.25
"""A slip where the drive's normal force changes by more than this fraction within
+-LOAD_CHANGE_WINDOW_S is a load-change slip (release, re-loading): its features are not compared.
Normal-force swings of the slips themselves (normal coupling, a few %) stay well below."""


def _crossing_time(t: FloatArray, y: FloatArray, i0: int, i1: int, level: float,
                   rising: bool) -> float:
    """First time in samples [i0, i1) at which ``y`` reaches ``level`` going up (``rising``) or
    down, linearly interpolated between samples; NaN where ``y`` is there at ``i0`` already or
    never gets there."""
    seg = (1.0 if rising else -1.0) * (y[i0:i1] - level)
    past = np.flatnonzero(seg >= 0.0)
    if past.size == 0 or past[0] == 0:
        return math.nan
    k = int(past[0])
    y0, y1 = float(seg[k - 1]), float(seg[k])
    t0, t1 = float(t[i0 + k - 1]), float(t[i0 + k])
    return t0 + (-y0) / (y1 - y0) * (t1 - t0)


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

    ``delta_valid`` (per sample, :mod:`rigctl.records.probe_range`): where False a probe was over
    range, and the delta features whose windows include such samples are left NaN (not compared).

    Steps: detect the slips; refine their drop times; per slip, its stick window
    (:func:`_cycle_window`), the levels at the drop (:func:`_levels_at_drop`), the loading ramp
    (:func:`_loading_ramp`), the drop's shape (:func:`_drop_shape`) and its covariates; then the
    run-wide covariates, the load-change slips left out (:func:`_leave_out_load_changes`) and the
    initial-stage curve.
    """
    t = t_s - t_s[0]
    if slips is None:
        slips = detect_slips(t, ft_N, delta_m, settings.detection, delta_valid,
                             v_drive_m_s=drive.sliding_velocity_at(t), fn_N=fn_N)
    rec = _Record(t, ft_N, delta_m, fn_N, drive, settings, delta_valid)
    n_ev = slips.n
    t_drop = _drop_times(rec, slips)
    feats = {name: np.full(n_ev, np.nan) for name in EVENT_FEATURES}
    se = {name: np.full(n_ev, np.nan) for name in SE_FEATURES}
    cov = {name: np.full(n_ev, np.nan) for name in COVARIATES}
    stage = np.ones(n_ev, dtype=np.int8)
    segment = drive.segment_index(t_drop) if n_ev else np.zeros(0, np.intp)
    # the last slip's settled level needs at least half a typical cycle of record after it
    min_tail = 0.5 * float(np.median(np.diff(t_drop))) if n_ev >= 3 else 0.3
    for j in range(n_ev):
        cyc = _cycle_window(rec, slips, t_drop, j, min_tail)
        lv = _levels_at_drop(rec, cyc, j, feats)
        _loading_ramp(rec, cyc, j, feats, se)
        _drop_shape(rec, cyc, lv, j, feats)
        cov["t_s"][j] = cyc.td
        cov["cycle"][j] = j
        cov["fn_N"][j] = lv.fn_pk
        cov["hold_s"][j] = drive.hold_time_between(cyc.prev_td, cyc.td)
        cov["stick_time_s"][j] = cyc.td - cyc.prev_td
        cov["ft_N"][j] = lv.peak
        cov["dft_dt_N_per_s"][j] = feats["rate_N_per_s"][j]
    if n_ev:
        cov["v_drive_m_per_s"] = np.abs(drive.velocity_at(t_drop))
        slips_m = np.nan_to_num(feats["slip_m"], nan=0.0)
        cov["cum_slip_m"] = np.concatenate([[0.0], np.cumsum(slips_m)[:-1]])
        cov["x_drive_m"] = drive.x_at(t_drop) - float(drive.x_stage_m[0])
        finite = np.isfinite(feats["lag_m"])
        if finite.any():
            feats["lag_m"] = feats["lag_m"] - float(np.median(feats["lag_m"][finite]))
        _leave_out_load_changes(drive, t_drop, feats)

    init_k = np.full(len(INIT_BANDS), np.nan)
    if n_ev:
        i_m = rec.idx(rec.t_motion)
        f0 = float(np.median(ft_N[max(0, i_m - 20) : i_m + 1]))
        peak0 = float(feats["peak_N"][0])
        if np.isfinite(peak0) and abs(f0) < 0.1 * abs(peak0):
            stage[0] = 0
            init_k = _initial_curve(ft_N, delta_m, i_m, int(slips.i_peak[0]), peak0, f0,
                                    rec.sigma_f, delta_valid)
    return EventTable(t_drop, segment, stage, feats, cov, init_k, slips.i_peak.copy(), se)


class _Record:
    """One record's signals and what every step of :func:`extract_events` reads from them (times
    relative to the first sample)."""

    def __init__(self, t: FloatArray, ft_N: FloatArray, delta_m: FloatArray, fn_N: FloatArray,
                 drive: DriveProfile, settings: ReadSettings,
                 delta_valid: np.ndarray | None) -> None:
        self.t, self.ft_N, self.delta_m, self.fn_N = t, ft_N, delta_m, fn_N
        self.drive, self.settings, self.delta_valid = drive, settings, delta_valid
        self.dt = float(np.median(np.diff(t))) if t.size > 1 else 1.0
        self.sigma_f = noise_sigma(ft_N)
        self.sigma_d = noise_sigma(delta_m)
        self.t_motion = drive.motion_start_s()
        self.x_drive = drive.x_at(t)
        self.drop_window = settings.detection.drop_window(self.dt)
        """Samples a drop is read over (as the slip detection reads it)."""

    def idx(self, time: float) -> int:
        """Index of the first sample at or after ``time``."""
        return int(np.searchsorted(self.t, time))

    def d_ok(self, i0: int, i1: int) -> bool:
        """Whether delta is within the probes' range over samples [i0, i1)."""
        return self.delta_valid is None or bool(self.delta_valid[max(i0, 0) : max(i1, 0)].all())


@dataclass(frozen=True)
class _Cycle:
    """One slip and the stick before it: the windows its features are read over."""

    td: float
    """Drop time."""
    prev_td: float
    """Previous drop (the start of motion for the first)."""
    a_load: float
    """Start of this stick's loading (after the settle time, not before the drive's last change)."""
    length: float
    """Loading time up to the drop."""
    after_len: float
    """Length of the settled post-slip window (0 when the record ends too soon after the slip)."""
    i_pk: int
    sign: int


def _drop_times(rec: _Record, slips: SlipIndices) -> FloatArray:
    """Each slip's drop time: where Ft crosses half-way down its fall, refined between samples."""
    t_drop = np.empty(slips.n)
    for j in range(slips.n):
        i_pk, i_end, s = int(slips.i_peak[j]), int(slips.i_end[j]), int(slips.sign[j])
        size0 = s * rec.ft_N[i_pk] - float(np.min(s * rec.ft_N[i_pk : i_end + 1]))
        level = rec.ft_N[i_pk] - s * 0.5 * size0
        crossing = _crossing_time(rec.t, rec.ft_N, i_pk, i_end + 1, level, rising=s < 0)
        t_drop[j] = crossing if math.isfinite(crossing) else float(rec.t[i_pk])
    return t_drop


def _cycle_window(rec: _Record, slips: SlipIndices, t_drop: FloatArray, j: int,
                  min_tail: float) -> _Cycle:
    """The stick before slip ``j`` and the post-slip window after it."""
    settle = rec.settings.settle_s
    td = float(t_drop[j])
    prev_td = float(t_drop[j - 1]) if j > 0 else rec.t_motion
    a = prev_td + settle if j > 0 else rec.t_motion
    a_load = max(a, rec.drive.last_change_before(td))
    n_ev = t_drop.shape[0]
    nxt = float(t_drop[j + 1]) if j + 1 < n_ev else float(rec.t[-1])
    after_len = min(0.4 * (nxt - td - settle), 1.0)
    if j + 1 == n_ev and nxt - td - settle < min_tail:
        after_len = 0.0  # the record ends before the stick after the last slip is seen
    return _Cycle(td, prev_td, a_load, td - a_load, after_len, int(slips.i_peak[j]),
                  int(slips.sign[j]))


@dataclass(frozen=True)
class _Levels:
    """Levels at a drop and the settled post-slip line they were read from."""

    peak: float
    trough: float
    slope_after: float
    post_axis: FloatArray
    """What the post-slip line is a line in: time, or the stage position across a velocity change."""
    post_at: float
    """The drop on ``post_axis``."""
    fn_pk: float


def _levels_at_drop(rec: _Record, cyc: _Cycle, j: int, feats: dict[str, FloatArray]) -> _Levels:
    """Peak, trough, drop, stick duration, slip distance, normal-force swing and lag of slip ``j``:
    line fits over the pre-drop ramp and the settled post-slip stick, evaluated at the drop."""
    t, dt, drive, td = rec.t, rec.dt, rec.drive, cyc.td
    settle = rec.settings.settle_s
    pre_len = min(0.15 * cyc.length, 0.3) if cyc.length > 0 else 0.0
    i_pre0, i_pre1 = rec.idx(td - max(pre_len, 8 * dt)), cyc.i_pk + 1
    i_post0, i_post1 = rec.idx(td + settle), rec.idx(td + settle + cyc.after_len)
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
            post_axis, post_at = rec.x_drive, xs_td
        else:
            i_post1 = min(i_post1, rec.idx(drive.phase_end(td)))
    peak, _ = line_fit(t, rec.ft_N, i_pre0, i_pre1, td)
    trough, slope_after = line_fit(post_axis, rec.ft_N, i_post0, i_post1, post_at)
    d_pk, _ = line_fit(t, rec.delta_m, i_pre0, i_pre1, td)
    d_after, _ = line_fit(post_axis, rec.delta_m, i_post0, i_post1, post_at)
    fn_pk, _ = line_fit(t, rec.fn_N, i_pre0, i_pre1, td)
    fn_after, _ = line_fit(post_axis, rec.fn_N, i_post0, i_post1, post_at)
    s = cyc.sign
    feats["peak_N"][j] = peak
    feats["trough_N"][j] = trough
    feats["drop_N"][j] = s * (peak - trough)
    feats["stick_s"][j] = _stick_duration(drive, cyc.prev_td, td)
    if rec.d_ok(i_pre0, i_pre1) and rec.d_ok(i_post0, i_post1):
        feats["slip_m"][j] = s * (d_after - d_pk)
        if abs(d_after - d_pk) > DELAY_MIN_SLIP_NOISE * rec.sigma_d:
            # half-way between the settled line levels, not from the peak sample: the time then
            # moves continuously with the signal instead of with the sampling phase
            i0 = max(cyc.i_pk - rec.drop_window, rec.idx(cyc.prev_td) + 1, 1)
            if rec.d_ok(i0, i_post0):
                feats["drop_delay_s"][j] = (
                    _crossing_time(t, rec.ft_N, i0, i_post0, 0.5 * (peak + trough), trough > peak)
                    - _crossing_time(t, rec.delta_m, i0, i_post0, 0.5 * (d_pk + d_after),
                                     d_after > d_pk))
    feats["fn_swing_N"][j] = fn_pk - fn_after
    if rec.d_ok(i_pre0, i_pre1):
        feats["lag_m"][j] = xs_td - d_pk
    return _Levels(peak, trough, slope_after, post_axis, post_at, fn_pk)


def _loading_ramp(rec: _Record, cyc: _Cycle, j: int, feats: dict[str, FloatArray],
                  se: dict[str, FloatArray]) -> None:
    """Early loading rate, K(i) and rounding of the stick before slip ``j``, with their standard
    errors (nothing for a stick shorter than 20 samples)."""
    t, dt, length, td, s = rec.t, rec.dt, cyc.length, cyc.td, cyc.sign
    if not length > 20 * dt:
        return
    i_e0, i_e1 = rec.idx(cyc.a_load + 0.1 * length), rec.idx(cyc.a_load + 0.6 * length)
    i_n0 = rec.idx(td - 0.15 * length)
    _, rate = line_fit(t, rec.ft_N, i_e0, i_e1, td)
    _, rate_end = line_fit(t, rec.ft_N, i_n0, cyc.i_pk + 1, td)
    feats["rate_N_per_s"][j] = s * rate
    t_seg = t[i_e0:i_e1]
    se_rate = slope_se(t_seg, rec.sigma_f)
    se_end = slope_se(t[i_n0 : cyc.i_pk + 1], rec.sigma_f)
    if rate != 0.0 and np.isfinite(rate):
        feats["rounding"][j] = rate_end / rate
        se["rate_N_per_s"][j] = se_rate / abs(rate)
        se["rounding"][j] = math.hypot(se_end, abs(rate_end) * se_rate / abs(rate)) / abs(rate)
    f_seg = rec.ft_N[i_e0:i_e1]
    # K(i) is read only where the window's force range stands well above the force noise: the
    # share of Ft's variance that is noise (1 - reliability ratio; Fuller, Measurement Error
    # Models, 1987, Sec. 1.1) at most MAX_NOISE_SHARE
    var_f = float(np.var(f_seg)) if f_seg.size > 3 else 0.0
    reliability = 1.0 - rec.sigma_f**2 / var_f if var_f > 0.0 else 0.0
    if f_seg.size > 3 and reliability >= 1.0 - MAX_NOISE_SHARE and rec.d_ok(i_e0, i_e1):
        # dFt/d(delta) as the ratio of the two slopes in time. Regressing delta on Ft instead
        # would mix in a post-slip ringing that has not died out: in it Ft and delta swing in
        # opposition on the drive spring (dFt = -K0 d(delta)), and a slowly decaying ringing
        # (a light, lightly damped slider) read the stiffness several times too high. A line in
        # time averages the ringing out over the window's cycles; noise in either channel only
        # adds scatter (the slopes' standard errors), no bias of first order
        _, rate_d = line_fit(t, rec.delta_m, i_e0, i_e1, td)
        k_i = rate / rate_d if rate_d != 0.0 else math.nan
        if np.isfinite(k_i) and k_i > 0.0:
            feats["k_stick_N_per_m"][j] = k_i
            se["k_stick_N_per_m"][j] = k_i * math.hypot(
                se_rate / abs(rate), slope_se(t_seg, rec.sigma_d) / abs(rate_d))


def _drop_shape(rec: _Record, cyc: _Cycle, lv: _Levels, j: int,
                feats: dict[str, FloatArray]) -> None:
    """Ringing about the settled line after slip ``j`` and the drop's sharpness."""
    drop = feats["drop_N"][j]
    if not (np.isfinite(lv.trough) and np.isfinite(drop) and drop > 0):
        return
    t, dt, td, ft = rec.t, rec.dt, cyc.td, rec.ft_N
    i_r0, i_r1 = rec.idx(td + dt), rec.idx(td + rec.settings.settle_s)
    if i_r1 - i_r0 >= 4 and np.isfinite(lv.slope_after):
        tr = t[i_r0:i_r1]
        dev = ft[i_r0:i_r1] - (lv.trough + lv.slope_after * (lv.post_axis[i_r0:i_r1] - lv.post_at))
        # weights ramp up over one sample from td + 1.5 dt, so the window start moves
        # continuously with the drop time instead of jumping a whole sample
        wgt = np.clip((tr - td - 1.5 * dt) / dt, 0.0, 1.0)
        ms = float(wgt @ dev**2) / max(float(wgt.sum()), 1e-12)
        feats["ring_N"][j] = float(np.sqrt(max(ms - rec.sigma_f**2, 0.0)))
    w = rec.drop_window
    n, i_pk, s = t.shape[0], cyc.i_pk, cyc.sign
    falls = s * (ft[i_pk : min(i_pk + w, n - 1)] - ft[i_pk + 1 : min(i_pk + w + 1, n)])
    if falls.size:
        feats["step_frac"][j] = float(np.max(falls)) / drop


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
    for b, (lo, hi) in enumerate(INIT_BANDS):
        sel = (f - f0 >= lo * span) & (f - f0 <= hi * span) if span > 0 else \
            (f - f0 <= lo * span) & (f - f0 >= hi * span)
        if np.count_nonzero(sel) < 5 or float(np.ptp(f[sel])) < 6.0 * sigma or not ok[sel].all():
            continue
        c = regress_slope(f[sel], d[sel])
        if np.isfinite(c) and c != 0.0:
            out[b] = 1.0 / c
    return out
