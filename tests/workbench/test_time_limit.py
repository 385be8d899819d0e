"""A point whose evaluation takes far longer than the search's typical one is stopped and counts
as a point that cannot be run (search_pool.TIME_LIMIT_FACTOR): one chattering model run must not
hold a search for minutes. The limit is the pool's own measure (a median of its evaluations), so
the tests set its factor and floor, not the machine's speed."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest

from rigctl.model import Drive, Simulator, build_model, run_clock
from rigctl.model.simulator import TimeLimitError
from rigctl.records.dataset import prepare_dataset
from rigctl.workbench import search_pool as sp
from rigctl.workbench.budget import Budget
from rigctl.workbench.campaigns import simulate_campaign
from rigctl.workbench.identify import free_params
from rigctl.workbench.model_choice import ModelChoice


@pytest.fixture(scope="module")
def dataset():
    return prepare_dataset(simulate_campaign(build_model("paper"), "tlre", seed=4,
                                             duration_scale=0.25))


def test_a_run_past_its_deadline_stops_with_a_clear_error():
    sim = Simulator(build_model("paper"), sample_rate_hz=1024.0)
    drive = Drive.constant(300.0, 1e-5, 5.0)
    assert sim.run(drive, record_elements=False, deadline=run_clock() + 600.0).n_samples > 0
    with pytest.raises(TimeLimitError, match=r"time limit at t = .* global slips"):
        sim.run(drive, record_elements=False, deadline=run_clock() - 1.0)


def test_the_deadline_is_read_on_cpu_time_which_other_work_does_not_spend():
    # a run's limit is for the work it does: time the thread spends waiting (other processes on
    # the core, here a sleep) does not count against it
    t0, w0 = run_clock(), time.monotonic()
    time.sleep(0.3)
    assert time.monotonic() - w0 >= 0.3
    assert run_clock() - t0 < 0.05
    x = 0.0
    while run_clock() - t0 < 0.05:  # work does
        x += 1.0
    assert x > 0.0


def _points(dataset, n):
    choice = ModelChoice("paper")
    free = free_params(choice, ["mu_s", "mu_k"])
    table = {p.name: p.value for p in choice.parameter_table()}
    u = np.array([fp.to_u(table[fp.name]) for fp in free])
    return choice, free, [sp.Point(u * (1.0 + 1e-4 * i)) for i in range(n)]


@pytest.mark.parametrize("workers", [0, 1])
def test_the_first_point_is_timed_alone_and_a_slower_one_is_not_run_to_its_end(
        dataset, monkeypatch, workers):
    choice, free, points = _points(dataset, 3)
    with sp.EvaluationPool(dataset, choice, free, Budget(), workers) as pool:
        assert pool.time_limit_s() is None  # nothing timed yet: no limit
        monkeypatch.setattr(sp, "TIME_LIMIT_FLOOR_S", 0.0)
        monkeypatch.setattr(sp, "TIME_LIMIT_FACTOR", 1e-6)  # any later run is "too slow"
        first, *rest = pool.evaluate(points)
        assert first.status == sp.OK and math.isfinite(first.elapsed_s)
        assert all(o.status == sp.FAILED and o.cost == math.inf for o in rest)
        assert not first.timed_out and all(o.timed_out for o in rest)
        assert pool.n_timed_out == 2  # counted, for the search's result (FitResult.n_timed_out)
        assert pool.time_limit_s() == pytest.approx(1e-6 * first.elapsed_s)


def test_the_limit_is_the_factor_times_the_median_and_never_below_the_floor(dataset):
    choice, free, points = _points(dataset, 3)
    with sp.EvaluationPool(dataset, choice, free, Budget(), 0) as pool:
        out = pool.evaluate(points)
        assert all(o.status == sp.OK for o in out)  # the default limit stops no ordinary point
        assert pool.n_timed_out == 0
        median = float(np.median([o.elapsed_s for o in out]))
        assert pool.time_limit_s() == pytest.approx(
            max(sp.TIME_LIMIT_FLOOR_S, sp.TIME_LIMIT_FACTOR * median))


SCALED_FRICTION = '''
"""scaled_friction: friction times (1 + c), as a plug-in term (the general path where c != 0)."""
from rigctl.model import Effect, ParamSpec


def mu_scaled(p, mu, x_m, v_m_s, t_s, fn_N, stick_s, z):
    return mu * (1.0 + p[0])


class ScaledFriction(Effect):
    name = "scaled_friction"
    summary = "friction times (1 + c)"
    signature = "every peak higher"
    reveal_protocol = "any"
    params = (ParamSpec("c", 0.0, -0.2, 0.2, "-", "relative change", off=0.0),)

    @staticmethod
    def friction_term():
        return mu_scaled
'''


@pytest.mark.parametrize("workers", [0, 1])
def test_each_integration_path_is_timed_against_its_own_evaluations(
        dataset, tmp_path, monkeypatch, workers):
    """A plug-in's terms act only away from off, and there the model runs the general path at a
    hundred or more times the exact path's cost: by design, not a chattering point. Timed against
    the exact path's median, every point with the term on would be stopped, and a screen of the
    user's own physics would see nothing beyond its off point."""
    path = tmp_path / "scaled_friction.py"
    path.write_text(SCALED_FRICTION)
    choice = ModelChoice("paper", ("scaled_friction",), {}, (str(path),))
    free = free_params(choice, ["scaled_friction.c"])
    (fp,) = free
    off = sp.Point(np.array([fp.to_u(0.0)]))
    on = [sp.Point(np.array([fp.to_u(c)])) for c in (0.01, 0.02, 0.03)]
    with sp.EvaluationPool(dataset, choice, free, Budget(), workers) as pool:
        assert not pool.general_path(off) and all(pool.general_path(p) for p in on)
        (first,) = pool.evaluate([off])  # the exact path timed
        assert first.status == sp.OK
        monkeypatch.setattr(sp, "TIME_LIMIT_FLOOR_S", 0.0)
        monkeypatch.setattr(sp, "TIME_LIMIT_FACTOR", 5.0)
        assert pool.time_limit_s(general=True) is None
        out = pool.evaluate([off, *on])  # the first point on the general path runs alone
        assert [o.status for o in out] == [sp.OK] * 4, [o.status for o in out]
        assert pool.n_timed_out == 0
        exact, general = pool.time_limit_s(), pool.time_limit_s(general=True)
        assert exact is not None and general is not None and general > 5.0 * exact
