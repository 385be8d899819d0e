"""The one budget of a search (:mod:`rigctl.workbench.budget`), on a fake clock."""

from __future__ import annotations

import math

import pytest

from rigctl.workbench.budget import Budget, SearchCancelledError, said


class FakeClock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


def test_an_evaluation_budget_counts_down_and_ends():
    clock = FakeClock()
    b = Budget(max_evaluations=10, clock=clock)
    b.spend(4)
    clock.t += 2.0
    assert b.evaluations_left() == 6
    assert b.fraction_done == pytest.approx(0.4)
    assert b.seconds_per_evaluation == pytest.approx(0.5)
    assert b.eta_s() == pytest.approx(3.0)  # 6 more at 0.5 s
    b.spend(6)
    assert b.exhausted()


def test_a_time_budget_buys_what_the_measured_cost_allows():
    clock = FakeClock()
    b = Budget(max_wall_s=10.0, clock=clock)
    b.start()
    assert b.evaluations_left() == math.inf  # no cost measured yet
    assert b.eta_s() == pytest.approx(10.0)
    b.spend(2)
    clock.t += 4.0  # 2 s per evaluation
    assert b.evaluations_left() == 3  # 6 s left
    assert b.eta_s() == pytest.approx(6.0)
    assert b.fraction_done == pytest.approx(0.4)
    clock.t += 6.0
    assert b.exhausted()


def test_whichever_limit_comes_first_ends_it():
    clock = FakeClock()
    b = Budget(max_evaluations=100, max_wall_s=10.0, clock=clock)
    b.spend(5)
    clock.t += 5.0  # 1 s per evaluation: 5 s buy 5 more, fewer than the 95 counted
    assert b.evaluations_left() == 5
    assert b.fraction_done == pytest.approx(0.5)
    assert b.time_binds()


def test_the_time_binds_only_where_it_buys_fewer_evaluations_than_the_count_left():
    clock = FakeClock()
    assert not Budget(max_evaluations=10, clock=clock).time_binds()  # no wall limit
    b = Budget(max_evaluations=10, max_wall_s=100.0, clock=clock)
    b.spend(5)
    clock.t += 5.0  # 1 s per evaluation: 95 s buy 95, more than the 5 counted
    assert b.evaluations_left() == 5 and not b.time_binds()
    b.spend(4)
    clock.t += 85.0  # 10 s per evaluation: 10 s left buy 1, as many as counted
    assert b.evaluations_left() == 1 and not b.time_binds()
    clock.t += 5.0  # 5 s left buy none of the 1 counted
    assert b.evaluations_left() == 0 and b.time_binds()
    assert Budget(max_wall_s=1.0, clock=clock).time_binds() is False  # no cost measured: inf


def test_a_cancel_is_raised_at_the_next_check():
    b = Budget(max_evaluations=10)
    b.check()
    b.cancel()
    assert b.cancelled
    with pytest.raises(SearchCancelledError):
        b.check()


def test_progress_gets_the_fraction_the_eta_and_the_message():
    clock = FakeClock()
    seen = []
    b = Budget(max_evaluations=20, clock=clock, progress=lambda *a: seen.append(a))
    b.spend(5)
    clock.t += 10.0
    b.report("global search")
    b.report("ending early", evaluations_left=5.0)
    assert seen[0] == (pytest.approx(0.25), pytest.approx(30.0), "global search")
    assert seen[1] == (pytest.approx(0.5), pytest.approx(10.0), "ending early")


@pytest.mark.parametrize("kwargs", [{"max_evaluations": 0}, {"max_wall_s": 0.0},
                                    {"max_wall_s": math.nan}])
def test_an_empty_budget_is_refused(kwargs):
    with pytest.raises(ValueError):
        Budget(**kwargs)


def test_said_puts_a_report_in_words():
    lines: list[str] = []
    progress = said(lines.append)
    progress(0.25, 30.4, "global search: generation 3")
    progress(math.nan, math.nan, "starts")
    assert lines == [
        "  global search: generation 3 (25% of the search budget, about 30 s left)",
        "  starts (? of the search budget, time left not known yet)",
    ]
