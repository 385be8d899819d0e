"""The drive a measured run applied: stage position and normal force as a few straight segments.

The model is simulated on each run's measured stage position and normal force (docs/reading-records.md,
"Reading a record", "Drive"). Feeding every noisy, quantised sample as a knot would make the model
integrate sensor noise and run slowly, so both histories are simplified to piecewise-linear curves:

1. knots by Douglas-Peucker splitting (Douglas & Peucker, Cartographica 10, 1973) with a tolerance
   of a few noise RMS / quantisation steps (stage) or of 3 % of the load (normal force; a commanded
   load changes by more, while the sensor noise and the small load swings a tilted frame makes at
   each slip - the ``normal_coupling`` signature the workbench must still see - are smaller);
2. each corner's time refined to where the straight lines fitted to its two neighbouring segments
   meet (Douglas-Peucker puts a knot on a sample, and noise moves it by several samples: at a
   velocity step of 20 um/s, 8 ms is 0.16 um of stage, three times the probe's event-to-event
   scatter; the model would then see a drive the measurement never had); a sharp corner that
   Douglas-Peucker cut with two knots becomes one;
3. the knot values by a continuous piecewise-linear least-squares fit through all samples, so a
   segment is as accurate as the average of its samples, not of its two end samples.

The segments also give the covariates of the protocol: drive velocity, holds (stage at rest) and the
motion start that opens the initial stage.
"""

from __future__ import annotations

import heapq
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from rigctl.data import DataError, MeasuredRun
from rigctl.records.fn_coupling import applied_normal_force
from rigctl.records.signals import FloatArray, noise_sigma

HOLD_VELOCITY_FRACTION = 0.002
"""A segment whose speed is below this fraction of the run's sliding speed (``reference_speed``) is
a hold (velocity steps span two decades, so a slow step of 1 % of the fastest must stay a slide);
so is a segment over which the stage moves less than the simplification tolerance (set exactly at
rest)."""


