"""Post-slip ringing: the slider's free vibration in stick, read from the measured force.

After a slip the specimen sticks again and, held between the drive spring K0 and the stuck
interface Kts, rings as a viscously damped oscillator: ``omega_n^2 = (K0 + Kts) / M`` and decay
rate ``sigma = (C0 + C_int) / (2 M)`` (the stick phase of the engine,
``rigctl/model/kernel/fast_stick.py``: ``wn = sqrt(kk / m)``, ``kk = k0 + kst``, ``cc = c0 +
c_int``). Its free response on the loading line is ``a + b t + A exp(-sigma t) cos(omega_d t +
phi)`` with ``omega_n^2 = omega_d^2 + sigma^2`` (Rao, *Mechanical Vibrations*, 5th ed., Sec.
2.6.2). Where the sampling resolves it, the ringing gives the mass and the damping of a model of
another rig (:mod:`rigctl.workbench.data_scale`); elsewhere they stay guesses.

The ringing is **resolved** in a slip when the damped sinusoid fitted after it (a least-squares fit,
:func:`scipy.optimize.curve_fit`, started at the line-detrended window's spectral peak):

* has at least MIN_SAMPLES_PER_CYCLE samples per cycle;
* stands MIN_SNR times above the white noise and stays above it for MIN_CYCLES cycles;
* has its frequency to within MAX_FREQ_SE;
* is not an alias. During a slip the elements slide and the mass swings on the drive spring alone,
  more slowly than in stick (omega_slip^2 = K0/M < omega_n^2): Ft falls along a half cosine,
  ``F_k + drop cos(omega_slip t)``, from the peak to half-way down in a quarter slip period, and
  by at most ``drop * omega_slip * dt`` in one sample. So the slip's steepest one-sample fall is at
  most ``2 pi f dt`` of its drop (``step_frac``, :mod:`rigctl.records.features`), and its
  peak-to-half-way time at least a quarter ringing period (ALIAS_SLACK allows for the peak sample
  read late on a rounded top). A slip over within a sample followed by a ringing of ten samples
  per cycle is a kilohertz ringing folded down by the sampling (this rig's own: about 1.1 kHz at
  1024 Hz), which says nothing about the mass.

A campaign's ringing is resolved when at least MIN_RESOLVED_FRACTION of the slips tried (and
MIN_RESOLVED of them) are, with frequencies agreeing to MAX_SPREAD (interquartile over median)
and phases at their drops agreeing (mean resultant length MIN_PHASE_COHERENCE): a ringing set off
by the slip starts at the same phase after every slip, while an alias's phase follows where the
slip fell between two samples, and a ringing seen after a few slips only, or at scattered
frequencies, is noise or another motion. On this rig's own simulated campaigns at 1024 Hz the
aliased ringing passes the per-slip tests after at most 3 of 19 slips, with phases scattered over
the circle (mean resultant length 0.1-0.4 over all slips); after a resolved ringing of another rig
the phases agree to 0.996.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
from scipy.optimize import OptimizeWarning, curve_fit

from rigctl.records.signals import FloatArray

MIN_SAMPLES_PER_CYCLE = 5.0
MIN_SNR = 5.0
"""Ringing amplitude over the record's white-noise RMS."""
MIN_CYCLES = 1.5
"""Cycles the ringing stays above twice the noise."""
MAX_FREQ_SE = 0.05
"""Largest relative standard error of the fitted frequency."""
ALIAS_SLACK = 1.5
"""A ringing period may exceed four times the slip's peak-to-half-way time by this factor."""
MAX_SLIPS = 40
"""Slips tried per run (evenly spread): a long record needs no more for a median."""
MAX_WINDOW_SAMPLES = 8192
MIN_WINDOW_SAMPLES = 16
MIN_RESOLVED = 5
MIN_RESOLVED_FRACTION = 0.3
MAX_SPREAD = 0.1
MIN_PHASE_COHERENCE = 0.8
"""Mean resultant length of the resolved rings' phases at their drops (1: all alike)."""


