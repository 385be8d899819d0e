"""Periodic structure and slip-to-slip correlation in a residual sampled at uneven points.

A residual read once per slip is sampled where the slips fall: unevenly along the track and in time.
Two tests, each on the residual of every run less its own straight line in the covariate (so a trend,
which the residual map reports as a straight line, is not taken for a period):

**A period** (:func:`periodic_test`). The generalised (floating-mean) Lomb-Scargle periodogram of
``scipy.signal.lombscargle`` (Zechmeister & Kuerster, A&A 496, 2009) of each run, summed over the
runs: each run keeps its own phase (where a lead screw or a motor stands at the start of a run is not
known from its record), the period and a common share of the variance are the data's. With the
scatter sigma^2 estimated from the runs' residuals about their lines, ``U(f) = sum_j dRSS_j(f) /
sigma^2`` is chi-square with nu = 2R degrees of freedom at one frequency (R runs, a cosine and a
sine each).

Its false-alarm probability over the frequencies searched is Baluev's (MNRAS 385, 1279, 2008):
``FAP = 1 - F(U) exp(-tau(U))``, F the chi-square CDF at one frequency and tau the expected number of
up-crossings of U over the band (Davies, Biometrika 74, 1987; the Rice formula for a chi-square
process), ``tau = 2 pi df sqrt(2 lambda / pi) U^((nu-1)/2) e^(-U/2) / (2^(nu/2) Gamma(nu/2))`` with
``lambda`` the largest variance of a run's sample positions (for one run this is Baluev's
``W exp(-Z) sqrt(Z)``, W = df sqrt(4 pi Var x); for several runs the largest lambda bounds the
up-crossing rate from above, so the FAP errs high). Baluev's approximation, not a permutation
test: it costs one periodogram, where permutations would need thousands of periodograms to resolve
the small probabilities a correction for many tests asks for (0.01 / 39 ~ 3e-4), and it is accurate
to a few % in the tail that matters (Baluev 2008, Sec. 7; VanderPlas, ApJS 236, 16, 2018, Fig. 15).
scipy has no false-alarm probability for a periodogram; astropy's ``LombScargle.false_alarm_
probability`` has this one for a single series, but astropy is not a dependency and would not sum
runs of their own phase: the formula is the dozen lines of :func:`false_alarm`.

The band searched is what the data can show: from MIN_CYCLES cycles over the longest run's span to
the Nyquist-like limit ``1 / (2 d)`` of the finest run's mean slip spacing d, in steps of
``1 / (OVERSAMPLING * span)``.

**Slip-to-slip correlation** (:func:`lag1_test`): the lag-1 autocorrelation of the residual
sequence within each run (slip order), pooled over runs, less its expectation under no correlation
(the lines removed make it slightly negative); ``z = (r1 - E r1) sqrt(pairs)`` is standard normal
with no correlation (Box & Jenkins' large-sample variance 1/n: the lag-1 Ljung-Box statistic is
z^2).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.signal import lombscargle
from scipy.special import gammaln
from scipy.stats import chi2

from rigctl.records.signals import FloatArray

MIN_CYCLES = 3.0
"""The longest period searched is a third of the longest run's span: with the run's straight line
removed, one or two cycles over a span cannot be told from a bend of a trend."""
OVERSAMPLING = 5.0
"""Frequency steps per periodogram peak width (1 / span): five keep the grid within a few % of the
highest point of any peak (VanderPlas 2018, Sec. 7.1)."""
MAX_FREQUENCIES = 5000
"""Bound on the grid (cost ~ slips x frequencies, about 1 s of one core for 2000 slips): beyond it
the step widens. At five steps per peak width this is reached for runs of more than 2000 slips;
at 4000 it is 2.5 steps, which still keeps a peak within 20 % of its height."""
CHUNK_ELEMENTS = 1_000_000
"""Slips x frequencies per call of ``lombscargle`` (its temporaries are arrays of this size, 8 MB
each): memory stays bounded on long records."""
MIN_SLIPS = 10
"""A run takes part with at least this many residuals: a line and a sinusoid are four parameters,
and fewer than twice that leave too little to judge them by."""


@dataclass(frozen=True)
class RunFit:
    """One run's residual against the covariate and its fitted sinusoid (at the common period)."""

    x: FloatArray
    y: FloatArray
    """The residual less the run's straight line in x."""
    cos: float
    sin: float
    """y ~ cos * cos(2 pi x / period) + sin * sin(2 pi x / period) + const."""
    const: float

    @property
    def amplitude(self) -> float:
        return math.hypot(self.cos, self.sin)


