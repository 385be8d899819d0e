"""The part of the measured normal force that follows the tangential force.

A model's drive is the *applied* normal load (:class:`~rigctl.workbench.drive_profile.DriveProfile`).
Where the loading frame tilts with the tangential load, or the sensor's axes cross-talk, the
measured Fn also moves with Ft: in the library's ``normal_coupling`` effect

    Fn,measured = Fn,applied + kappa Ft        (rigctl/model/effects/normal_coupling.py)

Taken into the drive as it is, that swing is counted twice by a model with the coupling (its own
kappa Ft comes on top) and stands for it in a model without it. On a held-out rig (kappa 0.126,
Ft about 64 N at 176 N) the drive's normal force followed the measured swing, 176.8 -> 187.7 ->
181.2 N, and the generating model scored E = 11 on its own noise-level data.

The coupling shows where Ft jumps: in a slip Ft falls within a sample or two while the applied load
does not move, so over those samples dFn = c dFt. ``c`` is the least-squares ratio over the samples
whose Ft step exceeds SLIP_STEP_SIGMAS times the step noise (and the median step: a loading ramp's
steps are not slips); on data without coupling it is noise about 0. It is taken out where it is
significant (MIN_T_RATIO standard errors of the regression), whatever the size of its swing: the
mean of c Ft lifts the measured level too.
"""

from __future__ import annotations

import math

import numpy as np

from rigctl.workbench.signals import FloatArray, noise_sigma

SLIP_STEP_SIGMAS = 10.0
"""A sample-to-sample Ft step this many noise sigmas of a step is part of a slip."""
MIN_SLIP_STEPS = 5
"""Fewer slip steps than this give no ratio (0)."""
MAX_COUPLING = 0.5
"""|dFn/dFt| beyond this is not a coupling of the loading frame (the effect's own bound)."""
MIN_T_RATIO = 5.0
"""``c`` is taken out where it is this many standard errors from 0 (noise about 0 is left)."""


def coupling_ratio(ft_N: FloatArray, fn_N: FloatArray) -> tuple[float, float]:
    """dFn/dFt over the samples where Ft jumps (slips) and its standard error; (0, inf) where
    there are too few of them."""
    none = (0.0, math.inf)
    if ft_N.shape[0] < 3 or fn_N.shape != ft_N.shape:
        return none
    dft, dfn = np.diff(ft_N), np.diff(fn_N)
    step_sigma = math.sqrt(2.0) * noise_sigma(ft_N)
    scale = float(np.percentile(ft_N, 99) - np.percentile(ft_N, 1))
    # a slip step stands out of the noise and of the loading's own steps (a noise-free ramp)
    floor = max(SLIP_STEP_SIGMAS * max(step_sigma, float(np.median(np.abs(dft)))),
                1e-3 * scale, 1e-12)
    sel = np.abs(dft) > floor
    n = int(np.count_nonzero(sel))
    if n < MIN_SLIP_STEPS:
        return none
    x, y = dft[sel], dfn[sel]
    sxx = float(np.dot(x, x))
    c = float(np.dot(x, y) / sxx)
    resid = y - c * x
    se = math.sqrt(float(np.dot(resid, resid)) / (n - 1) / sxx)
    if not math.isfinite(c) or abs(c) > MAX_COUPLING:
        return none
    return c, se


def applied_normal_force(ft_N: FloatArray, fn_N: FloatArray) -> tuple[FloatArray, float]:
    """The applied normal load ``Fn - c Ft`` and ``c`` where ``c`` is significant (MIN_T_RATIO
    standard errors from 0); else ``fn_N`` unchanged and 0. Not only the swing matters: the mean
    of ``c Ft`` lifts the whole measured level (6 N at 176 N on the held-out rig, where the drive fit
    kept the swing within its tolerance but at the measured level)."""
    c, se = coupling_ratio(ft_N, fn_N)
    if c == 0.0 or abs(c) < MIN_T_RATIO * se:
        return fn_N, 0.0
    out: FloatArray = fn_N - c * ft_N
    return out, c
