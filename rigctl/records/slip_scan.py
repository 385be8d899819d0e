"""The slip detector's scan over a record, compiled: the rules of :mod:`rigctl.records.events`.

:func:`scan_slips` is the work of :func:`rigctl.records.events.detect_slips` once its record-wide
settings (threshold, windows, delta noise, drive speed) are known: drop candidates, their
clusters, the long ring chains cut (:func:`split_ring_chains`), and per cluster the peak, the
ring-swing test (:func:`is_ring_swing`), the stroke-reversal test and the delta confirmation, with
the rules' constants below. It reads every model evaluation's series, where the same loop in
Python (thousands of small numpy calls) cost more than the integration (docs/performance.md,
"Evaluation"); its medians, quantiles and means are numpy's own (:mod:`rigctl.records.sample_stats`),
so it finds the slips the Python loop found (tests/records/test_compiled_reading.py).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from rigctl.records.sample_stats import np_mean, np_median, np_quantile

LONG_CHAIN_GAPS = 5
"""A cluster of drops longer than this many merge gaps is a chain of ring swings (swings closer
than the merge gap, ringing on above the threshold) that may hold the next slip."""
CHAIN_GROWTH = 1.5
"""In a chain, a drop this much larger than the one before it is not a swing of a decaying
ringing."""
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
AGAINST_FRACTION = 0.1
"""A drop is an unloading when the stage moves against the force faster than this fraction of the
record's typical drive speed (a stage at rest, or a phase line drifting by its noise, is not)."""
LOAD_CHANGE = 0.25
"""Relative change of Fn around a drop that makes it a load change (as the release rule of
:mod:`rigctl.records.features`), not a stroke reversal."""
CONFIRM_SIGMAS = 3.0
"""A confirming forward delta jump exceeds this many delta noise RMS."""


@njit(cache=True)
def _fmin(a: float, b: float) -> float:
    """np.minimum: NaN if either is NaN."""
    if math.isnan(a) or math.isnan(b):
        return math.nan
    return a if a <= b else b


@njit(cache=True)
def _fmax(a: float, b: float) -> float:
    if math.isnan(a) or math.isnan(b):
        return math.nan
    return a if a >= b else b


@njit(cache=True)
def _min_of(x: np.ndarray, i0: int, i1: int, s: float) -> float:
    """np.min(s * x[i0:i1]) (NaN propagates)."""
    m = s * x[i0]
    for i in range(i0 + 1, i1):
        m = _fmin(m, s * x[i])
    return m


@njit(cache=True)
def _max_of(x: np.ndarray, i0: int, i1: int, s: float) -> float:
    m = s * x[i0]
    for i in range(i0 + 1, i1):
        m = _fmax(m, s * x[i])
    return m


@njit(cache=True)
def run_size(ft: np.ndarray, r0: int, r1: int, w: int, n: int) -> float:
    """Force fall of a run of drop candidates (samples r0 .. r1) in the direction of loading: the
    highest of its first samples down to the lowest until a drop window after it."""
    s = 1.0 if ft[r0] >= 0 else -1.0
    return _max_of(ft, r0, min(r0 + w + 2, n), s) - _min_of(ft, r0, min(r1 + w + 1, n), s)