@dataclass(frozen=True)
class PeriodicFit:
    period: float
    """In the covariate's unit."""
    fap: float
    """Single-test false-alarm probability of the highest peak over the band searched."""
    statistic: float
    """U at the peak (chi-square with 2R degrees of freedom at one frequency)."""
    runs: tuple[RunFit, ...]

    def seen_amplitude(self, run: RunFit) -> float:
        """The run's semi-amplitude as its slips show it: sqrt 2 times the RMS, over the run's
        slips, of its fitted sinusoid less its mean. Where the run spans whole periods this is
        ``run.amplitude``; where it spans a fraction of one, the cosine, the sine, the constant
        and the straight line removed are nearly collinear there and the coefficients can take
        any size (their sum still fits the slips), so the coefficients' amplitude says nothing
        while this stays within what the slips show (at most sqrt 2 times their RMS: the fit
        is a projection of the residual)."""
        w = 2 * np.pi / self.period
        wave = run.cos * np.cos(w * run.x) + run.sin * np.sin(w * run.x)
        return math.sqrt(2.0) * float(np.std(wave))

    @property
    def amplitude(self) -> float:
        """Semi-amplitude: the RMS over slips of the runs' semi-amplitudes as their slips show
        them (:meth:`seen_amplitude`; in y's unit)."""
        n = np.array([r.x.size for r in self.runs], dtype=np.float64)
        a = np.array([self.seen_amplitude(r) for r in self.runs])
        return float(np.sqrt(np.sum(n * a**2) / np.sum(n)))


def _less_line(x: FloatArray, y: FloatArray) -> FloatArray:
    a = np.column_stack([np.ones_like(x), x - x.mean()])
    coef, *_ = np.linalg.lstsq(a, y, rcond=None)
    out: FloatArray = y - a @ coef
    return out


def usable(xs: Sequence[FloatArray], ys: Sequence[FloatArray]) -> list[tuple[FloatArray, FloatArray]]:
    """The runs' finite (x, y) pairs, sorted by x, of runs with at least MIN_SLIPS of them and a
    span of x."""
    out: list[tuple[FloatArray, FloatArray]] = []
    for x, y in zip(xs, ys, strict=True):
        ok = np.isfinite(x) & np.isfinite(y)
        if np.count_nonzero(ok) < MIN_SLIPS or float(np.ptp(x[ok])) <= 0:
            continue
        order = np.argsort(x[ok], kind="stable")
        out.append((x[ok][order], y[ok][order]))
    return out


def frequency_band(xs: Sequence[FloatArray]) -> FloatArray:
    """Frequencies (cycles per unit of x) the runs can show (module docstring); empty if none."""
    spans = [float(np.ptp(x)) for x in xs]
    spacing = min(s / (x.size - 1) for s, x in zip(spans, xs, strict=True))
    f_lo, f_hi = MIN_CYCLES / max(spans), 0.5 / spacing
    if f_hi <= f_lo:
        return np.zeros(0)
    n = int(min(MAX_FREQUENCIES, math.ceil((f_hi - f_lo) * OVERSAMPLING * max(spans)) + 1))
    return np.linspace(f_lo, f_hi, n)


def false_alarm(u: float, nu: int, band: float, lam: float) -> float:
    """Baluev's (2008) false-alarm probability of a peak U of a chi-square(nu) periodogram over a
    band of ``band`` cycles per unit, the sample positions' variance ``lam`` (module docstring)."""
    if u <= 0:
        return 1.0
    log_tau = (math.log(2 * math.pi * band) + 0.5 * math.log(2 * lam / math.pi)
               + 0.5 * (nu - 1) * math.log(u) - 0.5 * u - 0.5 * nu * math.log(2.0)
               - float(gammaln(0.5 * nu)))
    log_keep = float(chi2.logcdf(u, nu)) - math.exp(log_tau)
    return float(-math.expm1(log_keep))


