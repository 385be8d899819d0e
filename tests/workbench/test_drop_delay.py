"""``drop_delay_s``: the force drop behind the probes' slip tells a slow force sensor from a slow
slider (a heavier mass smears the drop as much, but its force follows its slip closely)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rigctl.model import build_model
from rigctl.records.dataset import prepare_dataset
from rigctl.workbench.campaigns import simulate_campaign
from tests.workbench.hidden import TEST_BASE

RATE_HZ = 4096.0
TAU_S = 2e-3


def _read(params: dict[str, float], sensor_tau_s: float = 0.0, **campaign):
    effects = ["sensor_dynamics"] if sensor_tau_s > 0 else []
    model = build_model("paper", effects=effects, params={**TEST_BASE, **params},
                        effect_params={"sensor_dynamics": {"tau_s": sensor_tau_s}}
                        if effects else None)
    runs = simulate_campaign(model, "tlre", seed=5, sample_rate_hz=RATE_HZ, velocity_m_s=2e-5,
                             duration_scale=0.5, **campaign)
    ds = prepare_dataset(runs)
    feats = ds.runs[0].events.features
    return feats["drop_delay_s"], feats["step_frac"]


@pytest.mark.slow
def test_a_slow_force_sensor_shows_as_a_delay_a_heavy_slider_does_not():
    delay0, sharp0 = _read({})
    delay_s, sharp_s = _read({}, sensor_tau_s=TAU_S)
    m0 = build_model("paper", params=TEST_BASE).base_values["m_kg"]
    delay_m, sharp_m = _read({"m_kg": 10.0 * m0})
    for d in (delay0, delay_s, delay_m):
        assert np.count_nonzero(np.isfinite(d)) >= 5
    dt = 1.0 / RATE_HZ
    # an ideal sensor: the force falls with the slip, within half a sample
    assert abs(float(np.nanmedian(delay0))) < 0.5 * dt
    # a first-order sensor behind a slip much faster than tau: half-way after about ln 2 tau
    assert 0.6 * math.log(2.0) * TAU_S < float(np.nanmedian(delay_s)) < 1.2 * math.log(2.0) * TAU_S
    # both the slow sensor and the heavy slider smear the drop (what step_frac sees) ...
    assert np.nanmedian(sharp_s) < 0.5 * np.nanmedian(sharp0)
    assert np.nanmedian(sharp_m) < 0.5 * np.nanmedian(sharp0)
    # ... but only the sensor puts the force well behind the slip: the heavy slider's force lags
    # its slip by a small part of the slip's own duration (0.2 ms here, against 1.4 ms)
    assert abs(float(np.nanmedian(delay_m))) < 0.25 * float(np.nanmedian(delay_s))


def test_no_probe_gives_no_delay():
    delay, _ = _read({}, sensor_tau_s=TAU_S)
    assert np.isfinite(delay).any()
    model = build_model("paper", effects=["sensor_dynamics"], params=TEST_BASE,
                        effect_params={"sensor_dynamics": {"tau_s": TAU_S}})
    runs = simulate_campaign(model, "tlre", seed=5, sample_rate_hz=RATE_HZ, velocity_m_s=2e-5,
                             duration_scale=0.5)
    for run in runs:
        run.d1_m[:] = 0.0
        run.d2_m[:] = 0.0
    ds = prepare_dataset(runs)
    assert not np.isfinite(ds.runs[0].events.features["drop_delay_s"]).any()


@pytest.mark.parametrize("rate_hz", [256.0, 1024.0])
def test_an_ideal_sensor_s_delay_stays_within_its_floor_at_low_rates(rate_hz):
    """Where the slip takes a sample or two the delay is only interpolation: it stays inside the
    half-sample floor its scatter is measured against."""
    model = build_model("paper", params=TEST_BASE)
    runs = simulate_campaign(model, "tlre", seed=6, sample_rate_hz=rate_hz, velocity_m_s=2e-5,
                             duration_scale=0.5)
    ds = prepare_dataset(runs)
    delay = ds.runs[0].events.features["drop_delay_s"]
    assert np.isfinite(delay).any()
    assert abs(float(np.nanmedian(delay))) < 0.5 / rate_hz
