"""Tangential stiffness along the Ft-delta curve (paper Sec. 3.1, Figs. 6b-d).

* Instantaneous stiffness ``K_I = dFt / d(delta)`` (the paper's K_I = dFt/d delta, the slope of the
  Ft-delta curve), read in ``N_BANDS`` bands of the stick's force rise: it falls across the bands
  in the initial stage, where the contact slips progressively from the back end, and stays flat in
  the stable stage (Figs. 6b, 6c).
* ``K(i)``, the slope of the *initial linear part* of cycle i (Fig. 6d): the same estimator over
  the band ``K_BAND`` of the rise (5-35 % of the way from the stick's start level to its peak).

The estimator (one slope per band), robust to the noise of both signals:

1. the band is a range of **force** (a fraction of the stick's rise), not of time, so a stick that
   is slow or fast is read over the same part of its curve; it starts above the level the stick
   began at (the aliased ringing after the previous slip has died out there);
2. the compliance ``c = d(delta)/dFt`` is the least-squares slope of delta on Ft over all samples in
   the band (Ft is the regressor: its relative noise is the smaller one), refitted once without the
   samples whose residual exceeds 4 robust standard deviations (a probe glitch, a stray sample);
3. Ft carries white noise of RMS ``sigma_f`` (:func:`rigctl.records.signals.noise_sigma`), which
   attenuates a least-squares slope by the reliability ratio ``1 - sigma_f^2 / var(Ft)`` (errors in
   variables; Fuller, *Measurement Error Models*, 1987, Sec. 1.1); ``c`` is divided by it, and a band
   whose force range is under 6 ``sigma_f`` (attenuation above ~10 %) gives NaN;
4. ``K = 1 / c`` with its standard error ``sigma_d / (c^2 sqrt(sum (Ft - mean)^2))`` from the white
   noise ``sigma_d`` of delta (:func:`rigctl.records.signals.slope_se`).

Samples where a displacement probe was over range (:mod:`rigctl.records.probe_range`) are left out;
a band without enough valid samples gives NaN.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rigctl.analysis.stickslip import PassRecord
from rigctl.data import FloatArray
from rigctl.records.signals import noise_sigma, slope_se

N_BANDS = 9
BAND_EDGES: tuple[float, float] = (0.05, 0.95)
K_BAND: tuple[float, float] = (0.05, 0.35)
MIN_BAND_SAMPLES = 8
MIN_RANGE_SIGMAS = 6.0
OUTLIER_SIGMAS = 4.0


@dataclass(frozen=True)
class Slope:
    """A stiffness read from one band of the Ft-delta curve."""

    k_N_per_m: float
    se_N_per_m: float
    ft_mid_N: float
    n: int


NAN_SLOPE = Slope(math.nan, math.nan, math.nan, 0)


def band_stiffness(ft_N: FloatArray, delta_m: FloatArray, sigma_f: float, sigma_d: float) -> Slope:
    """dFt/d(delta) of the samples of one band (the module docstring's estimator)."""
    n = ft_N.shape[0]
    if n < MIN_BAND_SAMPLES or float(np.ptp(ft_N)) < MIN_RANGE_SIGMAS * sigma_f:
        return NAN_SLOPE
    keep = np.ones(n, dtype=bool)
    c = math.nan
    for _ in range(2):
        f, d = ft_N[keep], delta_m[keep]
        if f.shape[0] < MIN_BAND_SAMPLES:  # the outliers left too few (none: a mean of nothing)
            return NAN_SLOPE
        df = f - f.mean()
        sxx = float(df @ df)
        if sxx <= 0.0:
            return NAN_SLOPE
        c = float(df @ (d - d.mean())) / sxx
        resid = delta_m - (d.mean() + c * (ft_N - f.mean()))
        scale = 1.4826 * float(np.median(np.abs(resid - np.median(resid))))
        if scale <= 0.0:
            break
        new_keep = np.abs(resid) <= OUTLIER_SIGMAS * scale
        if np.array_equal(new_keep, keep):
            break
        keep = new_keep
    f = ft_N[keep]
    var_f = float(np.var(f))
    reliability = 1.0 - sigma_f**2 / var_f if var_f > 0 else 0.0
    if reliability <= 0.0 or not math.isfinite(c) or c <= 0.0:
        return NAN_SLOPE
    c /= reliability
    se_c = slope_se(f, sigma_d)
    return Slope(1.0 / c, se_c / (c * c), float(np.mean(f)), int(f.shape[0]))


@dataclass(frozen=True)
class CycleStiffness:
    """Stiffness of one stick: K(i) and the K_I curve."""

    cycle: int
    stage: str
    k: Slope
    """K(i): the initial linear part (K_BAND)."""
    k_inst: tuple[Slope, ...]
    """K_I in the N_BANDS bands of the rise, lowest force first."""
    t_window_s: tuple[float, float]
    """Times of the K(i) band (first and last sample): the window Im(i) averages over."""
    f_start_N: float
    f_peak_N: float


def _stick_window(rec: PassRecord, j: int) -> tuple[int, int, float]:
    """Sample range [a, b) of the stick of cycle j (within the pass) and its start level."""
    c = rec.cycles
    t = rec.run.t_s
    a = int(np.searchsorted(t, c.t_start_s[j]))
    b = int(np.searchsorted(t, c.t_peak_s[j]))
    if j == 0:
        i_m = int(np.searchsorted(t, rec.pas.t_motion_s))
        base = rec.run.ft_N[max(0, i_m - 64) : i_m + 1]
        f0 = float(np.median(base)) if base.size else math.nan
    else:
        f0 = float(c.trough_N[j - 1])
    if not math.isfinite(f0) and b > a:
        f0 = float(np.min(rec.run.ft_N[a:b]))
    return a, b, f0


def _band(ft: FloatArray, f0: float, span: float, lo: float, hi: float) -> np.ndarray:
    return (ft >= f0 + lo * span) & (ft <= f0 + hi * span)


def cycle_stiffness(rec: PassRecord) -> list[CycleStiffness]:
    """K(i) and K_I of every cycle of a pass."""
    run = rec.run
    sigma_f = noise_sigma(run.ft_N)
    delta = run.delta_m
    ok = rec.delta_valid
    sigma_d = noise_sigma(delta[ok]) if ok.any() else 0.0
    edges = np.linspace(BAND_EDGES[0], BAND_EDGES[1], N_BANDS + 1)
    out: list[CycleStiffness] = []
    c = rec.cycles
    for j in range(c.n):
        a, b, f0 = _stick_window(rec, j)
        peak = float(c.peak_N[j])
        span = peak - f0
        if b - a < MIN_BAND_SAMPLES or not math.isfinite(span) or span <= 0:
            out.append(CycleStiffness(j + 1, c.stage[j], NAN_SLOPE, (NAN_SLOPE,) * N_BANDS,
                                      (math.nan, math.nan), f0, peak))
            continue
        ft = run.ft_N[a:b]
        d = delta[a:b]
        valid = ok[a:b]
        sel = _band(ft, f0, span, *K_BAND) & valid
        k = band_stiffness(ft[sel], d[sel], sigma_f, sigma_d)
        idx = np.flatnonzero(_band(ft, f0, span, *K_BAND))
        window = (float(run.t_s[a + idx[0]]), float(run.t_s[a + idx[-1]])) if idx.size \
            else (math.nan, math.nan)
        bands = []
        for lo, hi in zip(edges[:-1], edges[1:], strict=True):
            s = _band(ft, f0, span, lo, hi) & valid
            bands.append(band_stiffness(ft[s], d[s], sigma_f, sigma_d))
        out.append(CycleStiffness(j + 1, c.stage[j], k, tuple(bands), window, f0, peak))
    return out