@dataclass(frozen=True)
class DriveProfile:
    """Piecewise-linear stage position and normal force of one run (times relative to t_s[0])."""

    t_s: FloatArray
    x_stage_m: FloatArray
    fn_N: FloatArray
    t0_s: float
    """Absolute time of the run's first sample (the profile's t = 0)."""
    fn_per_ft: float = 0.0
    """dFn/dFt taken out of the measured normal force (:mod:`rigctl.records.fn_coupling`; 0: none)."""

    @property
    def velocity_m_per_s(self) -> FloatArray:
        """Stage velocity of each segment (len = knots - 1)."""
        out: FloatArray = np.diff(self.x_stage_m) / np.diff(self.t_s)
        return out

    @cached_property
    def is_hold(self) -> np.ndarray:
        """True for segments where the stage rests (computed once: the profile does not change)."""
        v = np.abs(self.velocity_m_per_s)
        v_ref = reference_speed(v, np.diff(self.t_s))
        return np.asarray((v == 0.0) | (v <= HOLD_VELOCITY_FRACTION * v_ref))

    def knot_index(self, t_rel_s: FloatArray) -> np.ndarray:
        """Index of the straight piece of the drive (between two knots) holding each time."""
        idx = np.searchsorted(self.t_s, t_rel_s, side="right") - 1
        return np.clip(idx, 0, self.t_s.shape[0] - 2)

    @cached_property
    def phase_knots(self) -> np.ndarray:
        """Knot indices where the protocol's phases begin, and the last knot (see _phases)."""
        return _phases(self)

    def segment_index(self, t_rel_s: FloatArray) -> np.ndarray:
        """Index of the protocol phase (constant velocity and load, or a hold) holding each time."""
        starts = self.t_s[self.phase_knots[:-1]]
        idx = np.searchsorted(starts, t_rel_s, side="right") - 1
        return np.clip(idx, 0, starts.shape[0] - 1)

    @cached_property
    def phase_velocity(self) -> FloatArray:
        """Mean stage velocity of each phase."""
        k = self.phase_knots
        out: FloatArray = np.diff(self.x_stage_m[k]) / np.diff(self.t_s[k])
        return out

    @cached_property
    def phase_is_hold(self) -> np.ndarray:
        """True for phases where the stage rests."""
        k = self.phase_knots
        rest = self.is_hold
        return np.array([bool(np.all(rest[a:b])) for a, b in zip(k[:-1], k[1:], strict=True)])

    @property
    def moving_velocities(self) -> FloatArray:
        """Mean velocities of the phases where the stage slides."""
        out: FloatArray = self.phase_velocity[~self.phase_is_hold]
        return out

    def velocity_at(self, t_rel_s: FloatArray) -> FloatArray:
        """Mean stage velocity of the phase holding each time."""
        out: FloatArray = self.phase_velocity[self.segment_index(t_rel_s)]
        return out

    def sliding_velocity_at(self, t_rel_s: FloatArray) -> FloatArray:
        """:meth:`velocity_at`, 0 in holds (a resting stage's line drifts by its noise)."""
        idx = self.segment_index(t_rel_s)
        out: FloatArray = np.where(self.phase_is_hold[idx], 0.0, self.phase_velocity[idx])
        return out

    def fn_at(self, t_rel_s: FloatArray) -> FloatArray:
        out: FloatArray = np.interp(t_rel_s, self.t_s, self.fn_N)
        return out

    def motion_start_s(self) -> float:
        """Relative time at which the stage first moves."""
        moving = np.flatnonzero(~self.is_hold)
        return float(self.t_s[moving[0]]) if moving.size else float(self.t_s[-1])

    def _time_within(self, t_a: float, t_b: float) -> FloatArray:
        """Seconds of each segment that fall inside [t_a, t_b] (relative times)."""
        out: FloatArray = np.clip(self.t_s[1:], t_a, t_b) - np.clip(self.t_s[:-1], t_a, t_b)
        return out

    def hold_time_between(self, t_a: float, t_b: float) -> float:
        """Seconds of stage rest inside [t_a, t_b] (relative times)."""
        return float(np.sum(self._time_within(t_a, t_b)[self.is_hold]))

    def last_change_before(self, t_rel_s: float) -> float:
        """Start of the phase holding ``t_rel_s`` (where the current loading began)."""
        k = int(self.segment_index(np.array([t_rel_s]))[0])
        return float(self.t_s[self.phase_knots[k]])

    def phase_end(self, t_rel_s: float) -> float:
        """End of the phase holding ``t_rel_s``."""
        k = int(self.segment_index(np.array([t_rel_s]))[0])
        return float(self.t_s[self.phase_knots[k + 1]])

    def n_segments(self) -> int:
        """Number of protocol phases."""
        return int(self.phase_knots.shape[0] - 1)

    def x_at(self, t_rel_s: FloatArray) -> FloatArray:
        """Stage position (simplified drive) at relative times."""
        out: FloatArray = np.interp(t_rel_s, self.t_s, self.x_stage_m)
        return out

    def travel_between(self, t_a: float, t_b: float) -> float:
        """Path length of the stage over [t_a, t_b] (relative times; back and forth both count)."""
        return float(np.sum(np.abs(self.velocity_m_per_s) * self._time_within(t_a, t_b)))

    def steady_slide_between(self, t_a: float, t_b: float) -> bool:
        """True when the stage slides without rest or reversal over [t_a, t_b] (the velocity may
        change): the stick loading is then a straight line in stage position across the corners."""
        ks = np.arange(int(self.knot_index(np.array([t_a]))[0]),
                       int(self.knot_index(np.array([t_b]))[0]) + 1)
        v = self.velocity_m_per_s[ks]
        return bool(not np.any(self.is_hold[ks]) and (np.all(v > 0) or np.all(v < 0)))


REFERENCE_SPEED_QUANTILE = 0.9
"""Quantile (by duration) of the segments' speeds taken as the run's sliding speed."""


