"""The time limit of a whole ``--auto`` run (rigctl/workbench/run_deadline.py) and how the
selection (rigctl/workbench/selection.py) ends at it: each fit's share of the time left, the hard
stop, the steps taken so far kept and the stop said."""

from __future__ import annotations

import threading
import time
from collections.abc import Sequence
from typing import Any

import pytest

from rigctl.workbench import selection as sel
from rigctl.workbench.budget import SearchCancelledError
from rigctl.workbench.identify import FitResult
from rigctl.workbench.model_choice import ModelChoice
from rigctl.workbench.run_deadline import RunDeadline
from tests.workbench.test_budget import FakeClock as Clock
from tests.workbench.test_selection import DATASET, POOL, S, Table


def test_a_fit_gets_the_time_left_over_the_fits_left_plus_one():
    clock = Clock()
    d = RunDeadline(600.0, clock=clock, watch=False)
    assert d.share_s(5) == pytest.approx(100.0)
    clock.t += 300.0
    assert d.left_s() == pytest.approx(300.0)
    assert d.share_s(2) == pytest.approx(100.0)
    assert d.share_s(0) == pytest.approx(150.0)  # the last fit: half of what is left
    assert not d.passed()
    clock.t += 301.0
    assert d.left_s() == 0.0 and d.passed() and d.expired()


def test_without_a_limit_there_is_no_share_and_no_stop():
    d = RunDeadline(None, watch=False)
    assert d.left_s() is None and d.share_s(3) is None and not d.passed()


@pytest.mark.parametrize("bad", [0.0, -5.0, float("nan")])
def test_a_limit_that_is_not_positive_is_refused(bad):
    with pytest.raises(ValueError, match="must be positive"):
        RunDeadline(bad, watch=False)


def test_the_watcher_sets_the_stop_at_the_limit_and_not_before():
    with RunDeadline(0.3) as d:
        assert not d.cancel.is_set()
        assert d.cancel.wait(2.0)
        assert d.passed() and not d.user_cancelled


def test_the_users_cancel_reaches_the_runs_searches_and_is_told_apart():
    user = threading.Event()
    with RunDeadline(600.0, user) as d:
        user.set()
        assert d.cancel.wait(2.0)
        assert d.user_cancelled and not d.passed()


def test_closing_ends_the_watcher():
    d = RunDeadline(600.0)
    d.close()
    assert d._thread is not None and not d._thread.is_alive()


def _base(t: Table) -> FitResult:
    base = t.fit(DATASET, ModelChoice("paper"))
    t.fitted.clear()
    t.walls.clear()
    return base


def test_each_fit_of_a_step_gets_its_share_of_the_time_left():
    t = Table({S(): 10.0, S("a"): 4.0, S("b"): 8.0, S("c"): 9.0})
    d = RunDeadline(700.0, clock=Clock(), watch=False)  # the clock stands still
    out = sel.select_effects(DATASET, _base(t), list(POOL), fit=t.fit,
                             screen=sel.by_short_fits(t.screen), deadline=d)
    n = len(out.rounds[0].trials)
    assert n >= 2
    # the first of n singles gets 700/(n + k + 1), k = SCREEN_KEEP: as many pair fits may follow
    k = sel.SCREEN_KEEP
    assert t.walls[:n] == [pytest.approx(700.0 / (n - i + k + 1)) for i in range(n)]
    assert all(w is not None for w in t.walls)


class Expiring(Table):
    """Fits that move the clock on by ``cost_s`` each, and raise as a search watching the run's
    cancel does once the limit is passed."""

    def __init__(self, errors: Any, clock: Clock, deadline_s: float, cost_s: float) -> None:
        super().__init__(errors)
        self.clock, self.deadline_s, self.cost_s = clock, deadline_s, cost_s

    def fit(self, ds: Any, choice: ModelChoice, *, starts: Sequence[ModelChoice] = (),
            max_wall_s: float | None = None) -> FitResult:
        if self.clock.t >= self.deadline_s:
            raise SearchCancelledError("search cancelled")
        self.clock.t += self.cost_s
        return super().fit(ds, choice, starts=starts, max_wall_s=max_wall_s)


def test_the_limit_keeps_the_steps_taken_and_says_where_it_ended():
    # step 1 fits and adds "a" alone (10 -> 4; "b" screens too poorly alone to be paired), its
    # fit takes the clock past the limit; step 2 would add "b" (4 -> 1), but its fit is stopped
    clock = Clock()
    clock.t = 0.0  # the fits' clock counts from the run's start
    errors = {S(): 10.0, S("a"): 4.0, S("c"): 9.5, S("d"): 9.5, S("e"): 9.5, S("a", "b"): 1.0}
    t = Expiring(errors, clock, deadline_s=50.0, cost_s=100.0)
    base = _base(t)
    clock.t = 0.0
    d = RunDeadline(50.0, clock=clock, watch=False)
    said: list[str] = []
    out = sel.select_effects(DATASET, base, list(POOL), fit=t.fit,
                             screen=sel.by_short_fits(t.screen), deadline=d, say=said.append)
    assert [(s.kind, s.effects) for s in out.steps] == [("add", ("a",))]
    assert out.final.choice.effects == ("a",)
    assert "forward step 2" in out.time_limited
    assert "backward elimination was not run" in out.time_limited
    assert any(m.startswith("time limit:") for m in said)


def test_the_users_cancel_is_not_taken_for_the_limit():
    user = threading.Event()
    user.set()
    t = Table({S(): 10.0, S("a"): 4.0})
    base = _base(t)
    d = RunDeadline(600.0, user, watch=False)

    def cancelled(*_a: Any, **_k: Any) -> FitResult:
        raise SearchCancelledError("search cancelled")

    with pytest.raises(SearchCancelledError):
        sel.select_effects(DATASET, base, list(POOL), fit=cancelled,
                           screen=sel.by_short_fits(t.screen), deadline=d)


def test_a_run_that_ends_in_time_is_not_marked():
    t = Table({S(): 10.0, S("a"): 4.0})
    with RunDeadline(600.0) as d:
        out = sel.select_effects(DATASET, _base(t), list(POOL), fit=t.fit,
                                 screen=sel.by_short_fits(t.screen), deadline=d)
    assert out.time_limited == "" and out.final.choice.effects == ("a",)


def test_the_watcher_stops_within_its_period():
    t0 = time.monotonic()
    with RunDeadline(0.2) as d:
        d.cancel.wait(2.0)
    assert time.monotonic() - t0 < 1.0


def test_a_limit_inside_backward_elimination_keeps_the_forward_steps():
    # step 1 adds "a"; step 2 has nothing significant; the refit without "a" is stopped
    clock = Clock()
    clock.t = 0.0  # the fits' clock counts from the run's start
    t = Expiring({S(): 10.0, S("a"): 4.0, S("c"): 9.5, S("d"): 9.5, S("e"): 9.5}, clock,
                 deadline_s=50.0, cost_s=100.0)
    base = _base(t)
    clock.t = 0.0
    out = sel.select_effects(DATASET, base, list(POOL), fit=t.fit,
                             screen=sel.by_short_fits(t.screen),
                             deadline=RunDeadline(50.0, clock=clock, watch=False))
    assert out.final.choice.effects == ("a",)
    assert "backward elimination" in out.time_limited
