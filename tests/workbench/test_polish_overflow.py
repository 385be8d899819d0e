"""The polish (search.SearchState.polish) on residuals whose squares overflow: scipy's trust-region
arithmetic squares them, and numpy's overflow warning must not reach the user's console (the
polish rejects such steps by their cost, as it rejects any worse step)."""

from __future__ import annotations

import warnings

import numpy as np

from rigctl.workbench.budget import Budget
from rigctl.workbench.identify import FreeParam
from rigctl.workbench.search import SearchState
from rigctl.workbench.search_pool import OK, Outcome, Point
from rigctl.workbench.search_space import SearchSpace


class _Pool:
    """Evaluates a residual that grows to 1e160 away from (0.3, 0.5)."""

    def __init__(self) -> None:
        self.calls = 0

    def evaluate(self, points: list[Point]) -> list[Outcome]:
        out = []
        for p in points:
            self.calls += 1
            u = np.asarray(p.u, dtype=np.float64)
            r = np.array([1e160 * (u[0] - 0.3), 1e160 * (u[1] - 0.5), u[0] + u[1]])
            with np.errstate(over="ignore"):
                cost = float(r @ r)
            out.append(Outcome(cost, OK, r))
        return out


def test_a_polish_through_overflowing_residuals_warns_nothing():
    free = (FreeParam("a", -10.0, 10.0, False, 1.0), FreeParam("b", -10.0, 10.0, False, 1.0))
    space = SearchSpace(free, np.ones(2), np.full(2, -10.0), np.full(2, 10.0), {}, False, {}, {})
    pool = _Pool()
    search = SearchState(space, pool, Budget(max_evaluations=60), 1, False)  # type: ignore[arg-type]
    search.evaluate([np.array([0.31, 0.52])])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        search.polish()
    assert pool.calls > 1  # it did run
    overflow = [w for w in caught if "overflow" in str(w.message)]
    assert not overflow, [str(w.message) for w in overflow]