def reference_speed(speed: FloatArray, dt: FloatArray, moving: np.ndarray | None = None) -> float:
    """The run's sliding speed that holds are judged against: the 90th percentile of the segments'
    speeds weighted by their duration (segments that move at all). Not the fastest segment: a
    protocol's repositioning strokes (the TLRE's return at 1.4 mm/s) would make its 1.3 um/s slide
    look like a rest."""
    sel = speed > 0.0 if moving is None else (moving & (speed > 0.0))
    if not np.any(sel):
        return 0.0
    sp, w = speed[sel], dt[sel]
    order = np.argsort(sp)
    cum = np.cumsum(w[order])
    k = int(np.searchsorted(cum, REFERENCE_SPEED_QUANTILE * cum[-1]))
    return float(sp[order][min(k, sp.size - 1)])


PHASE_SHIFT_S = 1.0
"""A change of velocity starts a new protocol phase when the stage departs from one straight line
by more than it travels in this time at the phase's mean speed (a velocity step of 10 -> 30 um/s
held 7 s departs by ~35 um, 1.7 s of travel; the jitter of a polled stage position or a stepper's
uneven steps stays well below)."""

PHASE_HOLD_MIN_S = 0.5
"""Rests or reversals no longer than this inside a slide (a stage that stalls between polls, position
jitter) are not phases."""

PHASE_FN_FRACTION = 0.05
"""A change of the normal load by more than this fraction of the run's largest starts a phase."""


def _phases(drive: DriveProfile) -> np.ndarray:
    """Knot indices where the protocol phases begin, plus the last knot.

    The knots follow the measured drive closely (a few noise RMS), so on a jittery stage record
    (polled positions, stepper motors) they come every second or so; comparing events within such
    pieces would pair nothing. Phases are what the protocol did: a hold (at least PHASE_HOLD_MIN_S),
    a slide in one direction at one velocity (PHASE_SHIFT_S), one normal load (PHASE_FN_FRACTION).
    """
    n = drive.t_s.shape[0] - 1
    if n <= 1:
        return np.array([0, n], dtype=np.intp)
    v = drive.velocity_m_per_s
    dt = np.diff(drive.t_s)
    rest = drive.is_hold.copy()
    kind = np.where(rest, 0, np.sign(v)).astype(np.int8)
    # short rests or reversals inside a slide in one direction (a stage stalling between polls,
    # position jitter) are part of the slide
    k = 0
    while k < n:
        j = k
        while j < n and kind[j] == kind[k]:
            j += 1
        if k > 0 and j < n and kind[k - 1] == kind[j] != 0 \
                and float(np.sum(dt[k:j])) <= PHASE_HOLD_MIN_S:
            kind[k:j] = kind[k - 1]
        k = j
    fn_mid = 0.5 * (drive.fn_N[:-1] + drive.fn_N[1:])
    fn_thr = PHASE_FN_FRACTION * max(float(np.max(np.abs(drive.fn_N))), 1e-9)
    starts = [0]
    for k in range(1, n):
        if kind[k] != kind[k - 1] or abs(fn_mid[k] - fn_mid[starts[-1]]) > fn_thr:
            starts.append(k)
    starts.append(n)
    # within a slide: velocity changes by the departure from one straight line
    out: list[int] = []
    for a, b in zip(starts[:-1], starts[1:], strict=True):
        out.append(a)
        if kind[a] == 0 or b - a < 2:
            continue
        span = drive.t_s[b] - drive.t_s[a]
        v_mean = abs(drive.x_stage_m[b] - drive.x_stage_m[a]) / span if span > 0 else 0.0
        if v_mean <= 0.0:
            continue
        idx = douglas_peucker(drive.t_s[a : b + 1], drive.x_stage_m[a : b + 1],
                              v_mean * PHASE_SHIFT_S)
        out.extend(int(a + i) for i in idx[1:-1])
    out.append(n)
    return np.array(sorted(set(out)), dtype=np.intp)


