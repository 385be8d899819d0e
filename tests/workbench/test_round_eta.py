"""The time left in a diagnose round, from the candidate fits already done."""

from __future__ import annotations

import math

import pytest

from rigctl.workbench.round_eta import RoundClock, eta_s, say_duration


def test_time_left_scales_the_elapsed_time_by_the_cost_left_over_the_cost_done() -> None:
    assert eta_s(30.0, [1.0, 2.0], [3.0]) == pytest.approx(30.0)
    assert eta_s(10.0, [0.5], [0.5, 1.0]) == pytest.approx(30.0)
    assert eta_s(10.0, [1.0], []) == 0.0
    assert math.isnan(eta_s(10.0, [], [1.0]))


def test_durations_are_said_as_rounded_estimates() -> None:
    assert say_duration(12.0) == "about 10 s"
    assert say_duration(1.0) == "about 5 s"
    assert say_duration(600.0) == "about 10 min"
    assert say_duration(7200.0) == "about 2.0 h"
    assert say_duration(math.nan) == "unknown"


def test_a_round_clock_counts_fits_and_says_the_time_left() -> None:
    now = [0.0]
    clock = RoundClock([4.0, 2.0, 2.0], clock=lambda: now[0])
    now[0] = 40.0
    assert clock.finished(0) == "[1/3, about 40 s left in this round]"
    now[0] = 60.0
    assert clock.finished(2) == "[2/3, about 20 s left in this round]"
    now[0] = 70.0
    assert clock.finished(1) == "[3/3]"