@njit(cache=True)
def split_ring_chains(cand: np.ndarray, starts: np.ndarray, ft: np.ndarray, w: int,
                       gap: int) -> np.ndarray:
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

    The clusters are ranges of ``cand`` (``starts``, its length last); so are the clusters
    returned (consecutive runs joined make a range)."""
    n = ft.shape[0]
    out = np.empty(cand.shape[0] + 1, np.intp)
    k = 0
    for b in range(starts.shape[0] - 1):
        a, e = starts[b], starts[b + 1]
        if int(cand[e - 1] - cand[a]) <= LONG_CHAIN_GAPS * gap:
            out[k] = a
            k += 1
            continue
        out[k] = a
        k += 1
        r_a = a
        r_e = a + 1
        while r_e < e and cand[r_e] - cand[r_e - 1] <= w + 1:
            r_e += 1
        opened = run_size(ft, cand[r_a], cand[r_e - 1], w, n)
        last = opened
        while r_e < e:
            r_a = r_e
            r_e = r_a + 1
            while r_e < e and cand[r_e] - cand[r_e - 1] <= w + 1:
                r_e += 1
            size = run_size(ft, cand[r_a], cand[r_e - 1], w, n)
            if opened < RING_SIZE_FRACTION * size:
                opened = size
            elif size > RING_SIZE_FRACTION * opened and size > CHAIN_GROWTH * last:
                out[k] = r_a
                k += 1
                opened = size
            last = size
    out[k] = cand.shape[0]
    return out[: k + 1]


@njit(cache=True)
def is_ring_swing(ft: np.ndarray, s: float, w: int, i_prev_peak: int, prev_size: float,
                   i_pk: int, i_end: int, size: float) -> bool:
    """A drop of ``size`` from ``i_pk`` to ``i_end`` is a swing of the ringing of the previous
    slip (peak at ``i_prev_peak``, drop ``prev_size``); ``s * ft`` is the force in the direction of
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
    f_min = s * ft[i_pk]
    k_min = 0
    for k in range(1, i_end + 1 - i_pk):  # np.argmin: the first lowest (or the first NaN)
        v = s * ft[i_pk + k]
        if math.isnan(f_min):
            break
        if math.isnan(v) or v < f_min:
            f_min, k_min = v, k
    look = RING_LOOK_BACK * (k_min + w)
    if look > RING_SPAN_OVER_ELAPSED * (i_pk - i_prev_peak):
        return False
    b0 = max(i_pk - look, i_prev_peak)
    if i_pk - b0 <= 0:
        return False
    before = s * ft[b0:i_pk]
    f_pk = s * ft[i_pk]
    rise = f_pk - np_quantile(before, RING_LOW_QUANTILE)
    lo, hi = RING_RISE_RANGE
    if not lo * size <= rise <= hi * size:
        return False
    a1 = min(i_end + look, ft.shape[0])
    if a1 - i_end <= 0:
        return False
    return np_median(s * ft[i_end:a1]) > f_pk - RING_RETURN * size


@njit(cache=True)
def _load_changes(fn: np.ndarray, i0: int, i1: int) -> bool:
    """|Fn| over samples i0 .. i1 changes by more than LOAD_CHANGE of its largest."""
    a, b = max(i0, 0), min(max(i1, 0) + 1, fn.shape[0])
    if b <= a:
        return False
    top = bottom = abs(fn[a])
    for i in range(a + 1, b):
        top = _fmax(top, abs(fn[i]))
        bottom = _fmin(bottom, abs(fn[i]))
    return top > 0.0 and top - bottom > LOAD_CHANGE * top


@njit(cache=True)
def _all(mask: np.ndarray, i0: int, i1: int) -> bool:
    """mask[i0:i1].all()"""
    i, stop = max(i0, 0), min(i1, mask.shape[0])
    while i < stop and mask[i]:
        i += 1
    return i >= stop


@njit(cache=True)
def _extremes_ahead(x: np.ndarray, w: int) -> tuple[np.ndarray, np.ndarray]:
    """Lowest and highest of x[i+1 .. i+w] for every i, the signal held at its last value past
    its end, NaN propagating as in numpy (signals.sliding_extreme)."""
    n = x.shape[0]
    lo = np.empty(n)
    hi = np.empty(n)
    for i in range(n):
        a = b = x[i + 1] if i + 1 < n else x[n - 1]
        for k in range(2, w + 1):
            v = x[i + k] if i + k < n else x[n - 1]
            a = _fmin(a, v)
            b = _fmax(b, v)
        lo[i], hi[i] = a, b
    return lo, hi