def _quantum(x: FloatArray) -> float:
    """The smallest step of a quantised signal (0 if it is not visibly quantised)."""
    d = np.abs(np.diff(x))
    nz = d[d > 0]
    if nz.size < 10:
        return 0.0
    q = float(np.percentile(nz, 5))
    if nz.size > 0.5 * d.size:
        # mostly moving: still quantised if the steps are whole multiples of the smallest one (a
        # 1 nm encoder moving more than half a step per sample), not if they are continuous noise
        ratio = nz / q
        if np.mean(np.abs(ratio - np.round(ratio)) < 0.05) < 0.8:
            return 0.0
    return q


def douglas_peucker(t: FloatArray, y: FloatArray, tol: float, max_knots: int = 400) -> np.ndarray:
    """Indices of the knots of a piecewise-linear approximation within ``tol`` of every sample.

    The segment with the largest deviation is split first, so when ``max_knots`` runs out (a long
    record whose tolerance is below its quantisation, e.g. a 1 nm stage encoder moving more than
    half a step per sample) the knots went to the corners of the drive, not all to its last part.
    """
    n = t.shape[0]
    knots = {0, n - 1}

    def split(a: int, b: int) -> tuple[float, int, int, int] | None:
        if b - a < 2:
            return None
        tt = t[a : b + 1]
        chord = y[a] + (y[b] - y[a]) * (tt - t[a]) / (t[b] - t[a])
        dev = np.abs(y[a : b + 1] - chord)
        k = int(np.argmax(dev))
        return (-float(dev[k]), a, b, a + k) if dev[k] > tol else None

    heap = [s for s in (split(0, n - 1),) if s is not None]
    while heap and len(knots) < max_knots:
        _, a, b, m = heapq.heappop(heap)
        knots.add(m)
        for s in (split(a, m), split(m, b)):
            if s is not None:
                heapq.heappush(heap, s)
    return np.array(sorted(knots), dtype=np.intp)


def piecewise_linear_lsq(t: FloatArray, y: FloatArray, knot_t: FloatArray) -> FloatArray:
    """Knot values of the continuous piecewise-linear least-squares fit (hat-function basis)."""
    nk = knot_t.shape[0]
    j = np.clip(np.searchsorted(knot_t, t, side="right") - 1, 0, nk - 2)
    u = (t - knot_t[j]) / (knot_t[j + 1] - knot_t[j])
    w0 = 1.0 - u
    w1 = u
    diag = np.bincount(j, w0 * w0, nk) + np.bincount(j + 1, w1 * w1, nk)
    off = np.bincount(j, w0 * w1, nk - 1)
    rhs = np.bincount(j, w0 * y, nk) + np.bincount(j + 1, w1 * y, nk)
    a = np.diag(diag) + np.diag(off, 1) + np.diag(off, -1)
    a[np.diag_indices(nk)] += 1e-12 * (diag.max() + 1.0)  # knots with no samples nearby
    out: FloatArray = np.linalg.solve(a, rhs)
    return out


REFINE_TRIM = 0.15
"""Fraction of a segment's length left out at each end when its line is fitted for corner times."""
REFINE_MIN_SAMPLES = 16
REFINE_MAX_SHIFT = 0.1
"""A corner moves by at most this fraction of its shorter neighbouring segment."""


def _line(t: FloatArray, y: FloatArray, lo: float, hi: float) -> tuple[float, float] | None:
    """Slope and intercept of the least-squares line through the samples of [lo, hi] (trimmed)."""
    trim = REFINE_TRIM * (hi - lo)
    i0, i1 = np.searchsorted(t, [lo + trim, hi - trim])
    if i1 - i0 < REFINE_MIN_SAMPLES:
        return None
    tt = t[i0:i1]
    tm = float(np.mean(tt))
    dt = tt - tm
    den = float(np.dot(dt, dt))
    if den <= 0.0:
        return None
    slope = float(np.dot(dt, y[i0:i1])) / den
    return slope, float(np.mean(y[i0:i1])) - slope * tm


