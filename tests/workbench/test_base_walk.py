"""The Gauss-Newton walk of the base parameters at a candidate's scan point (fitting._BaseWalk):
kept starts walk on while a step still gains, and stop after GN_STALL steps in a row without."""

from __future__ import annotations

import numpy as np

from rigctl.workbench import fitting
from rigctl.workbench.fitting import GN_MIN_GAIN, GN_STALL, _BaseWalk
from rigctl.workbench.identify import FreeParam

FREE = [FreeParam("a", -100.0, 100.0, False, 1.0), FreeParam("b", -100.0, 100.0, False, 1.0)]
BOUNDS = (np.full(2, -100.0), np.full(2, 100.0))
A3 = np.array([[1.0, 0.9], [0.3, 1.0], [0.5, -0.4]])


class _Linear:
    """r(u) = A u - y, counting its evaluations (stands in for a simulation)."""

    def __init__(self, A: np.ndarray, y: np.ndarray) -> None:
        self.A, self.y, self.costs = A, y, []

    def __call__(self, dataset, choice, fns):
        vec = self.A @ np.array([choice.values["a"], choice.values["b"]]) - self.y
        self.costs.append(float(vec @ vec))
        return vec


class _Choice:
    def __init__(self, values=None):
        self.values = values or {}

    def with_values(self, values):
        return _Choice({**self.values, **values})


def _walk(monkeypatch, A, J0):
    problem = _Linear(np.asarray(A, float), np.array([3.0, -2.0, 1.0]))
    monkeypatch.setattr(fitting, "_vector_or_none", problem)
    pt = {"a": 0.0, "b": 0.0, "effect.x": 1.0}
    vec0 = problem(None, _Choice(pt), None)
    problem.costs.clear()
    walk = _BaseWalk(pt, (float(vec0 @ vec0), dict(pt)))
    J0 = np.asarray(J0, float)
    walk.start(FREE, J0, vec0, np.linalg.lstsq(J0, -vec0, rcond=None)[0])
    return walk, problem


def test_a_walk_with_a_poor_jacobian_goes_on_while_it_gains(monkeypatch):
    # Broyden's updates correct a poor starting Jacobian over several steps
    walk, problem = _walk(monkeypatch, A3, np.eye(3, 2))
    walk.advance(None, _Choice(), FREE, BOUNDS, (0.0, 1.0), 2)
    after_two = walk.best[0]
    walk.advance(None, _Choice(), FREE, BOUNDS, (0.0, 1.0), 3)
    assert after_two < (1 - GN_MIN_GAIN) * problem.costs[0]  # the second step still gained
    assert len(problem.costs) > 2 and walk.best[0] < after_two
    assert walk.best[1]["effect.x"] == 1.0  # only the base parameters move


def test_a_walk_that_stops_gaining_stops_after_gn_stall_steps(monkeypatch):
    # an exact Jacobian reaches the least-squares minimum of a linear problem in one step:
    # nothing is left to gain after it
    walk, problem = _walk(monkeypatch, A3, A3)
    walk.advance(None, _Choice(), FREE, BOUNDS, (0.0, 1.0), 10)
    assert len(problem.costs) == 1 + GN_STALL
    r_min = A3 @ np.linalg.lstsq(A3, [3.0, -2.0, 1.0], rcond=None)[0] - [3.0, -2.0, 1.0]
    assert abs(walk.best[0] - float(r_min @ r_min)) < 1e-9 and walk.best[0] > 0.1


def test_a_point_that_cannot_be_run_ends_the_walk(monkeypatch):
    walk, _ = _walk(monkeypatch, A3, np.eye(3, 2))
    monkeypatch.setattr(fitting, "_vector_or_none", lambda d, c, f: None)
    best = walk.best
    walk.advance(None, _Choice(), FREE, BOUNDS, (0.0, 1.0), 5)
    assert walk.best == best and walk.u is None
