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
steps are not slips); on data without coupling it is noise about 0. It is taken out only where the
swing it makes exceeds the drive fit's tolerance on Fn (a smaller one never shows in the drive).
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


def coupling_ratio(ft_N: FloatArray, fn_N: FloatArray) -> float:
    """dFn/dFt over the samples where Ft jumps (slips); 0 where there are too few of them."""
    if ft_N.shape[0] < 3 or fn_N.shape != ft_N.shape:
        return 0.0
    dft, dfn = np.diff(ft_N), np.diff(fn_N)
    step_sigma = math.sqrt(2.0) * noise_sigma(ft_N)
    scale = float(np.percentile(ft_N, 99) - np.percentile(ft_N, 1))
    # a slip step stands out of the noise and of the loading's own steps (a noise-free ramp)
    floor = max(SLIP_STEP_SIGMAS * max(step_sigma, float(np.median(np.abs(dft)))),
                1e-3 * scale, 1e-12)
    sel = np.abs(dft) > floor
    if np.count_nonzero(sel) < MIN_SLIP_STEPS:
        return 0.0
    c = float(np.dot(dfn[sel], dft[sel]) / np.dot(dft[sel], dft[sel]))
    return c if math.isfinite(c) and abs(c) <= MAX_COUPLING else 0.0


def applied_normal_force(ft_N: FloatArray, fn_N: FloatArray, fn_tol_N: float) -> tuple[FloatArray, float]:
    """The applied normal load ``Fn - c Ft`` and ``c``, where the coupled swing ``|c|`` times Ft's
    range exceeds ``fn_tol_N`` (the drive fit's tolerance: a smaller one never shows in the
    drive); else ``fn_N`` unchanged and 0."""
    c = coupling_ratio(ft_N, fn_N)
    if c == 0.0:
        return fn_N, 0.0
    ft_range = float(np.percentile(ft_N, 99) - np.percentile(ft_N, 1))
    if abs(c) * ft_range <= fn_tol_N:
        return fn_N, 0.0
    out: FloatArray = fn_N - c * ft_N
    return out, c