def periodic_test(xs: Sequence[FloatArray], ys: Sequence[FloatArray]) -> PeriodicFit | None:
    """The strongest period of ``ys`` (one array per run) against ``xs`` and its false-alarm
    probability (module docstring); None where no run has enough residuals or the band is empty."""
    runs = usable(xs, ys)
    if not runs:
        return None
    freqs = frequency_band([x for x, _ in runs])
    if freqs.size == 0:
        return None
    detrended = [(x, _less_line(x, y)) for x, y in runs]
    n_total = sum(x.size for x, _ in runs)
    dof = n_total - 2 * len(runs)
    rss0 = sum(float(y @ y) for _, y in detrended)
    if dof <= 0 or rss0 <= 0:
        return None
    sigma2 = rss0 / dof
    drss = np.zeros_like(freqs)
    for x, y in detrended:
        step = max(1, CHUNK_ELEMENTS // x.size)
        for i in range(0, freqs.size, step):
            # unnormalised floating-mean power is half the fall of the residual sum of squares
            drss[i:i + step] += 2.0 * lombscargle(x - x[0], y, 2 * np.pi * freqs[i:i + step],
                                                  floating_mean=True)
    u = drss / sigma2
    k = int(np.argmax(u))
    f = float(freqs[k])
    nu = 2 * len(runs)
    lam = max(float(np.var(x)) for x, _ in runs)
    fap = false_alarm(float(u[k]), nu, float(freqs[-1] - freqs[0]), lam)
    fits = []
    for x, y in detrended:
        a = np.column_stack([np.cos(2 * np.pi * f * x), np.sin(2 * np.pi * f * x), np.ones_like(x)])
        c, *_ = np.linalg.lstsq(a, y, rcond=None)
        fits.append(RunFit(x, y, float(c[0]), float(c[1]), float(c[2])))
    return PeriodicFit(1.0 / f, fap, float(u[k]), tuple(fits))


def sinusoid(fit: PeriodicFit, run: RunFit, x: FloatArray) -> FloatArray:
    """The fitted sinusoid of ``run`` at ``x``."""
    w = 2 * np.pi / fit.period
    out: FloatArray = run.cos * np.cos(w * x) + run.sin * np.sin(w * x) + run.const
    return out


def refit(fit: PeriodicFit, xs: Sequence[FloatArray], ys: Sequence[FloatArray]) -> PeriodicFit:
    """The same period fitted to other values at the same points (the physical residual where the
    test ran on the scaled one): each run's sinusoid less its straight line."""
    runs = usable(xs, ys)
    w = 2 * np.pi / fit.period
    fits = []
    for x, y in runs:
        y = _less_line(x, y)
        a = np.column_stack([np.cos(w * x), np.sin(w * x), np.ones_like(x)])
        c, *_ = np.linalg.lstsq(a, y, rcond=None)
        fits.append(RunFit(x, y, float(c[0]), float(c[1]), float(c[2])))
    return PeriodicFit(fit.period, fit.fap, fit.statistic, tuple(fits))


@dataclass(frozen=True)
class Lag1:
    r1: float
    """Pooled lag-1 autocorrelation of the runs' residuals less their lines."""
    p: float
    """Two-sided probability of |z| this large with no correlation."""


def lag1_test(ts: Sequence[FloatArray], ys: Sequence[FloatArray]) -> Lag1 | None:
    """Slip-to-slip correlation of ``ys`` (slips in the order of ``ts``, one array per run): module
    docstring. None where no run has enough residuals."""
    runs = usable(ts, ys)
    if not runs:
        return None
    num = den = expected_num = 0.0
    pairs = 0
    for t, y in runs:
        e = _less_line(t, y)
        num += float(e[:-1] @ e[1:])
        den += float(e @ e)
        # E[e_i e_i+1] = -sigma^2 H[i+1, i] for e = (I - H) noise: the line's hat matrix H
        a = np.column_stack([np.ones_like(t), t - t.mean()])
        inv = np.linalg.inv(a.T @ a)
        expected_num -= float(np.sum((a[1:] @ inv) * a[:-1]))
        pairs += t.size - 1
    if den <= 0:
        return None
    dof = sum(t.size for t, _ in runs) - 2 * len(runs)
    r1 = num / den
    z = (r1 - expected_num / dof) * math.sqrt(pairs)
    return Lag1(r1, math.erfc(abs(z) / math.sqrt(2.0)))
