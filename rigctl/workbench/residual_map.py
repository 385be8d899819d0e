"""Where a model fails: residuals located in time, by stage, by phase and against covariates.

Inputs are the event-level comparisons of :mod:`rigctl.workbench.metrics`. Every per-event residual
is taken in units of the feature's measured scatter (z). The map has four views:

* by **time**: mean z of each feature in tenths of each run;
* by **stage**: mean z over initial-stage events (the slip that ends loading from rest) and over
  stable events;
* by **phase**: stick-phase features (peak, loading rate, K(i), rounding, recurrence, probe lag) and
  slip-phase features (drop, trough, ringing, sharpness, slip, drop delay, Fn swing) - a compact
  view of whether the model fails while the interface sticks or while it slips;
* against **covariates** (drive velocity, hold and stick time, Fn, cycle number, cumulative slip,
  Ft, dFt/dt, time): for every feature and covariate a straight-line fit z = a + b g(c), with
  g = ln for positive covariates spanning more than a decade (hold and stick times, velocities),
  giving the trend's amplitude (b times the spread of g, in z) and its t statistic;
* **beyond a straight line** (:attr:`ResidualMap.patterns`, :attr:`ResidualMap.correlations`,
  computed when first read): a period against the slider's position along the track (its
  cumulative slip in the run) and against time, and a correlation from slip to slip
  (:mod:`rigctl.workbench.periodic`), each at a false-alarm probability of FAP_LEVEL over all the
  tests of the map.

:func:`discrepancies` turns the strongest structures into sentences such as "peaks after long
holds are under-predicted by 3.1 N, growing with log stick time", the patterns first: "peaks rise
and fall by +-0.5 N with a period of about 40 um of track".
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from rigctl.records.dataset import Dataset
from rigctl.records.feature_info import FEATURES
from rigctl.records.features import COVARIATES, EVENT_FEATURES
from rigctl.records.signals import FloatArray
from rigctl.workbench.metrics import RunComparison
from rigctl.workbench.periodic import PeriodicFit, lag1_test, periodic_test, refit

STICK_FEATURES = ("peak_N", "stick_s", "rate_N_per_s", "k_stick_N_per_m", "rounding", "lag_m")
SLIP_FEATURES = ("trough_N", "drop_N", "ring_N", "step_frac", "slip_m", "drop_delay_s",
                 "fn_swing_N")

COVARIATE_NAMES: dict[str, str] = {
    "t_s": "time",
    "cycle": "cycle number",
    "fn_N": "Fn",
    "v_drive_m_per_s": "drive velocity",
    "hold_s": "hold time",
    "stick_time_s": "stick time",
    "cum_slip_m": "cumulative slip",
    "ft_N": "Ft",
    "dft_dt_N_per_s": "dFt/dt",
    "x_drive_m": "position along the track",
}
HIGH_END: dict[str, str] = {
    "t_s": "late in the run", "cycle": "in later cycles", "fn_N": "at high Fn",
    "v_drive_m_per_s": "at high drive velocity", "hold_s": "after long holds",
    "stick_time_s": "after long sticks", "cum_slip_m": "after much slip", "ft_N": "at high Ft",
    "dft_dt_N_per_s": "at fast loading", "x_drive_m": "further along the track",
}
LOW_END: dict[str, str] = {
    "t_s": "early in the run", "cycle": "in the first cycles", "fn_N": "at low Fn",
    "v_drive_m_per_s": "at low drive velocity", "hold_s": "after short holds",
    "stick_time_s": "after short sticks", "cum_slip_m": "before much slip", "ft_N": "at low Ft",
    "dft_dt_N_per_s": "at slow loading", "x_drive_m": "near the track's start",
}

TREND_T_MIN = 3.0  # t statistic a residual trend needs to be reported (about p < 0.003)
TREND_AMPLITUDE_MIN = 1.0  # and an amplitude of one scatter unit: smaller is not worth words


@dataclass(frozen=True)
class Trend:
    feature: str
    covariate: str
    log: bool
    amplitude_z: float
    """b * std(g(c)): how far the trend moves the residual across the data, in scatter units."""
    t_stat: float
    n: int
    slope: float
    """dz / dg"""


PATTERN_COVARIATES: dict[str, str] = {"x_drive_m": "of track", "t_s": ""}
"""Covariates searched for a period, with the words after its period: the slider's position along
the track (the drive's position at the slip, :data:`rigctl.records.features.COVARIATES`) and
time."""
FAP_LEVEL = 0.01
"""False-alarm probability of a reported pattern or correlation over all the tests of one map
(Bonferroni: each test's own at FAP_LEVEL / number of tests), so that a model within the scatter
gets a made-up pattern in at most about 1 map of 100."""


@dataclass(frozen=True)
class Pattern:
    """A period in a feature's residual (:mod:`rigctl.workbench.periodic`)."""

    feature: str
    covariate: str
    fit: PeriodicFit
    """Fitted to the physical residual (the feature's unit; ln for ratio features)."""
    amplitude_z: float
    """Semi-amplitude in scatter units."""
    fap: float
    """False-alarm probability over all the map's tests."""


@dataclass(frozen=True)
class Correlation:
    """A slip-to-slip correlation of a feature's residual within runs."""

    feature: str
    r1: float
    p: float
    """False-alarm probability over all the map's tests."""


@dataclass
class ResidualMap:
    by_time: dict[str, FloatArray]
    """Mean z per feature in ten time bins (all runs' relative times pooled)."""
    by_stage: dict[str, dict[str, float]]
    """{"initial": {feature: mean z}, "stable": {...}}"""
    by_phase: dict[str, float]
    """RMS z of stick-phase and slip-phase features."""
    trends: list[Trend]
    bias: dict[str, tuple[float, float]]
    """Per feature: (mean z, t statistic of the mean)."""
    table: dict[str, dict[str, FloatArray]]
    """Per feature: z and the physical residual of every event ("z", "r"), each covariate and the
    run it belongs to ("run")."""

    @cached_property
    def structure(self) -> tuple[list[Pattern], list[Correlation]]:
        """Periods and slip-to-slip correlations above FAP_LEVEL (module docstring), most
        significant first."""
        return find_structure(self.table)

    @property
    def patterns(self) -> list[Pattern]:
        return self.structure[0]

    @property
    def correlations(self) -> list[Correlation]:
        return self.structure[1]


def _event_table(dataset: Dataset, comps: list[RunComparison]) -> dict[str, dict[str, FloatArray]]:
    out: dict[str, dict[str, FloatArray]] = {}
    for name in EVENT_FEATURES:
        r = np.concatenate([c.like_for_like(name) for c in comps]) if comps else np.zeros(0)
        sig = np.concatenate([dataset.event_sigma(i, name) for i in range(len(dataset.runs))]) \
            if comps else np.zeros(0)
        cols: dict[str, FloatArray] = {"r": r, "z": r / sig}
        for cov in COVARIATES:
            cols[cov] = np.concatenate([run.events.covariates[cov] for run in dataset.runs])
        cols["stage"] = np.concatenate([run.events.stage.astype(float) for run in dataset.runs])
        cols["run"] = np.concatenate([np.full(run.events.n, float(i))
                                      for i, run in enumerate(dataset.runs)])
        cols["t_frac"] = np.concatenate(
            [run.events.t_drop_s / max(run.n_samples / run.sample_rate_hz, 1e-9)
             for run in dataset.runs]
        )
        out[name] = cols
    return out


LOG_SPAN = 5.0  # a covariate spanning more than a factor 5 is regressed on its logarithm


def transform(c: FloatArray) -> tuple[FloatArray, bool]:
    """ln for non-negative covariates whose positive values span more than LOG_SPAN (zeros, e.g.
    no hold, sit half the smallest positive value below it), the covariate itself otherwise."""
    pos = c[c > 0]
    if np.all(c >= 0) and pos.size >= 2 and pos.max() / pos.min() > LOG_SPAN:
        shift = 0.5 * float(pos.min()) if pos.size < c.size else 0.0
        return np.log(c + shift), True
    return c, False


def _trend(z: FloatArray, c: FloatArray) -> tuple[bool, float, float, float, int] | None:
    ok = np.isfinite(z) & np.isfinite(c)
    if np.count_nonzero(ok) < 6:
        return None
    z, c = z[ok], c[ok]
    g, log = transform(c)
    sg = float(np.std(g))
    if sg <= 0 or float(np.ptp(g)) <= 1e-12 * (abs(float(np.mean(g))) + 1e-300):
        return None
    gc = (g - g.mean()) / sg
    slope_std = float(gc @ (z - z.mean())) / float(gc @ gc)
    resid = z - z.mean() - slope_std * gc
    n = z.size
    s2 = float(resid @ resid) / max(n - 2, 1)
    se = math.sqrt(s2 / float(gc @ gc)) if s2 > 0 else 0.0
    t = slope_std / se if se > 0 else (math.inf if slope_std != 0 else 0.0)
    return log, slope_std, t, slope_std / sg, n


def residual_map(dataset: Dataset, comps: list[RunComparison]) -> ResidualMap:
    table = _event_table(dataset, comps)
    by_time: dict[str, FloatArray] = {}
    by_stage: dict[str, dict[str, float]] = {"initial": {}, "stable": {}}
    trends: list[Trend] = []
    bias: dict[str, tuple[float, float]] = {}
    for name, cols in table.items():
        z = cols["z"]
        ok = np.isfinite(z)
        bins = np.clip((cols["t_frac"] * 10).astype(int), 0, 9)
        by_time[name] = np.array(
            [float(np.mean(z[ok & (bins == b)])) if np.any(ok & (bins == b)) else np.nan
             for b in range(10)]
        )
        for label, val in (("initial", 0.0), ("stable", 1.0)):
            sel = ok & (cols["stage"] == val)
            by_stage[label][name] = float(np.mean(z[sel])) if sel.any() else float("nan")
        if ok.sum() >= 2:
            m = float(np.mean(z[ok]))
            sd = float(np.std(z[ok], ddof=1))
            # all residuals equal: no scatter to judge them by; a bias of 0 is none at all
            flat = math.copysign(math.inf, m) if m != 0 else 0.0
            bias[name] = (m, m / (sd / math.sqrt(ok.sum())) if sd > 0 else flat)
        for cov in COVARIATES:
            res = _trend(z, cols[cov])
            if res is None:
                continue
            log, amp, t, slope, n = res
            trends.append(Trend(name, cov, log, abs(amp), t, n, slope))
    by_phase = {}
    for label, names in (("stick", STICK_FEATURES), ("slip", SLIP_FEATURES)):
        zs = np.concatenate([table[n]["z"] for n in names])
        zs = zs[np.isfinite(zs)]
        by_phase[label] = float(np.sqrt(np.mean(zs**2))) if zs.size else float("nan")
    trends.sort(key=lambda tr: tr.amplitude_z, reverse=True)
    return ResidualMap(by_time, by_stage, by_phase, trends, bias, table)


def _by_run(cols: dict[str, FloatArray], key: str) -> list[FloatArray]:
    runs = cols["run"]
    return [cols[key][runs == i] for i in np.unique(runs)]


def find_structure(table: dict[str, dict[str, FloatArray]]
                   ) -> tuple[list[Pattern], list[Correlation]]:
    """Per feature the strongest period against each of PATTERN_COVARIATES and the slip-to-slip
    correlation of its z residuals; kept where the false-alarm probability times the number of
    tests run is at most FAP_LEVEL and the structure is as large as a trend must be
    (TREND_AMPLITUDE_MIN: a sinusoid's RMS, amplitude / sqrt 2, or the RMS of the part the previous
    slip predicts, r1 times the residual's RMS, at least one scatter unit). A feature keeps its
    strongest period only."""
    found: list[tuple[str, str, PeriodicFit]] = []
    lags: list[tuple[str, float, float]] = []
    n_tests = 0
    for name, cols in table.items():
        zs = _by_run(cols, "z")
        for cov in PATTERN_COVARIATES:
            fit = periodic_test(_by_run(cols, cov), zs)
            if fit is not None:
                n_tests += 1
                found.append((name, cov, fit))
        lag = lag1_test(_by_run(cols, "t_s"), zs)
        if lag is not None:
            n_tests += 1
            z = np.concatenate(zs)
            rms = float(np.sqrt(np.nanmean((z - np.nanmean(z)) ** 2)))
            if abs(lag.r1) * rms >= TREND_AMPLITUDE_MIN:
                lags.append((name, lag.r1, lag.p))
    patterns: list[Pattern] = []
    for name, cov, fit in sorted(found, key=lambda f: f[2].fap):
        fap = min(1.0, fit.fap * n_tests)
        if fap > FAP_LEVEL or fit.amplitude / math.sqrt(2) < TREND_AMPLITUDE_MIN \
                or any(p.feature == name for p in patterns):
            continue
        cols = table[name]
        phys = refit(fit, _by_run(cols, cov), _by_run(cols, "r"))
        patterns.append(Pattern(name, cov, phys, fit.amplitude, fap))
    correlations = [Correlation(name, r1, min(1.0, p * n_tests))
                    for name, r1, p in sorted(lags, key=lambda c: c[2])
                    if p * n_tests <= FAP_LEVEL]
    return patterns, correlations


FACTOR_FROM = 3.0
"""A ratio feature off by this factor or more is said as "by a factor of N", not in percent."""


def _amount(name: str, r: FloatArray) -> str:
    return _size(name, float(np.mean(r)))


def _size(name: str, m: float) -> str:
    """A residual of ``m`` (the feature's unit; ln for ratio features) in words, without sign."""
    info = FEATURES[name]
    if info.log:
        if abs(m) >= math.log(FACTOR_FROM):  # "36265 %" says less than "a factor of 364"
            return f"a factor of {math.exp(abs(m)):.3g}"
        return f"{abs(math.expm1(m)) * 100:.0f} %"
    unit = info.unit
    if unit == "m":
        return f"{abs(m) * 1e6:.2g} um"
    if unit == "s":  # a delay (durations are ratios, above)
        return f"{abs(m) * 1e3:.2g} ms"
    if unit == "-":
        return f"{abs(m):.2g}"
    return f"{abs(m):.2g} {unit}"


def _verb(mean_residual: float) -> str:
    """Residuals are model - measured: negative means the model predicts too little."""
    return "under-predicted" if mean_residual < 0 else "over-predicted"


def trend_matrix(rmap: ResidualMap) -> FloatArray:
    """Signed trend amplitude (z) of every slip feature (rows, :data:`EVENT_FEATURES`) against every
    covariate (columns, :data:`COVARIATES`); 0 where |t| < TREND_T_MIN (the residual-map picture of
    the report and of the GUI)."""
    amp = np.zeros((len(EVENT_FEATURES), len(COVARIATES)))
    for tr in rmap.trends:
        if abs(tr.t_stat) >= TREND_T_MIN:
            amp[EVENT_FEATURES.index(tr.feature), COVARIATES.index(tr.covariate)] = (
                np.sign(tr.slope) * tr.amplitude_z)
    return amp


def significant_trends(rmap: ResidualMap) -> list[Trend]:
    return [
        t for t in rmap.trends
        if abs(t.t_stat) >= TREND_T_MIN and t.amplitude_z >= TREND_AMPLITUDE_MIN
    ]


def _period(cov: str, period: float) -> str:
    if cov == "t_s":
        return f"{period:.2g} s"
    if period < 1e-3:
        return f"{period * 1e6:.2g} um"
    return f"{period * 1e3:.2g} mm"


def pattern_text(p: Pattern) -> str:
    """"peaks rise and fall by +-0.52 N with a period of about 40 um of track (false-alarm
    probability 1e-06)"."""
    where = PATTERN_COVARIATES[p.covariate]
    period = _period(p.covariate, p.fit.period) + (f" {where}" if where else "")
    return (f"{FEATURES[p.feature].phrase} rise and fall by +-{_size(p.feature, p.fit.amplitude)} "
            f"with a period of about {period} (false-alarm probability {p.fap:.1g})")


def correlation_text(c: Correlation) -> str:
    how = "are correlated" if c.r1 > 0 else "alternate"
    return (f"{FEATURES[c.feature].phrase} {how} from slip to slip (lag-1 autocorrelation "
            f"{c.r1:.2f} within runs, false-alarm probability {c.p:.1g})")


def discrepancies(rmap: ResidualMap, limit: int = 5) -> list[str]:
    """The largest structured discrepancies, in words: periods first (a straight-line trend they
    cause follows them), then slip-to-slip correlations, then trends and biases, strongest first.
    A feature's period or correlation stands for its own straight-line trends (which a sinusoid over
    a few cycles makes); its bias, which neither says, may follow."""
    structured = [pattern_text(p) for p in rmap.patterns]
    used: set[str] = {p.feature for p in rmap.patterns}
    for cor in rmap.correlations:
        if cor.feature not in used:
            used.add(cor.feature)
            structured.append(correlation_text(cor))
    candidates: list[tuple[float, str]] = []
    trended: set[str] = set()
    for tr in significant_trends(rmap):
        if tr.feature in used or tr.feature in trended:
            continue
        trended.add(tr.feature)
        cols = rmap.table[tr.feature]
        z, r, c = cols["z"], cols["r"], cols[tr.covariate]
        ok = np.isfinite(z) & np.isfinite(c)
        lo_q, hi_q = np.quantile(c[ok], [1 / 3, 2 / 3])
        high = ok & (c >= hi_q)
        low = ok & (c <= lo_q)
        m_high = float(np.mean(r[high])) if high.any() else 0.0
        m_low = float(np.mean(r[low])) if low.any() else 0.0
        at_high = abs(m_high) >= abs(m_low)
        sel = high if at_high else low
        where = (HIGH_END if at_high else LOW_END)[tr.covariate]
        m = m_high if at_high else m_low
        cov = ("log " if tr.log else "") + COVARIATE_NAMES[tr.covariate]
        phrase = FEATURES[tr.feature].phrase
        z_high = float(np.mean(z[high])) if high.any() else 0.0
        z_low = float(np.mean(z[low])) if low.any() else 0.0
        if z_high * z_low < 0 and min(abs(z_high), abs(z_low)) >= TREND_AMPLITUDE_MIN:
            drift = "up" if tr.slope < 0 else "down"
            text = (f"{phrase} drift {drift} with {cov} relative to the model: "
                    f"{_verb(m_low)} by {_amount(tr.feature, r[low])} {LOW_END[tr.covariate]}, "
                    f"{_verb(m_high)} by {_amount(tr.feature, r[high])} "
                    f"{HIGH_END[tr.covariate]}")
        else:
            grows = "growing" if (tr.slope > 0) == (m > 0) else "shrinking"
            text = (f"{phrase} {where} are {_verb(m)} by "
                    f"{_amount(tr.feature, r[sel])}, {grows} with {cov}")
        candidates.append((tr.amplitude_z * abs(tr.t_stat) ** 0.5, text))
    for name, (mz, t) in rmap.bias.items():
        # a period or a correlation leaves the mean to be said; a trend says it
        if name in trended or abs(t) < TREND_T_MIN or abs(mz) < TREND_AMPLITUDE_MIN:
            continue
        r = rmap.table[name]["r"]
        r = r[np.isfinite(r)]
        text = f"{FEATURES[name].phrase} are {_verb(float(np.mean(r)))} by {_amount(name, r)} " \
            "throughout"
        candidates.append((abs(mz) * abs(t) ** 0.5, text))
    candidates.sort(key=lambda x: x[0], reverse=True)
    return (structured + [text for _, text in candidates])[:limit]
