"""A saturated force reading counts as "at least this much": the force guard trips at the sensor's range
(issue 35: the simulated sensor saturated at 655.34 N, 0.02 N/count then, the guard at 800 N never
tripped)."""

from __future__ import annotations

import math

import pytest

from drivers.can_daq import CanDaq, CanDaqConfig
from drivers.errors import ForceLimitError, SettingError
from drivers.ratings import RATED_NORMAL_FORCE_N
from drivers.safety import EmergencyStop, ForceGuard

from .test_drv_safety import LoggingStage

RANGE_N = 32767 * 0.02  # a DAQ's full scale at 0.02 N/count: 655.34 N, below the 800 N limit
DEFAULT_FULL_SCALE_N = 32767 * 0.025  # the default scale's full scale: 819.175 N


@pytest.fixture
def stage(estop: EmergencyStop) -> LoggingStage:
    return LoggingStage("normal", estop)


def test_a_saturated_reading_trips_a_guard_whose_limit_is_above_the_range(stage: LoggingStage) -> None:
    guard = ForceGuard(stage, limit_N=800.0, range_N=RANGE_N)
    assert guard.trips_above_N == RANGE_N
    assert guard.feed([650.0, 655.0, 655.32]) is None  # below full scale: a real reading
    trip = guard.feed([655.0, RANGE_N, RANGE_N])
    assert trip is not None and guard.tripped
    assert trip.range_N == RANGE_N and trip.limit_N == 800.0
    assert "saturated" in str(trip) and "655.34 N" in str(trip) and "800 N" in str(trip)
    assert stage.log == [("estop",)]
    with pytest.raises(ForceLimitError, match="saturated"):  # motion refused after, same words
        stage.move_absolute(0.02, 1e-5)


def test_negative_full_scale_is_saturated_too(stage: LoggingStage) -> None:
    guard = ForceGuard(stage, limit_N=800.0, range_N=RANGE_N)
    assert guard.feed([-32768 * 0.02]) is not None


def test_a_limit_below_the_range_trips_as_before_without_saying_saturated(stage: LoggingStage) -> None:
    guard = ForceGuard(stage, limit_N=500.0, range_N=RANGE_N)
    trip = guard.feed([501.0])
    assert trip is not None and trip.range_N is None
    assert "|Fn| = 501 N exceeds 500 N" in str(trip)


def test_a_release_from_saturation_is_not_stopped_by_its_own_start(stage: LoggingStage) -> None:
    guard = ForceGuard(stage, limit_N=800.0, range_N=RANGE_N)
    guard.feed([RANGE_N])
    guard.allow_release()
    assert guard.feed([RANGE_N, RANGE_N]) is None  # still saturated while it starts: releasing
    assert guard.feed([640.0]) is None and guard.releasing  # below the range, not clearly
    assert guard.feed([600.0, 400.0]) is None  # below 0.95 x the range: release mode ends
    assert not guard.releasing
    assert guard.feed([RANGE_N]) is not None  # saturation trips again


@pytest.mark.parametrize("bad", [0.0, -1.0, math.nan])
def test_the_guard_refuses_a_range_that_is_not_a_positive_number(stage: LoggingStage, bad: float) -> None:
    with pytest.raises(ValueError, match="range"):
        ForceGuard(stage, range_N=bad)


def test_the_can_daq_range_is_the_configured_one_at_most_the_wire_full_scale() -> None:
    assert CanDaqConfig().saturation_N == DEFAULT_FULL_SCALE_N  # nothing configured: int16 full scale
    assert CanDaqConfig().saturation_N >= RATED_NORMAL_FORCE_N  # it reads the stage's rated load
    assert CanDaqConfig(force_range_N=500.0).saturation_N == 500.0  # a 500 N sensor
    assert CanDaqConfig(force_range_N=2000.0).saturation_N == DEFAULT_FULL_SCALE_N  # wire first
    assert CanDaqConfig(force_N_per_count=0.02, force_range_N=2000.0).saturation_N == RANGE_N
    assert CanDaqConfig(force_N_per_count=0.05).saturation_N == pytest.approx(1638.35)
    with CanDaq(CanDaqConfig(channel="rigctl-force-range", force_range_N=500.0)) as daq:
        assert daq.force_range_N == 500.0


@pytest.mark.parametrize("bad", [0.0, -5.0, math.nan])
def test_a_configured_range_that_is_not_a_positive_number_is_refused(bad: float) -> None:
    with pytest.raises(SettingError, match="force_range_N"):
        CanDaqConfig(force_range_N=bad)