@dataclass(frozen=True)
class RingFit:
    """The ringing after one slip."""

    freq_hz: float
    """Damped frequency omega_d / 2 pi."""
    decay_per_s: float
    """Decay rate sigma of the envelope."""
    resolved: bool
    phase_rad: float = math.nan
    """Phase of the ringing's cosine at the slip's drop time, in [0, 2 pi)."""


@dataclass(frozen=True)
class Ringing:
    """A campaign's post-slip ringing (NaN where not resolved)."""

    freq_hz: float = math.nan
    decay_per_s: float = math.nan
    n_resolved: int = 0
    n_tried: int = 0

    @property
    def resolved(self) -> bool:
        return math.isfinite(self.freq_hz) and self.freq_hz > 0.0

    @property
    def omega_n2(self) -> float:
        """Undamped angular frequency squared, omega_d^2 + sigma^2 (rad^2/s^2)."""
        sigma = self.decay_per_s if math.isfinite(self.decay_per_s) else 0.0
        return (2.0 * math.pi * self.freq_hz) ** 2 + sigma**2


def _damped(t: FloatArray, a: float, b: float, c: float, amp: float, sigma: float, omega: float,
            phase: float) -> FloatArray:
    """Free response of a damped oscillator on the stick's loading curve (module docstring; the
    quadratic term takes the curvature of a stick that softens towards the peak)."""
    with np.errstate(over="ignore", invalid="ignore"):
        return a + b * t + c * t**2 + amp * np.exp(-sigma * t) * np.cos(omega * t + phase)


