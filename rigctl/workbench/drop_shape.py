"""The slip frequency read from the shape of the measured drops, where the sampling resolves it.

During a global slip every element slides, so the slider swings on the drive spring alone
(:mod:`rigctl.workbench.data_scale`): with little damping the tangential force falls along a
half cosine, ``Ft = F_k + (drop / 2) cos(omega_slip t)``, ``omega_slip^2 = K0 / M``, from the peak
to the trough in half a period. Its largest fall over one sample interval dt is
``drop sin(omega_slip dt / 2)`` where the two samples straddle the steepest point, and at least
``drop sin(omega_slip dt / 2) cos(omega_slip dt / 2)`` for any sampling phase (the midpoint of the
sample pair within dt / 2 of it). The feature ``step_frac`` (:mod:`rigctl.records.features`) is that
fall over the drop, so

    omega_slip = 2 asin(step_frac) / dt,    M = K0 / omega_slip^2.

It is read only where the slip spans at least :data:`MIN_SAMPLES_PER_SLIP` samples, i.e. the
median ``step_frac`` is at most sin(pi / (2 MIN_SAMPLES_PER_SLIP)): there the sampling phase moves
``step_frac`` by at most a factor cos(pi / (2 MIN_SAMPLES_PER_SLIP)) (0.87), so the mass by at most
a factor 1.3, against the decades between rigs that the preset's slip frequency leaves open. A
slip over within fewer samples bounds the frequency from below only. Damping, a sensor's lag or an
effect that rounds the drop also slow the fall: the reading is one start of the search among
others, ranked by the cost it reaches, never a value imposed.
"""

from __future__ import annotations

import math

import numpy as np

from rigctl.records.dataset import Dataset

MIN_SAMPLES_PER_SLIP = 3.0
"""Samples a slip (half a slip period) must span for its fall to state the frequency: at three,
the sampling phase leaves the reading within a factor cos(pi / 6) = 0.87 of the frequency."""


def slip_omega(dataset: Dataset) -> float:
    """The slip's angular frequency omega_slip [rad/s] read from the stable slips' ``step_frac``
    (module docstring); NaN where the drops are not resolved or not measured."""
    omegas: list[np.ndarray] = []
    fracs: list[np.ndarray] = []
    for run in dataset.runs:
        if not run.sample_rate_hz > 0.0:
            continue
        ev = run.events
        sf = np.asarray(ev.features["step_frac"], dtype=float)[ev.stage == 1]
        sf = sf[np.isfinite(sf) & (sf > 0.0)]
        fracs.append(sf)
        omegas.append(2.0 * np.arcsin(np.minimum(sf, 1.0)) * run.sample_rate_hz)
    frac = np.concatenate(fracs) if fracs else np.zeros(0)
    if not frac.size or float(np.median(frac)) > math.sin(math.pi / (2.0 * MIN_SAMPLES_PER_SLIP)):
        return math.nan
    return float(np.median(np.concatenate(omegas)))


def drop_shape_mass(dataset: Dataset, k0_N_per_m: float) -> float:
    """M = K0 / omega_slip^2 [kg] (NaN where the drops do not resolve the slip frequency)."""
    omega = slip_omega(dataset)
    if not (math.isfinite(omega) and omega > 0.0 and k0_N_per_m > 0.0):
        return math.nan
    return k0_N_per_m / omega**2
