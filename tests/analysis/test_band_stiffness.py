"""One band's stiffness (rigctl/analysis/stiffness.py: band_stiffness) on bands it cannot read."""

from __future__ import annotations

import math
import warnings

import numpy as np

from rigctl.analysis.stiffness import band_stiffness


def test_a_band_whose_samples_are_all_rejected_is_nan_without_a_numpy_warning():
    # delta unreadable over the band (NaN): every sample's residual is NaN, none is kept; numpy's
    # "Mean of empty slice" reached `rigctl analyse` on a clean simulated CSV
    ft = np.linspace(10.0, 20.0, 200)
    delta = np.full(200, np.nan)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        s = band_stiffness(ft, delta, sigma_f=0.01, sigma_d=1e-8)
    assert math.isnan(s.k_N_per_m) and s.n == 0


def test_a_clean_band_reads_its_slope():
    ft = np.linspace(10.0, 20.0, 200)
    delta = ft / 2.0e6
    s = band_stiffness(ft, delta, sigma_f=1e-3, sigma_d=1e-10)
    assert abs(s.k_N_per_m / 2.0e6 - 1.0) < 1e-3
