"""Repeatability of repeated loadings (paper Sec. 2.2, Fig. 3).

The paper states, for three repetitions: the relative error of the maximum Isum(t) in the NLRE
(< 1.31 %), of the linear fit Isum-Fn below 300 N in the TLRE (< 5.6 %), and of the maximum Ft in
the TLRE (3.56 %). Its formula was lost; we use, for a quantity x_j measured in each repetition j,

    relative error = max_j |x_j - mean(x)| / |mean(x)|

(the largest deviation of one repetition from the mean, a conservative reading of "relative error").
For the linear fit Isum = a + b Fn (least squares over the samples of each loading branch with
Fn <= ``FIT_LIMIT_N``) the quantity is the slope b; its R^2 and the largest relative deviation of
the data from the line (``fit_error`` = max |Isum - (a + b Fn)| / (a + b Fn)) are given per
repetition too.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from rigctl.data import FloatArray

FIT_LIMIT_N = 300.0


def relative_error(values: FloatArray) -> float:
    """max |x_j - mean| / |mean| (NaN with fewer than two finite values or a zero mean)."""
    v = np.asarray(values, dtype=np.float64)
    v = v[np.isfinite(v)]
    if v.size < 2:
        return math.nan
    m = float(np.mean(v))
    return float(np.max(np.abs(v - m)) / abs(m)) if m != 0 else math.nan


@dataclass(frozen=True)
class Repeated:
    """One quantity over the repetitions."""

    name: str
    unit: str
    values: tuple[float, ...]
    relative_error: float
    extra: dict[str, list[float]] = field(default_factory=dict)

    @staticmethod
    def of(name: str, unit: str, values: list[float], **extra: list[float]) -> Repeated:
        arr = np.array(values, dtype=np.float64)
        return Repeated(name, unit, tuple(float(x) for x in values), relative_error(arr), extra)

    def to_dict(self) -> dict[str, object]:
        return {"name": self.name, "unit": self.unit, "values": list(self.values),
                "relative_error": self.relative_error, **self.extra}


@dataclass(frozen=True)
class LinearFit:
    intercept: float
    slope: float
    r2: float
    fit_error: float
    n: int


def linear_fit(fn_N: FloatArray, isum: FloatArray, limit_N: float = FIT_LIMIT_N) -> LinearFit:
    """Least-squares Isum = a + b Fn over the samples with Fn <= limit_N."""
    sel = np.isfinite(fn_N) & np.isfinite(isum) & (fn_N <= limit_N)
    x, y = fn_N[sel], isum[sel]
    if x.size < 3 or float(np.ptp(x)) <= 0:
        return LinearFit(math.nan, math.nan, math.nan, math.nan, int(x.size))
    b, a = np.polyfit(x, y, 1)
    fit = a + b * x
    ss_res = float(np.sum((y - fit) ** 2))
    ss_tot = float(np.sum((y - y.mean()) ** 2))
    r2 = 1.0 - ss_res / ss_tot if ss_tot > 0 else math.nan
    err = float(np.max(np.abs(y - fit) / np.abs(fit))) if np.all(fit != 0) else math.nan
    return LinearFit(float(a), float(b), r2, err, int(x.size))


def loading_branches(t_s: FloatArray, fn_N: FloatArray, apart_N: float) -> list[tuple[int, int]]:
    """Sample ranges [a, b) where Fn rises from the apart level to the maximum of its contact.

    One per contact (a stretch above ``apart_N``); the branch ends at the contact's largest Fn, so a
    pre-load overshoot is included and the unloading to the set point is not.
    """
    above = fn_N > apart_N
    m = np.concatenate([[False], above, [False]]).astype(np.int8)
    edges = np.flatnonzero(np.diff(m))
    out: list[tuple[int, int]] = []
    for a, b in zip(edges[0::2], edges[1::2], strict=True):
        if b - a < 8:
            continue
        peak = int(a + np.argmax(fn_N[a:b]))
        start = max(int(a) - 1, 0)
        if peak - start >= 8:
            out.append((start, peak + 1))
    return out