def _merge_cut_corners(t: FloatArray, y: FloatArray, knot_t: FloatArray) -> FloatArray:
    """A sharp corner that Douglas-Peucker cut with two knots (a segment too short to fit a line
    between two long ones) becomes one knot where the two long segments' lines meet, if they meet
    inside the short segment."""
    knots = list(knot_t)
    i = 1
    while i + 2 < len(knots):
        a, k1, k2, b = knots[i - 1], knots[i], knots[i + 1], knots[i + 2]
        if _line(t, y, k1, k2) is not None:
            i += 1
            continue
        left = _line(t, y, a, k1)
        right = _line(t, y, k2, b)
        if left is not None and right is not None and left[0] != right[0]:
            tc = (right[1] - left[1]) / (left[0] - right[0])
            if np.isfinite(tc) and k1 <= tc <= k2:
                knots[i : i + 2] = [tc]
        i += 1
    return np.asarray(knots, dtype=np.float64)


def refine_knot_times(t: FloatArray, y: FloatArray, knot_t: FloatArray) -> FloatArray:
    """Interior knot times moved to the intersection of the lines of their two segments.

    A corner is only moved when both segments hold enough samples, their slopes differ and the
    intersection lies near the knot (short segments of a curved or stepped history stay as found).
    """
    knot_t = _merge_cut_corners(t, y, knot_t.astype(np.float64))
    out = knot_t.copy()
    for i in range(1, knot_t.shape[0] - 1):
        a, k, b = float(knot_t[i - 1]), float(knot_t[i]), float(knot_t[i + 1])
        left = _line(t, y, a, k)
        right = _line(t, y, k, b)
        if left is None or right is None or left[0] == right[0]:
            continue
        tc = (right[1] - left[1]) / (left[0] - right[0])
        if np.isfinite(tc) and abs(tc - k) <= REFINE_MAX_SHIFT * min(k - a, b - k):
            out[i] = tc
    return out


def _flatten_groups(values: FloatArray, tol: float) -> FloatArray:
    """Consecutive knot values that stay within ``tol`` of each other become their mean (exactly
    constant inputs let the engine use its fast exact recurrence, and a held load is constant)."""
    out = values.copy()
    start = 0
    for i in range(1, values.shape[0] + 1):
        group = values[start:i + 1] if i < values.shape[0] else values[start:i]
        if i == values.shape[0] or float(np.ptp(group)) > tol:
            out[start:i] = float(np.mean(values[start:i]))
            start = i
    return out


def _fit_channel(t: FloatArray, y: FloatArray, tol: float) -> tuple[FloatArray, FloatArray]:
    idx = douglas_peucker(t, y, tol)
    knot_t = refine_knot_times(t, y, t[idx])
    return knot_t, piecewise_linear_lsq(t, y, knot_t)


def _merge_close(knots: FloatArray, dt_min: float) -> FloatArray:
    """Drop knots closer than ``dt_min`` to the previous one (the last knot is kept)."""
    keep = [0]
    for i in range(1, knots.shape[0] - 1):
        if knots[i] - knots[keep[-1]] >= dt_min and knots[-1] - knots[i] >= dt_min:
            keep.append(i)
    keep.append(knots.shape[0] - 1)
    out: FloatArray = knots[keep]
    return out


FN_APART_FRACTION = 0.005
"""Normal force below this fraction of the run's largest is taken as the specimens apart."""


def fn_apart_N(fn_N: FloatArray) -> float:
    """Measured normal force [N] below which the specimens are taken as apart.

    Five times the force noise, or half a percent of the largest force of the run (1.5 N at 300 N),
    whichever is larger: a measured release is zero plus noise and offset, never exactly zero.
    """
    peak = float(np.max(np.abs(fn_N))) if fn_N.size else 0.0
    return max(5.0 * noise_sigma(fn_N), FN_APART_FRACTION * peak)


