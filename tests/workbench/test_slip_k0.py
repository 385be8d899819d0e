"""Where no stick's loading ramp is read, the slips show the drive spring: drop = K0 x slip while
every element slides (data_scale.slip_k0; docs/identification.md, "Starting values from the
data"). Without it such a record had no start at its own scale, and the search from the preset
(1,000 times stiffer) ended where every feature was at the missing-event charge."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from rigctl.records.dataset import prepare_dataset
from rigctl.records.features import EventTable
from rigctl.workbench.data_scale import (
    PRESET,
    PRESET_KTS_RATIO,
    base_start,
    measure_scale,
    slip_k0,
)
from tests.workbench.synth import LIGHT_RIG, light_rig_tlre

K0 = LIGHT_RIG["k0_N_per_m"]


@pytest.fixture(scope="module")
def tables() -> list[EventTable]:
    return [r.events for r in prepare_dataset(light_rig_tlre(c0_N_s_per_m=0.6)).runs]


def _no_ramp(tables: list[EventTable]) -> list[EventTable]:
    """The same events with no loading ramp read (sticks too short for its window)."""
    return [dataclasses.replace(t, features={**t.features,
                                             "rate_N_per_s": np.full(t.n, np.nan)})
            for t in tables]


def test_the_slips_force_drop_over_their_distance_is_the_drive_spring(tables):
    assert slip_k0(tables) == pytest.approx(K0, rel=0.02)


def test_the_ramp_still_gives_the_series_stiffness_where_it_is_read(tables):
    series = 1.0 / (1.0 / K0 + 1.0 / LIGHT_RIG["kts_N_per_m"])
    assert measure_scale(tables).k_eff_N_per_m == pytest.approx(series, rel=0.05)


def test_without_a_ramp_the_start_takes_k0_from_the_slips(tables):
    scale = measure_scale(_no_ramp(tables))
    assert scale.usable
    start = base_start(scale, dict(PRESET))
    assert start["k0_N_per_m"] == pytest.approx(K0, rel=0.02)
    assert start["kts_N_per_m"] == pytest.approx(PRESET_KTS_RATIO * start["k0_N_per_m"])


def test_without_a_ramp_or_delta_there_is_still_no_stiffness(tables):
    scale = measure_scale(_no_ramp(tables), delta_measured=False)
    assert math.isnan(scale.k_eff_N_per_m) and not scale.usable
