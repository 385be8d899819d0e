"""The stage physics: trapezoidal moves that take time, loud refusals, stop, e-stop, homing."""

from __future__ import annotations

import math

import pytest

from sim_devices.stage_axis import NORMAL_STAGE, TANGENTIAL_STAGE, Alarm, StageAxis


def enabled_axis() -> StageAxis:
    axis = StageAxis(TANGENTIAL_STAGE)
    axis.enable(0.0)
    return axis


def test_trapezoid_honours_velocity_and_acceleration() -> None:
    axis = enabled_axis()
    p0, a = axis.position_m(0.0), TANGENTIAL_STAGE.accel_m_s2
    assert axis.move_to(1.0, p0 + 2e-3, 1e-3) == Alarm.NONE
    t_ramp = 1e-3 / a
    # accelerating: x = a t^2 / 2; cruising at v; arrives at t0 + d/v + v/a
    assert axis.position_m(1.0 + 0.1) == pytest.approx(p0 + 0.5 * a * 0.1**2, rel=1e-9)
    assert axis.velocity_m_s(1.0 + t_ramp + 0.5) == pytest.approx(1e-3)
    t_end = 1.0 + 2e-3 / 1e-3 + t_ramp
    assert axis.moving(t_end - 1e-6) and not axis.moving(t_end + 1e-9)
    assert axis.position_m(t_end) == pytest.approx(p0 + 2e-3, abs=1e-12)
    st = axis.status(t_end + 0.1)
    assert st.in_position and not st.moving and st.alarm == Alarm.NONE


def test_short_move_is_a_triangle() -> None:
    axis = enabled_axis()
    p0, a = axis.position_m(0.0), TANGENTIAL_STAGE.accel_m_s2
    axis.move_to(0.0, p0 + 1e-6, 5e-3)
    t_half = math.sqrt(1e-6 / a)
    assert axis.velocity_m_s(t_half) == pytest.approx(a * t_half)
    assert not axis.moving(2 * t_half + 1e-9)


@pytest.mark.parametrize("target", [-1e-3, 0.2001, math.nan])
def test_target_outside_travel_refused_with_alarm_1(target: float) -> None:
    axis = enabled_axis()
    p0 = axis.position_m(0.0)
    assert axis.move_to(0.0, target, 1e-3) == Alarm.OVER_TRAVEL
    st = axis.status(1.0)
    assert st.fault and st.alarm == Alarm.OVER_TRAVEL and st.position_m == p0 and not st.moving


@pytest.mark.parametrize("velocity", [0.0, -1e-3, 6e-3, math.inf])
def test_bad_velocity_refused_with_driver_fault(velocity: float) -> None:
    axis = enabled_axis()
    assert axis.move_to(0.0, 0.11, velocity) == Alarm.DRIVER_FAULT
    assert not axis.moving(0.5)


def test_move_while_disabled_refused_and_alarm_blocks_until_reset() -> None:
    axis = StageAxis(TANGENTIAL_STAGE)
    assert axis.move_to(0.0, 0.11, 1e-3) == Alarm.DRIVER_FAULT
    axis.enable(0.1)
    assert axis.move_to(0.2, 0.11, 1e-3) == Alarm.DRIVER_FAULT  # still latched
    axis.reset_alarm(0.3)
    assert axis.move_to(0.3, 0.11, 1e-3) == Alarm.NONE


def test_stop_decelerates_and_emergency_stop_halts_at_once() -> None:
    axis = enabled_axis()
    p0, a = axis.position_m(0.0), TANGENTIAL_STAGE.accel_m_s2
    axis.move_to(0.0, p0 + 0.05, 5e-3)
    t_stop = 2.0  # cruising at 5 mm/s since t = 1 s
    p_stop = axis.position_m(t_stop)
    axis.stop(t_stop)
    braking = 5e-3**2 / (2 * a)
    assert axis.position_m(t_stop + 5.0) == pytest.approx(p_stop + braking, rel=1e-9)
    assert axis.status(t_stop + 5.0).in_position
    axis.move_to(10.0, p0, 5e-3)
    p_e = axis.position_m(11.5)
    axis.emergency_stop(11.5)
    st = axis.status(12.0)
    assert st.position_m == p_e and st.alarm == Alarm.EMERGENCY_STOP and st.fault
    assert axis.move_to(12.0, p0, 1e-3) == Alarm.EMERGENCY_STOP


def test_home_sets_homed_on_arrival_only() -> None:
    axis = StageAxis(NORMAL_STAGE)
    axis.enable(0.0)
    axis.home(0.0)
    duration = NORMAL_STAGE.start_position_m / NORMAL_STAGE.homing_velocity_m_s
    assert not axis.status(duration * 0.5).homed
    st = axis.status(duration + 1.0)
    assert st.homed and st.limit and st.position_m == NORMAL_STAGE.home_position_m


def test_retarget_while_moving_brakes_first() -> None:
    axis = enabled_axis()
    p0 = axis.position_m(0.0)
    axis.move_to(0.0, p0 + 0.01, 5e-3)
    axis.move_to(2.0, p0, 5e-3)  # reverse while cruising forward
    v = [axis.velocity_m_s(2.0 + dt) for dt in (0.0, 0.5, 1.0, 1.5)]
    assert v[0] > 0 and v[1] > 0 and v[3] < 0  # decelerates through zero, then returns
    assert axis.position_m(100.0) == pytest.approx(p0, abs=1e-12)