APART_MIN_S = 0.1
"""Shortest stretch below :func:`fn_apart_N` taken as a release (shorter ones are noise)."""


def _apart_intervals(t: FloatArray, fn: FloatArray) -> list[tuple[float, float]]:
    """Stretches ``(t_start, t_end)`` where the measured Fn stays below :func:`fn_apart_N`."""
    below = fn < fn_apart_N(fn)
    if not below.any():
        return []
    d = np.diff(below.astype(np.int8))
    starts = [int(i) for i in np.flatnonzero(d == 1) + 1]
    ends = [int(i) for i in np.flatnonzero(d == -1)]
    if below[0]:
        starts.insert(0, 0)
    if below[-1]:
        ends.append(below.size - 1)
    return [(float(t[a]), float(t[b])) for a, b in zip(starts, ends, strict=True)
            if t[b] - t[a] >= APART_MIN_S]


def drive_profile(run: MeasuredRun, fn_tolerance_fraction: float = 0.03,
                  coupling: tuple[float, float] | None = None) -> DriveProfile:
    """The simplified drive of ``run`` (raises DataError if the stage never moves). ``coupling``:
    the campaign's dFn/dFt and its standard error (:func:`~rigctl.records.fn_coupling.
    campaign_coupling`); None: read from this run."""
    t = run.t_s - run.t_s[0]
    x = run.x_stage_m
    fn = run.fn_N
    q = _quantum(x)
    x_tol = max(3.0 * q, 8.0 * noise_sigma(x), 1e-9)
    fn_scale = float(np.median(np.abs(fn)))
    fn_tol = max(8.0 * noise_sigma(fn), fn_tolerance_fraction * fn_scale, 1e-6)
    xt, xv = _fit_channel(t, x, x_tol)
    # the applied load: without the swing that follows Ft (a coupled frame, cross-talk)
    fn_applied, fn_per_ft = applied_normal_force(run.ft_N, fn, coupling)
    ft, fv = _fit_channel(t, fn_applied, fn_tol)
    # holds: the stage rests exactly
    v = np.diff(xv) / np.diff(xt)
    v_ref = reference_speed(np.abs(v), np.diff(xt), np.abs(np.diff(xv)) > x_tol)
    rest = (np.abs(v) <= HOLD_VELOCITY_FRACTION * v_ref) | (np.abs(np.diff(xv)) <= x_tol)
    for k in np.flatnonzero(rest):
        mean = 0.5 * (xv[k] + xv[k + 1])
        xv[k] = xv[k + 1] = mean
    fv = _flatten_groups(fv, fn_tol)
    dt_min = 5.0 * float(np.median(np.diff(t)))
    apart = _apart_intervals(t, fn)
    edges = np.array([e for pair in apart for e in pair], dtype=np.float64)
    knots = _merge_close(np.union1d(np.union1d(xt, ft), edges), dt_min)
    if edges.size:  # the edges of a release are where the contact ends and starts: keep them
        knots = np.union1d(knots, edges)
    xk = np.interp(knots, xt, xv)
    fk = np.clip(np.interp(knots, ft, fv), 0.0, None)
    # specimens apart: a released load reads as sensor noise around zero (and the Fn line fit may
    # leave a few newtons there), which the engine would take for a light contact (its threshold is
    # 0.01 N) and so never start a new initial stage when the load comes back
    for ta, tb in apart:
        fk[(knots >= ta) & (knots <= tb)] = 0.0
    prof = DriveProfile(knots, xk, fk, float(run.t_s[0]), fn_per_ft)
    travel = float(np.max(x) - np.min(x))
    if travel <= 4.0 * x_tol or prof.moving_velocities.size == 0:
        raise DataError(
            f"the stage does not move (travel {travel * 1e6:.3g} um): no tangential loading to "
            "compare against",
            path=run.source or None,
            column="x_stage_m",
        )
    return prof
