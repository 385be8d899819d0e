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

A **repetition** with images is one loading of the specimen (:class:`Loading`): a stretch where the
measured Fn stays above the apart level (an NLRE loading to 500 N; a TLRE loading to 300 N with its
slide). Within a run, its loadings are the repetitions (:func:`loadings`, :func:`image_repeatability`);
across the runs of one protocol, each run is one, its value the mean over its loadings.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rigctl.data import FloatArray

FIT_LIMIT_N = 300.0
PEAK_REACHED = 0.99
"""A loading branch ends where Fn first reaches this fraction of its contact's largest Fn."""


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


def contacts(fn_N: FloatArray, apart_N: float, min_samples: int = 8) -> list[tuple[int, int]]:
    """Sample ranges [a, b) where Fn stays above ``apart_N`` (at least ``min_samples`` long)."""
    above = fn_N > apart_N
    m = np.concatenate([[False], above, [False]]).astype(np.int8)
    edges = np.flatnonzero(np.diff(m))
    return [(int(a), int(b)) for a, b in zip(edges[0::2], edges[1::2], strict=True)
            if b - a >= min_samples]


def _peak_reached(fn_N: FloatArray) -> int:
    """First index where Fn reaches ``PEAK_REACHED`` of its largest value (not a later noise peak
    of the plateau: a TLRE slides at that load, and its contact changes while Fn does not)."""
    top = float(np.max(fn_N))
    return int(np.argmax(fn_N >= PEAK_REACHED * top))


def loading_branches(t_s: FloatArray, fn_N: FloatArray, apart_N: float) -> list[tuple[int, int]]:
    """Sample ranges [a, b) where Fn rises from the apart level to the maximum of its contact.

    One per contact (a stretch above ``apart_N``); the branch ends where Fn first reaches
    ``PEAK_REACHED`` of the contact's largest Fn, so a pre-load overshoot is included and the
    unloading to the set point, or a slide at the load, is not.
    """
    out: list[tuple[int, int]] = []
    for a, b in contacts(fn_N, apart_N):
        peak = a + _peak_reached(fn_N[a:b])
        start = max(a - 1, 0)
        if peak - start >= 8:
            out.append((start, peak + 1))
    return out


@dataclass(frozen=True)
class Loading:
    """One loading of the specimen seen by the camera: a repetition of the NLRE or TLRE."""

    t_start_s: float
    t_peak_s: float
    """When Fn first reaches ``PEAK_REACHED`` of its largest (the loading branch is start..peak)."""
    t_end_s: float
    fn_max_N: float
    n_frames: int
    isum_max: float
    """Largest Isum (Eq. 1) of its frames."""
    ic_max: float
    """Largest contact intensity Ic (dark field subtracted)."""
    fit: LinearFit
    """Isum = a + b Fn over the loading branch's frames with Fn <= ``FIT_LIMIT_N``."""

    def to_dict(self) -> dict[str, object]:
        f = self.fit
        return {"t_start_s": self.t_start_s, "t_peak_s": self.t_peak_s, "t_end_s": self.t_end_s,
                "fn_max_N": self.fn_max_N, "frames": self.n_frames, "isum_max": self.isum_max,
                "ic_max": self.ic_max, "fit_slope_per_N": f.slope, "fit_intercept": f.intercept,
                "fit_r2": f.r2, "fit_error": f.fit_error, "fit_frames": f.n}


def loadings(t_s: FloatArray, fn_N: FloatArray, apart_N: float, t_frames_s: FloatArray,
             fn_frames_N: FloatArray, isum: FloatArray, ic: FloatArray,
             limit_N: float = FIT_LIMIT_N) -> list[Loading]:
    """The loadings of a run (contacts of the force record) with at least 3 finite frames each."""
    out: list[Loading] = []
    for a, b in contacts(fn_N, apart_N):
        t_a, t_b = float(t_s[a]), float(t_s[b - 1])
        t_pk = float(t_s[a + _peak_reached(fn_N[a:b])])
        inside = (t_frames_s >= t_a) & (t_frames_s <= t_b) & np.isfinite(isum)
        if np.count_nonzero(inside) < 3:
            continue
        branch = inside & (t_frames_s <= t_pk)
        out.append(Loading(t_a, t_pk, t_b, float(np.max(fn_N[a:b])), int(np.count_nonzero(inside)),
                           float(np.max(isum[inside])), float(np.max(ic[inside])),
                           linear_fit(fn_frames_N[branch], isum[branch], limit_N)))
    return out


def image_repeatability(reps: list[Loading], limit_N: float = FIT_LIMIT_N) -> list[Repeated]:
    """Relative errors of max Isum and of the Isum-Fn slope over the loadings ([] under two)."""
    if len(reps) < 2:
        return []
    return [
        Repeated.of("max Isum", "grey levels", [r.isum_max for r in reps],
                    ic_max=[r.ic_max for r in reps]),
        Repeated.of(f"Isum-Fn slope below {limit_N:.0f} N", "grey levels/N",
                    [r.fit.slope for r in reps], r2=[r.fit.r2 for r in reps],
                    fit_error=[r.fit.fit_error for r in reps],
                    fit_frames=[float(r.fit.n) for r in reps]),
    ]


@dataclass(frozen=True)
class RunRepeat:
    """What one run contributes as a repetition across runs: means over its own repetitions."""

    run: str
    max_ft_N: float
    """Mean over the run's passes of their largest cycle peak (NaN without a pass)."""
    isum_max: float
    """Mean over the run's loadings of their max Isum (NaN without frames)."""
    slope_per_N: float
    """Mean over the run's loadings of their Isum-Fn slope below ``FIT_LIMIT_N``."""

    @staticmethod
    def of(run: str, max_ft_N: list[float], reps: list[Loading]) -> RunRepeat:
        def mean(v: list[float]) -> float:
            a = np.array(v, dtype=np.float64)
            a = a[np.isfinite(a)]
            return float(np.mean(a)) if a.size else math.nan

        return RunRepeat(run, mean(max_ft_N), mean([r.isum_max for r in reps]),
                         mean([r.fit.slope for r in reps]))


@dataclass(frozen=True)
class RepeatGroup:
    """Runs of one protocol with the same parameters: the repetitions of Sec. 2.2 across runs."""

    protocol: str
    parameters: dict[str, Any]
    runs: tuple[str, ...]
    quantities: list[Repeated]

    def to_dict(self) -> dict[str, object]:
        return {"protocol": self.protocol, "parameters": self.parameters, "runs": list(self.runs),
                "quantities": [q.to_dict() for q in self.quantities]}


def repeat_group(protocol: str, parameters: dict[str, Any], runs: list[RunRepeat],
                 limit_N: float = FIT_LIMIT_N) -> RepeatGroup:
    """Relative errors across runs of max Ft, max Isum and the Isum-Fn slope (those measured)."""
    qs: list[Repeated] = []
    for name, unit, vals in (
            ("max Ft", "N", [r.max_ft_N for r in runs]),
            ("max Isum", "grey levels", [r.isum_max for r in runs]),
            (f"Isum-Fn slope below {limit_N:.0f} N", "grey levels/N",
             [r.slope_per_N for r in runs])):
        if np.count_nonzero(np.isfinite(vals)) >= 2:
            qs.append(Repeated.of(name, unit, vals))
    return RepeatGroup(protocol, dict(parameters), tuple(r.run for r in runs), qs)
