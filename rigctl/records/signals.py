"""Small numerical helpers shared by event detection and feature extraction.

* :func:`median` - ``np.median`` of a 1-D array, the same value bit for bit, at a quarter of the cost
  for an even count: numpy selects the two middle elements by a partition on two ``kth`` (about
  four times one partition at 24,000 elements); one partition at the upper middle leaves the lower
  middle as the largest element below it. Where a quarter or more of the values are exactly zero,
  they are counted apart (see the function). (Short windows inside compiled loops use
  :func:`rigctl.records.sample_stats.np_median`, which sorts.)
* :func:`noise_sigma` - white-noise RMS of a sampled signal from its second differences. For white
  noise of RMS s the second difference has variance 6 s^2, and a median-based estimate of it ignores
  the rare large steps (slips) and any linear trend (stick ramps): s = 1.4826 MAD(d2) / sqrt(6)
  (the normal-consistent MAD; e.g. Huber & Ronchetti, *Robust Statistics*, 2nd ed., sec. 5.1).
* :func:`line_fit` - ordinary least-squares straight line over a window, evaluated at a chosen time.
* :func:`von_neumann_sigma` - event-to-event scatter of a feature sequence from successive
  differences, var = mean(diff^2) / 2 (von Neumann et al., Ann. Math. Stat. 12, 1941), robustified with
  the MAD. It ignores slow trends, so a drifting feature is not mistaken for a noisy one.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

_MAD_TO_SIGMA = 1.482602218505602
_NOISE_SAMPLE_LIMIT = 24000


def median(x: FloatArray) -> float:
    """``float(np.median(x))`` of a 1-D array (NaN where it holds a NaN or nothing): the middle
    element, or for an even count the two middle ones summed and halved as ``np.median`` does
    (``np.mean`` of two: their sum from 0.0 divided by 2), from one partition (module docstring).

    Where a quarter or more of the values are exactly zero (the second differences of a noise-free
    series: a model's run), the zeros are counted and the middle ranks selected among the
    negatives or the positives, since numpy's selection slows down about tenfold on a large block
    of equal values. The order statistics are the same values either way. Only a zero's sign could
    differ, and summing from 0.0 makes every zero +0.0."""
    n = x.shape[0]
    if n == 0 or np.isnan(x).any():
        return float("nan")
    h = n // 2
    even = n % 2 == 0
    n_zero = int(np.count_nonzero(x == 0.0))
    if n_zero * _ZERO_BLOCK_SHARE >= n:
        lower, upper = _middle_split(x[x < 0.0], n_zero, x[x > 0.0], h, even)
    else:
        p = np.partition(x, h)
        lower, upper = (float(p[:h].max()) if even else math.nan), float(p[h])
    # summed from 0.0 as numpy's mean sums (a middle -0.0 gives 0.0, as there)
    if not even:
        return float(0.0 + upper)
    return float((0.0 + lower + upper) / 2.0)


_ZERO_BLOCK_SHARE = 4
""":func:`median` counts the zeros apart where they are at least 1/4 of the values. This choice
affects speed only, never the value. Measured on models' second differences: at about half zeros
the split is 2-3 times faster; at about a seventh it is slower, since the selection among the
rest then costs as much as the whole."""


def _middle_split(neg: FloatArray, n_zero: int, pos: FloatArray, h: int,
                  even: bool) -> tuple[float, float]:
    """The values of ranks ``h - 1`` (NaN unless ``even``) and ``h`` (from 0) of the sorted values:
    ``neg`` (all below zero), then ``n_zero`` >= 1 zeros, then ``pos`` (all above zero). Each comes
    from one partition at most: where both ranks fall in one part, the lower is the largest
    element below the upper, as in :func:`median`."""
    n_neg = neg.shape[0]
    if h < n_neg:
        p = np.partition(neg, h)
        return (float(p[:h].max()) if even else math.nan), float(p[h])
    r = h - n_neg  # the upper's rank among the zeros and the positives
    if r < n_zero:
        upper = 0.0
    else:
        p = np.partition(pos, r - n_zero)
        upper = float(p[r - n_zero])
    if not even:
        return math.nan, upper
    if r == 0:  # the lower is the largest negative (there is one: h >= 1 for an even count)
        return float(neg.max()), upper
    if r - 1 < n_zero:
        return 0.0, upper
    return float(p[: r - n_zero].max()), upper


def noise_sigma(x: FloatArray) -> float:
    """Robust white-noise RMS of ``x`` (0 for a noise-free piecewise-linear signal)."""
    if x.shape[0] < 4:
        return 0.0
    if x.shape[0] > _NOISE_SAMPLE_LIMIT:
        # 8 evenly spread blocks are plenty for a median and keep long records cheap
        n_blk = _NOISE_SAMPLE_LIMIT // 8
        starts = np.linspace(0, x.shape[0] - n_blk, 8).astype(np.intp)
        d2 = np.concatenate(
            [x[s + 2 : s + n_blk] - 2.0 * x[s + 1 : s + n_blk - 1] + x[s : s + n_blk - 2]
             for s in starts]
        )
    else:
        d2 = x[2:] - 2.0 * x[1:-1] + x[:-2]
    mad = median(np.abs(d2 - median(d2)))
    if mad == 0.0:
        # quantised signals: most second differences are exactly 0; use the RMS of the small ones
        small = d2[np.abs(d2) <= 4.0 * (np.percentile(np.abs(d2), 90) + 1e-300)]
        return float(np.sqrt(np.mean(small**2) / 6.0)) if small.size else 0.0
    return _MAD_TO_SIGMA * mad / math.sqrt(6.0)


def von_neumann_sigma(values: FloatArray) -> float:
    """Robust event-to-event scatter of a sequence (NaNs ignored; NaN if fewer than 3 values)."""
    v = values[np.isfinite(values)]
    if v.shape[0] < 3:
        return float("nan")
    d = np.diff(v)
    return _MAD_TO_SIGMA * float(np.median(np.abs(d - np.median(d)))) / math.sqrt(2.0)


def line_fit(t: FloatArray, y: FloatArray, i0: int, i1: int, t_eval: float) -> tuple[float, float]:
    """Least-squares line through samples [i0, i1); returns (value at ``t_eval``, slope).

    Returns NaNs when the window holds fewer than 3 samples.
    """
    i0 = max(i0, 0)
    i1 = min(i1, t.shape[0])
    if i1 - i0 < 3:
        return float("nan"), float("nan")
    n = i1 - i0
    t0 = float(t[i0])
    tt = t[i0:i1] - t0
    yy = y[i0:i1]
    st = float(tt.sum())
    sy = float(yy.sum())
    sxx = float(tt @ tt) - st * st / n
    if sxx <= 0.0:
        return sy / n, float("nan")
    slope = (float(tt @ yy) - st * sy / n) / sxx
    return sy / n + slope * (t_eval - t0 - st / n), slope


def slope_se(x: FloatArray, sigma_y: float) -> float:
    """Standard error of a least-squares slope dy/dx over abscissae ``x`` when y carries white
    noise of RMS ``sigma_y``: sigma_y / sqrt(sum (x - mean x)^2) (any regression text, e.g.
    Draper & Smith, Applied Regression Analysis, Sec. 1.4). NaN with fewer than 3 points."""
    if x.shape[0] < 3:
        return float("nan")
    dx = x - x.mean()
    sxx = float(dx @ dx)
    return sigma_y / math.sqrt(sxx) if sxx > 0.0 else float("nan")


def regress_slope(x: FloatArray, y: FloatArray) -> float:
    """Least-squares slope dy/dx (NaN with fewer than 3 points or no spread in x)."""
    if x.shape[0] < 3:
        return float("nan")
    dx = x - x.mean()
    sxx = float(dx @ dx)
    if sxx <= 0.0:
        return float("nan")
    return float(dx @ (y - y.mean())) / sxx


def sliding_extreme(x: FloatArray, width: int, kind: str) -> FloatArray:
    """out[i] = min (or max) of x[i+1 .. i+width], the window clipped at the end of the signal."""
    n = x.shape[0]
    pad = np.concatenate([x, np.full(width, x[-1])])
    op = np.minimum if kind == "min" else np.maximum
    out = pad[1 : n + 1].copy()
    for k in range(2, width + 1):
        op(out, pad[k : n + k], out=out)
    return out
