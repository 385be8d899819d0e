"""The normal contact compliance law Fn(z)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim_devices.contact_law import NormalContactLaw


def test_zero_when_apart_monotonic_in_contact() -> None:
    law = NormalContactLaw()
    assert law.fn_N(law.z_contact_m - 1e-3) == 0.0
    assert law.fn_N(law.z_contact_m) == 0.0
    z = law.z_contact_m + np.linspace(1e-9, 120e-6, 500)
    fn = np.array([law.fn_N(float(v)) for v in z])
    assert np.all(np.diff(fn) > 0)


def test_full_load_needs_tens_of_micrometres() -> None:
    law = NormalContactLaw()
    assert law.fn_N(law.z_contact_m + 80e-6) == pytest.approx(500.0)
    approach_300 = law.z_for_fn_m(300.0) - law.z_contact_m
    assert 20e-6 < approach_300 < 80e-6


def test_inverse_round_trip_and_bad_input() -> None:
    law = NormalContactLaw.from_reference(0.01, 400.0, 60e-6)
    for fn in (1.0, 150.0, 799.0):
        assert law.fn_N(law.z_for_fn_m(fn)) == pytest.approx(fn)
    for bad in (0.0, -5.0, math.nan):
        with pytest.raises(ValueError):
            law.z_for_fn_m(bad)
    with pytest.raises(ValueError):
        NormalContactLaw(k_n_N_per_m1_5=-1.0)