def fit_ring(t: FloatArray, f: FloatArray, sigma_noise: float, half_fall_s: float,
             step_frac: float, t_drop_s: float) -> RingFit | None:
    """The damped sinusoid of the window ``t``, ``f`` (a stick after a slip); None when it cannot be
    fitted. ``half_fall_s`` (the time from the slip's peak to half-way down) and ``step_frac`` (its
    steepest one-sample fall over its drop) are the alias test of the module docstring."""
    n = t.shape[0]
    if n < MIN_WINDOW_SAMPLES:
        return None
    tt = t - t[0]
    dt = float(tt[1] - tt[0])
    trend = np.polyfit(tt, f, 2)
    resid = f - np.polyval(trend, tt)
    n_fft = 8 * n
    spectrum = np.abs(np.fft.rfft(resid * np.hanning(n), n_fft))
    freqs = np.fft.rfftfreq(n_fft, dt)
    band = (freqs > MIN_CYCLES / tt[-1]) & (freqs <= 1.0 / (MIN_SAMPLES_PER_CYCLE * dt))
    if not band.any():
        return None
    omega0 = 2.0 * math.pi * float(freqs[np.argmax(np.where(band, spectrum, 0.0))])
    amp0 = float(np.max(np.abs(resid[: max(4, n // 4)])))
    p0 = [trend[2], trend[1], trend[0], amp0, 1.0 / tt[-1], omega0, 0.0]
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", OptimizeWarning)
            popt, pcov = curve_fit(_damped, tt, f, p0=p0, maxfev=2000)
    except (RuntimeError, ValueError):
        return None
    amp, sigma, omega = abs(float(popt[3])), float(popt[4]), abs(float(popt[5]))
    phase = float(popt[6]) if popt[5] > 0 else -float(popt[6])
    if popt[3] < 0:
        phase += math.pi
    phase = (phase + omega * (t_drop_s - float(t[0]))) % (2.0 * math.pi)
    se_omega = float(np.sqrt(pcov[5, 5])) if np.all(np.isfinite(pcov)) else math.inf
    if not (omega > 0.0 and math.isfinite(sigma)):
        return None
    period = 2.0 * math.pi / omega
    lasts = amp * math.exp(-max(sigma, 0.0) * MIN_CYCLES * period) >= 2.0 * sigma_noise
    resolved = (
        period >= MIN_SAMPLES_PER_CYCLE * dt
        and tt[-1] >= MIN_CYCLES * period
        and amp >= MIN_SNR * sigma_noise and lasts
        and sigma >= 0.0
        and se_omega <= MAX_FREQ_SE * omega
        and half_fall_s > 0.0
        and period <= ALIAS_SLACK * 4.0 * half_fall_s
        and step_frac <= 2.0 * math.pi * dt / period
    )
    return RingFit(omega / (2.0 * math.pi), sigma, bool(resolved), phase)


def run_ring_fits(t: FloatArray, ft_N: FloatArray, t_drop_s: FloatArray, i_peak: np.ndarray,
                  sign: np.ndarray, step_frac: FloatArray, sigma_noise: float) -> list[RingFit]:
    """The ringing after the slips of one run (at most MAX_SLIPS, evenly spread; a fit that fails
    counts as not resolved).

    Slip ``j`` falls from sample ``i_peak[j]`` through half-way at ``t_drop_s[j]``; its window runs
    from two such half-falls after the drop (the trough) to the last fifth of the stick before the
    next peak (the run's end for the last slip), at most MAX_WINDOW_SAMPLES."""
    n_slips = i_peak.shape[0]
    if n_slips == 0 or t.shape[0] < 2:
        return []
    dt = float(np.median(np.diff(t)))
    pick = np.unique(np.linspace(0, n_slips - 1, min(n_slips, MAX_SLIPS)).round().astype(int))
    out = []
    for j in pick:
        f = -ft_N if sign[j] < 0 else ft_N
        half = float(t_drop_s[j] - t[int(i_peak[j])])
        i0 = int(np.searchsorted(t, t_drop_s[j] + 2.0 * max(half, 0.0) + 2.0 * dt))
        i_next = int(i_peak[j + 1]) if j + 1 < n_slips else t.shape[0]
        i1 = min(i_next - max(2, (i_next - i0) // 5), i0 + MAX_WINDOW_SAMPLES)
        fit = fit_ring(t[i0:i1], f[i0:i1], sigma_noise, half, float(step_frac[j]),
                       float(t_drop_s[j])) \
            if i1 - i0 >= MIN_WINDOW_SAMPLES and np.isfinite(step_frac[j]) else None
        out.append(fit if fit is not None else RingFit(math.nan, math.nan, False))
    return out


def campaign_ringing(fits: Iterable[RingFit]) -> Ringing:
    """The campaign's :class:`Ringing` from its slips' fits (module docstring)."""
    fits = list(fits)
    tried = len(fits)
    ok = [f for f in fits if f.resolved]
    if len(ok) < MIN_RESOLVED or len(ok) < MIN_RESOLVED_FRACTION * max(tried, 1):
        return Ringing(n_resolved=len(ok), n_tried=tried)
    freq = np.array([f.freq_hz for f in ok])
    q25, med, q75 = (float(v) for v in np.quantile(freq, (0.25, 0.5, 0.75)))
    coherence = float(np.abs(np.mean(np.exp(1j * np.array([f.phase_rad for f in ok])))))
    if (q75 - q25) > MAX_SPREAD * med or coherence < MIN_PHASE_COHERENCE:
        return Ringing(n_resolved=len(ok), n_tried=tried)
    decay = float(np.median([f.decay_per_s for f in ok]))
    return Ringing(med, decay, len(ok), tried)


def ringing_mass(ring: Ringing, k0_N_per_m: float, kts_N_per_m: float) -> float:
    """The mass that rings at ``ring``'s frequency between the drive spring and the stuck
    interface: ``M = (K0 + Kts) / omega_n^2`` (module docstring)."""
    return (k0_N_per_m + kts_N_per_m) / ring.omega_n2

