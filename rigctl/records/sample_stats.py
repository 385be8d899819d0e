"""numpy's reductions over a window of samples, compiled, giving numpy's own results.

The slip detection and the feature reads (:mod:`rigctl.records.slip_scan`,
:mod:`rigctl.records.window_reads`) run thousands of medians, quantiles and sums over short windows
of a record; called from Python each costs microseconds of overhead for nanoseconds of work. These
are the same computations inside numba, written to give numpy's results bit for bit (finite
inputs; NaN wherever numpy gives NaN), so that a record reads the same whichever code reads it:

* :func:`np_sum` - numpy's pairwise summation (``pairwise_sum`` in numpy's ``loops_utils``: blocks
  of 8 accumulators up to 128 values, halves above), started from 0 as ``np.add.reduce`` does;
* :func:`np_median` - the middle value, or the mean of the two middle ones;
* :func:`np_quantile` - numpy's default ``linear`` method (Hyndman & Fan's 7th) with its
  ``_lerp`` (from the upper neighbour for weights of one half and more).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

_BLOCK = 128
"""numpy's PW_BLOCKSIZE: the largest run summed by one block of 8 accumulators."""


@njit(cache=True)
def _block_sum(a: np.ndarray, lo: int, n: int) -> float:
    """numpy's sum of at most _BLOCK values from ``a[lo]``: 8 accumulators, then the rest."""
    if n < 8:
        r = 0.0
        for i in range(n):
            r += a[lo + i]
        return r
    r0, r1, r2, r3 = a[lo], a[lo + 1], a[lo + 2], a[lo + 3]
    r4, r5, r6, r7 = a[lo + 4], a[lo + 5], a[lo + 6], a[lo + 7]
    i = 8
    stop = n - (n % 8)
    while i < stop:
        j = lo + i
        r0 += a[j]
        r1 += a[j + 1]
        r2 += a[j + 2]
        r3 += a[j + 3]
        r4 += a[j + 4]
        r5 += a[j + 5]
        r6 += a[j + 6]
        r7 += a[j + 7]
        i += 8
    r = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < n:
        r += a[lo + i]
        i += 1
    return r


@njit(cache=True)
def _half(n: int) -> int:
    """Where numpy splits a run of n values: half, less its remainder modulo 8."""
    n2 = n // 2
    return n2 - n2 % 8


@njit(cache=True)
def pairwise_sum(a: np.ndarray, lo: int, n: int) -> float:
    """Sum of ``a[lo:lo + n]`` in numpy's pairwise order: each run over _BLOCK values is the sum
    of its two halves (walked with an explicit stack: numba caches no recursive function)."""
    if n <= _BLOCK:
        return _block_sum(a, lo, n)
    depth = 64
    s_lo = np.empty(depth, np.int64)
    s_n = np.empty(depth, np.int64)
    s_left = np.empty(depth)
    s_right = np.zeros(depth, np.bool_)
    top = 0
    s_lo[0], s_n[0] = lo, n
    while True:
        while s_n[top] > _BLOCK:  # down the left halves
            s_right[top] = False
            s_lo[top + 1], s_n[top + 1] = s_lo[top], _half(s_n[top])
            top += 1
        v = _block_sum(a, s_lo[top], s_n[top])
        top -= 1
        while top >= 0 and s_right[top]:  # up through the finished right halves
            v = s_left[top] + v
            top -= 1
        if top < 0:
            return v
        s_left[top], s_right[top] = v, True  # the left half is done: its right half next
        h = _half(s_n[top])
        s_lo[top + 1], s_n[top + 1] = s_lo[top] + h, s_n[top] - h
        top += 1


@njit(cache=True)
def np_sum(a: np.ndarray) -> float:
    """``np.sum(a)`` of a 1-D float64 array."""
    return 0.0 + pairwise_sum(a, 0, a.shape[0])


@njit(cache=True)
def np_dot(a: np.ndarray, b: np.ndarray) -> float:
    """``a @ b`` of two 1-D float64 arrays, as numpy's pairwise sum of the products (numpy's own
    ``@`` goes to BLAS: the same to rounding, summed in BLAS's order)."""
    return np_sum(a * b)


@njit(cache=True)
def np_mean(a: np.ndarray) -> float:
    """``np.mean(a)`` (NaN for an empty array)."""
    n = a.shape[0]
    return np_sum(a) / n if n else math.nan


@njit(cache=True)
def np_var(a: np.ndarray) -> float:
    """``np.var(a)``: the mean squared deviation from the mean."""
    n = a.shape[0]
    if n == 0:
        return math.nan
    d = a - np_mean(a)
    return np_sum(d * d) / n


@njit(cache=True)
def _sorted_or_nan(a: np.ndarray) -> tuple[np.ndarray, bool]:
    s = np.sort(a)
    return s, s.shape[0] > 0 and math.isnan(s[-1])  # NaN sorts last


@njit(cache=True)
def np_median(a: np.ndarray) -> float:
    """``np.median(a)`` (NaN if empty or any value is NaN)."""
    n = a.shape[0]
    if n == 0:
        return math.nan
    s, has_nan = _sorted_or_nan(a)
    if has_nan:
        return math.nan
    h = n // 2
    if n % 2:
        return float(s[h])
    return (0.0 + s[h - 1] + s[h]) / 2.0


@njit(cache=True)
def np_quantile(a: np.ndarray, q: float) -> float:
    """``np.quantile(a, q)`` with the default ``linear`` method (NaN if any value is NaN)."""
    n = a.shape[0]
    if n == 0:
        return math.nan
    s, has_nan = _sorted_or_nan(a)
    if has_nan:
        return math.nan
    vi = (n - 1) * q
    if vi >= n - 1:
        return float(s[n - 1])
    if vi < 0.0:
        return float(s[0])
    prev = math.floor(vi)
    gamma = vi - prev
    lo, hi = s[int(prev)], s[int(prev) + 1]
    diff = hi - lo
    if gamma >= 0.5:
        return float(hi - diff * (1.0 - gamma))
    return float(lo + diff * gamma)
