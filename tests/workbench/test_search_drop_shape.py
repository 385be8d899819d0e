"""The slip frequency read from the drops' shape (rigctl/workbench/drop_shape.py), the search's
start for a mass the data do not state: right where the slip spans a few samples, silent where it
does not."""

from __future__ import annotations

import math

import pytest

from rigctl.model import build_model
from rigctl.records.dataset import prepare_dataset
from rigctl.workbench.campaigns import simulate_campaign
from rigctl.workbench.drop_shape import drop_shape_mass
from tests.workbench.test_search import FN_N, NOISE, RIG, V_M_S


def _tlre(params, rate_hz, fn_N=FN_N, v_m_s=V_M_S, noise=NOISE):
    runs = simulate_campaign(build_model("paper", params=params), "tlre", seed=5, noise=noise,
                             sample_rate_hz=rate_hz, fn_N=fn_N, velocity_m_s=v_m_s,
                             duration_scale=0.25)
    return prepare_dataset(runs)


def test_a_slip_over_several_samples_states_the_mass():
    # sqrt(K0 / M) = 1000 rad/s: at 2 kHz a slip (half a period, 3.1 ms) spans six samples
    m = drop_shape_mass(_tlre(RIG, 2000.0), RIG["k0_N_per_m"])
    assert m == pytest.approx(RIG["m_kg"], rel=0.3)


def test_a_slip_within_a_sample_or_two_states_nothing():
    # the preset: an 880 Hz slip at 1024 Hz is over within about a sample
    dataset = _tlre({}, 1024.0, fn_N=300.0, v_m_s=1e-5, noise=None)
    assert math.isnan(drop_shape_mass(dataset, 1.475e6))
