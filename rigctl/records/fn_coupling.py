"""The part of the measured normal force that follows the tangential force.

A model's drive is the *applied* normal load (:class:`~rigctl.records.drive_profile.DriveProfile`).
Where the loading frame tilts with the tangential load, or the sensor's axes cross-talk, the
measured Fn also moves with Ft: in the library's ``normal_coupling`` effect

    Fn,measured = Fn,applied + kappa Ft        (rigctl/model/effects/normal_coupling.py)

Taken into the drive as it is, that swing is counted twice by a model with the coupling (its own
kappa Ft comes on top) and stands for it in a model without it: even the generating model then
misfits its own data (the case: docs/decisions.md).

The coupling shows where Ft jumps: in a slip Ft falls within a few samples while the applied load
does not move, so over those samples dFn = c dFt. ``c`` is the least-squares ratio over the steps
whose Ft change exceeds SLIP_STEP_SIGMAS times the step noise (and the median step: a loading ramp's
steps are not slips); on data without coupling it is noise about 0. A slow slip (a heavy slider on
a soft spring: 13 ms, 40 samples, for 0.47 kg on 28 kN/m) falls by less than that in any one sample,
so the steps are also taken over longer lags (LAGS_SAMPLES), and the lag that reads ``c`` most
precisely gives it (its standard error widened by sqrt(lag): steps over a lag overlap). The frame
is the campaign's: the steps of all its runs are pooled (:func:`campaign_coupling`), so a run with
few slips is read with the others. ``c`` is taken out where it is significant (MIN_T_RATIO
standard errors of the regression), whatever the size of its
swing: the mean of c Ft lifts the measured level too.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from rigctl.records.signals import FloatArray, noise_sigma

SLIP_STEP_SIGMAS = 10.0
"""An Ft step (over a lag) this many noise sigmas of a one-sample step is part of a slip."""
MIN_SLIP_STEPS = 5
"""Fewer slip steps than this times the lag give no ratio at that lag."""
LAGS_SAMPLES: tuple[int, ...] = (1, 2, 4, 8, 16, 32, 64)
"""Steps over each of these lags are read, the most precise ratio kept (a slip spread over up to
64 samples)."""
MAX_COUPLING = 0.5
"""|dFn/dFt| beyond this is not a coupling of the loading frame (the effect's own bound)."""
MIN_T_RATIO = 5.0
"""``c`` is taken out where it is this many standard errors from 0 (noise about 0 is left)."""


class _Record:
    """One record's Ft and Fn with the floor a slip step must pass (the step noise)."""

    def __init__(self, ft_N: FloatArray, fn_N: FloatArray) -> None:
        self.ft_N, self.fn_N = ft_N, fn_N
        self.usable = ft_N.shape[0] >= 3 and fn_N.shape == ft_N.shape
        if self.usable:
            self.step_sigma = math.sqrt(2.0) * noise_sigma(ft_N)
            self.scale = float(np.percentile(ft_N, 99) - np.percentile(ft_N, 1))

    def slip_steps(self, lag: int) -> tuple[FloatArray, FloatArray] | None:
        """(dFt, dFn) over ``lag`` samples where Ft jumps; None where there are too few."""
        if not self.usable or 4 * lag >= self.ft_N.shape[0]:
            return None
        dft = self.ft_N[lag:] - self.ft_N[:-lag]
        # a slip step stands out of the noise and of the loading's own steps (a noise-free ramp)
        floor = max(SLIP_STEP_SIGMAS * max(self.step_sigma, float(np.median(np.abs(dft)))),
                    1e-3 * self.scale, 1e-12)
        sel = np.abs(dft) > floor
        if np.count_nonzero(sel) < MIN_SLIP_STEPS * lag:  # a slip gives up to ``lag`` steps
            return None
        return dft[sel], (self.fn_N[lag:] - self.fn_N[:-lag])[sel]


def _ratio(x: FloatArray, y: FloatArray, lag: int) -> tuple[float, float]:
    """Least-squares dFn/dFt through 0 and its standard error (widened by sqrt(lag): steps over a
    lag overlap)."""
    n = x.shape[0]
    sxx = float(np.dot(x, x))
    c = float(np.dot(x, y) / sxx)
    resid = y - c * x
    return c, math.sqrt(float(np.dot(resid, resid)) / (n - 1) / sxx * lag)


def campaign_coupling(records: Sequence[tuple[FloatArray, FloatArray]]) -> tuple[float, float]:
    """dFn/dFt of a loading frame from the slip steps of its records ((Ft, Fn) pairs, pooled, so
    that a run with few slips, a low load of a sweep, is read with the others) and its standard
    error: at the lag of LAGS_SAMPLES that reads it most precisely (a step over a whole slow slip
    stands further out of the Fn noise than one sample of it). (0, inf) where no lag has enough
    steps, or beyond MAX_COUPLING."""
    recs = [_Record(ft, fn) for ft, fn in records]
    best = (0.0, math.inf)
    for lag in LAGS_SAMPLES:
        found = [st for st in (r.slip_steps(lag) for r in recs) if st is not None]
        if not found:
            continue
        c, se = _ratio(np.concatenate([st[0] for st in found]),
                       np.concatenate([st[1] for st in found]), lag)
        if math.isfinite(c) and se < best[1]:
            best = (c, se)
    return best if abs(best[0]) <= MAX_COUPLING else (0.0, math.inf)


def coupling_ratio(ft_N: FloatArray, fn_N: FloatArray) -> tuple[float, float]:
    """dFn/dFt of one record (:func:`campaign_coupling`) and its standard error."""
    return campaign_coupling([(ft_N, fn_N)])


def applied_normal_force(ft_N: FloatArray, fn_N: FloatArray,
                         ratio: tuple[float, float] | None = None) -> tuple[FloatArray, float]:
    """The applied normal load ``Fn - c Ft`` and ``c`` where ``c`` is significant (MIN_T_RATIO
    standard errors from 0); else ``fn_N`` unchanged and 0. ``ratio``: ``(c, se)`` of the
    campaign (:func:`campaign_coupling`); None: read from this record. Not only the swing matters:
    the mean of ``c Ft`` lifts the whole measured level (by c times the mean Ft, which a drive fit
    keeps even where the swing lies within its tolerance)."""
    c, se = coupling_ratio(ft_N, fn_N) if ratio is None else ratio
    if c == 0.0 or abs(c) < MIN_T_RATIO * se:
        return fn_N, 0.0
    out: FloatArray = fn_N - c * ft_N
    return out, c