@njit(cache=True)
def scan_slips(
    ft: np.ndarray, delta: np.ndarray, delta_valid: np.ndarray, v_drive: np.ndarray,
    fn: np.ndarray, w: int, gap: int, thr: float, confirm_factor: float, d_sigma: float,
    d_informative: bool, v_ref: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Peaks, ends and signs of the slips of ``ft``: the drops beyond ``thr`` within the drop
    window ``w`` (in samples), merged within ``gap``, long ring chains cut, each cluster's peak
    found, and ring swings, stroke reversals (the drive against the force, unless Fn changes) and
    small drops that delta does not confirm left out (:mod:`rigctl.records.events`).

    Absent inputs are empty arrays: ``delta`` (no delta confirmation), ``delta_valid`` (all
    valid), ``v_drive`` (no stroke-reversal test), ``fn`` (no load-change exception)."""
    n = ft.shape[0]
    # candidates: |Ft| beyond the threshold and a drop beyond it within the next w samples (the
    # signal held at its last value past its end): for Ft > 0, Ft less the lowest of them
    cand_buf = np.empty(n, np.intp)
    n_cand = 0
    if np.isnan(ft).any():  # NaN propagates through the window's extreme, as in numpy
        lo_ahead, hi_ahead = _extremes_ahead(ft, w)
        for i in range(n):
            f = ft[i]
            drop = f - lo_ahead[i] if f > 0 else hi_ahead[i] - f  # np.sign(f) > 0
            if drop > thr and abs(f) > thr:
                cand_buf[n_cand] = i
                n_cand += 1
    else:
        # f - min(x) > thr exactly when f - x > thr for some x (subtraction is monotone)
        for i in range(n):
            f = ft[i]
            if not abs(f) > thr:
                continue
            for k in range(i + 1, i + w + 1):
                v = ft[k] if k < n else ft[n - 1]
                if (f - v if f > 0 else v - f) > thr:
                    cand_buf[n_cand] = i
                    n_cand += 1
                    break
    empty = np.zeros(0, np.intp)
    if n_cand == 0:
        return empty, empty.copy(), np.zeros(0, np.int8)
    cand = cand_buf[:n_cand].copy()
    starts_buf = np.empty(n_cand + 1, np.intp)
    starts_buf[0] = 0
    nb = 1
    for i in range(1, n_cand):
        if cand[i] - cand[i - 1] > gap:
            starts_buf[nb] = i
            nb += 1
    starts_buf[nb] = n_cand
    clusters = split_ring_chains(cand, starts_buf[: nb + 1], ft, w, gap)
    has_delta = delta.shape[0] > 0
    has_valid = delta_valid.shape[0] > 0
    has_v = v_drive.shape[0] > 0
    has_fn = fn.shape[0] > 0
    peaks = np.empty(clusters.shape[0], np.intp)
    ends = np.empty(clusters.shape[0], np.intp)
    signs = np.empty(clusters.shape[0], np.int8)
    m = 0
    prev_size = 0.0
    for b in range(clusters.shape[0] - 1):
        c0, c1 = cand[clusters[b]], cand[clusters[b + 1] - 1]
        s = 1 if ft[c0] > 0 else (-1 if ft[c0] < 0 else 0)
        i_end = min(c1 + w, n - 1)
        size_est = run_size(ft, c0, c1, w, n)
        seg_end = min(c0 + w + 2, n)
        lim = max(0.5 * thr, 0.1 * size_est)
        i_pk = -1
        for k in range(c0, seg_end - 1):
            if s * ft[k] - s * ft[k + 1] > lim:
                i_pk = k
                break
        if i_pk < 0:  # np.argmax: the first highest (or the first NaN)
            best = s * ft[c0]
            i_pk = c0
            for k in range(c0 + 1, seg_end):
                v = s * ft[k]
                if math.isnan(best):
                    break
                if math.isnan(v) or v > best:
                    best, i_pk = v, k
        if i_pk > i_end:
            continue
        size = s * ft[i_pk] - _min_of(ft, i_pk, i_end + 1, s)
        if size <= thr:
            continue
        if (m > 0 and signs[m - 1] == s
                and is_ring_swing(ft, s, w, peaks[m - 1], prev_size, i_pk, i_end, size)):
            continue
        if has_v:
            against = np_mean(s * v_drive[i_pk : i_end + 1]) < -AGAINST_FRACTION * v_ref
            if against and not (has_fn and _load_changes(fn, i_pk - gap, i_end + gap)):
                continue
        if (size < confirm_factor * thr and d_informative and has_delta
                and (not has_valid or _all(delta_valid, i_pk - w, min(n, i_end + gap)))):
            before = np_median(delta[max(0, i_pk - w) : i_pk + 1])
            after = np_median(delta[i_end : min(n, i_end + gap)])
            if s * (after - before) <= CONFIRM_SIGMAS * d_sigma:
                continue
        peaks[m] = i_pk
        ends[m] = i_end
        signs[m] = s
        m += 1
        prev_size = size
    return peaks[:m].copy(), ends[:m].copy(), signs[:m].copy()
