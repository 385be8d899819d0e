"""Screening effect sets at the cost of about one Jacobian each: the score test, and spread points.

Forward selection (:mod:`rigctl.workbench.selection`) fits only the few effect sets a screen
keeps. This screen ranks every set by what adding it could gain with the model's own parameters
re-fitted *linearly*, from a handful of evaluations of the model with the set added:

1. **The model's own metric, once.** J_b, the residual's Jacobian over the model's own
   coordinates at its fitted values (its fit's where it has one, else one forward-difference
   Jacobian, :meth:`rigctl.workbench.search.SearchState.jacobian`), and Q, an orthonormal basis of
   its column space (SVD, singular values below :data:`RANK_TOL` of the largest dropped). A
   residual r at a point whose base parameters are those of the model is lowered by a
   Gauss-Newton step over them to r - Q Q^T r: the *linear profile* of r over the base.
2. **The score test** (Rao 1948; the Lagrange-multiplier test, e.g. Seber & Wild, *Nonlinear
   Regression*, 1989, sec. 5.9). At the effect's off values (the set added, the model itself bit
   for bit, :class:`~rigctl.workbench.search_space.ExactOff`) the forward-difference columns J_e
   of the coordinates that switch it on, made orthogonal to the base, G = J_e - Q Q^T J_e; the
   Gauss-Newton step over them from the model's residual r_0, damped by the space's prior
   (each coordinate's expected spread s: (G^T G + S^-1) d = -G^T r_0, as
   :meth:`~rigctl.workbench.search.SearchState.metric` ranks starts), is *evaluated*, and its
   residual profiled over the base. Its gain predicted to first order, |r_0|^2 - |r_0 + G d|^2,
   is the score statistic (in squared scatter units, the unit of the residual).
3. **The typical size and spread points.** An effect whose influence vanishes smoothly at off (a
   Stribeck velocity going to 0) has no slope there, so no score; and on a record whose slips
   shift with the least change of a parameter the residual is rough at a finite difference's
   scale, so the score can point anywhere. The set at its typical size (its library defaults at
   the data's scale, :func:`~rigctl.workbench.search_space.typical_point`, the centre of its
   prior) and :data:`SPREAD_POINTS` scrambled Sobol points over
   the plausible ranges of the set's coordinates (:class:`~rigctl.workbench.search_space.
   SearchSpace`, the same ranges a full fit spreads its starts over), the base at the model's
   values, each evaluated and profiled over the base.
4. **The same points with the base levels re-read.** An effect at a finite size can shift the
   levels the base fit set far beyond what the linear profile follows (rate-and-state aging adds
   b ln(1 + theta V_ref / D_c) to every friction level: a few per cent of mu, tens of scatter
   units, and the slips' timing moves with it). So each of those points that can be run is also
   evaluated with the base's friction levels and stiffnesses re-read from the data at the
   effect's values (the ratio guess of :mod:`rigctl.workbench.guess`, read from the slips of the
   point's own evaluation in the worker that made it: :attr:`~rigctl.workbench.search_pool.
   Point.reread`), as the data-scale start reads them for the model itself; profiled the same
   way.

A set's screened error is the model's error scaled by the lowest profiled cost over its points
*relative to the profiled cost of the off point* (the model itself, its base re-fitted linearly):
E_set = E_model sqrt(min cost / cost_off), so a set that helps nowhere screens at the model's
error. The off point's own linear re-fit is no gain of the set: the model has it without any
effect, and where the model's fit is at its least-squares minimum it is zero (J_b^T r_0 = 0).
Where it is not (a fit ended by its budget, a residual rough at a finite difference's scale), the
linear re-fit predicts a gain at every point alike, which the full fits then do not find; counted
as the set's gain it would make every set look significant. Every screened cost is that of an
evaluated residual; only the base's re-fit is linear. Costs: about 3 + 2 SPREAD_POINTS + 1-3
evaluations per on-coordinate per set (a re-read costs no run of its own, its point one
evaluation): 20-25 for the library's effects, about a third of a 60-evaluation short search.
The point where it was found, with the base moved by the damped Gauss-Newton step the profile
assumes, is the set's start for its full fit (:attr:`Screened.start`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from rigctl.records.dataset import Dataset
from rigctl.records.signals import FloatArray
from rigctl.workbench.budget import Budget
from rigctl.workbench.element_count import spreads_elements
from rigctl.workbench.identify import FitResult
from rigctl.workbench.interrupts import signals_raise
from rigctl.workbench.model_choice import ModelChoice, effect_of, with_effects
from rigctl.workbench.parallel import default_workers
from rigctl.workbench.round_eta import RoundClock
from rigctl.workbench.search import SearchState
from rigctl.workbench.search_pool import OK, EvaluationPool
from rigctl.workbench.search_space import (
    SearchSpace,
    build_space,
    effects_at_data_scale,
    typical_point,
)

Say = Callable[[str], None]

SPREAD_POINTS = 8
"""Sobol points per effect set over its plausible ranges (a power of two keeps the scrambled
sequence balanced): with one to three coordinates per effect, eight points put at least two in
each half of every coordinate's range and one in each octant of three, enough to land in the basin
of an optimum that spans a fraction of its range."""
RANK_TOL = 1e-8
"""Singular values of J_b below this fraction of the largest span no direction of the base:
parameters the data do not move (their columns zero or a combination of others)."""


@dataclass(frozen=True)
class Screened:
    """One effect set's screen: its screened error, the score statistic, what it cost."""

    effects: tuple[str, ...]
    error: float
    """The model's error scaled by the set's lowest profiled cost over the off point's: what the
    set adds to the linear re-fit of the base (module docstring)."""
    score: float
    """The score statistic: the first-order gain of the Gauss-Newton step over the set's
    on-coordinates at off, in squared scatter units (0 where it has none)."""
    evaluations: int
    best_at: str
    """Where the screened error was found: ``off``, ``score step``, ``typical size`` or
    ``spread point``."""
    start: ModelChoice | None = None
    """The model with the set added at the point where the screened error was found, its base
    moved by the linear re-fit that point's profile assumes (:meth:`BaseMetric.step`): a start for
    the set's full fit, so that the fit begins where the screen saw its gain (None where that
    point is the model itself, which every fit starts from)."""
    score_df: int = 0
    """The coordinates the score's step moves (the statistic's degrees of freedom; 0 where the
    set has no score)."""


def base_basis(jacobian: FloatArray) -> FloatArray:
    """An orthonormal basis Q of the column space of ``jacobian`` (module docstring, 1)."""
    J = np.nan_to_num(np.asarray(jacobian, dtype=np.float64))
    if J.size == 0:
        return np.zeros((J.shape[0], 0))
    U, s, _ = np.linalg.svd(J, full_matrices=False)
    if s.size == 0 or not s[0] > 0.0:
        return np.zeros((J.shape[0], 0))
    return np.asarray(U[:, s > RANK_TOL * s[0]], dtype=np.float64)


def profiled_cost(r: FloatArray, Q: FloatArray) -> float:
    """|r - Q Q^T r|^2: the cost of residual ``r`` after a Gauss-Newton step over the base."""
    rp = r - Q @ (Q.T @ r)
    return float(rp @ rp)


def screened_error(model_error: float, cost: float, cost_off: float, cost_model: float) -> float:
    """A set's screened error: ``model_error`` scaled by the square root of its lowest profiled
    ``cost`` over the off point's profiled cost ``cost_off`` (module docstring; ``cost_model``,
    the model's own |r_0|^2, where the off point's profile removes everything)."""
    ref = cost_off if cost_off > 0.0 else cost_model
    return model_error * math.sqrt(cost / ref) if ref > 0.0 else model_error


@dataclass(frozen=True)
class BaseMetric:
    """The model's own Jacobian J_b at its values (columns: the base coordinates ``names``) and
    the orthonormal basis Q of its columns."""

    J: FloatArray
    names: tuple[str, ...]
    Q: FloatArray

    @classmethod
    def of(cls, J: FloatArray, names: Sequence[str]) -> BaseMetric:
        return cls(np.nan_to_num(np.asarray(J, dtype=np.float64)), tuple(names), base_basis(J))

    def step(self, r: FloatArray, space: SearchSpace) -> dict[int, float]:
        """The damped Gauss-Newton step over the base from residual ``r``, by coordinate of
        ``space``: (J_b^T J_b + S^-1) d = -J_b^T r with the space's prior spreads s, as the
        search's metric stage steps (the linear re-fit the profile assumes, damped where the data
        do not determine a direction). Coordinates of ``names`` that ``space`` lacks are left."""
        index = {fp.name: i for i, fp in enumerate(space.free)}
        cols = [k for k, n in enumerate(self.names) if n in index]
        if not cols:
            return {}
        J = self.J[:, cols]
        at = [index[self.names[k]] for k in cols]
        prior = np.diag(1.0 / space.std[at] ** 2)
        d = -np.linalg.solve(J.T @ J + prior, J.T @ np.nan_to_num(r))
        return {i: float(v) for i, v in zip(at, d, strict=True)}


def _effect_coordinates(space: SearchSpace, effects: Sequence[str], count_new: bool) -> list[int]:
    idx = [i for i, fp in enumerate(space.free) if effect_of(fp.name) in effects]
    if count_new and space.count:
        idx.append(len(space.free))
    return idx


class _SetScreen:
    """The screen of one effect set, in its own evaluation pool."""

    def __init__(self, dataset: Dataset, model: FitResult, effects: tuple[str, ...],
                 budget: Budget, workers: int, seed: int) -> None:
        self.dataset, self.model, self.effects, self.seed = dataset, model, effects, seed
        choice = effects_at_data_scale(dataset, with_effects(model.choice, effects), effects)
        self.choice: ModelChoice = choice
        self.space = build_space(dataset, choice, choice,
                                 spreads_elements(choice)).switching_off(effects)
        self.x0 = self.space.off_point(self.space.vector(choice))
        self.coords = _effect_coordinates(self.space, effects,
                                          not spreads_elements(model.choice))
        self.on = [i for i in self.coords if i in self.space.off]
        self.base = [i for i in range(len(self.space.free)) if i not in self.coords]
        self.budget, self.workers = budget, workers

    def run(self, metric: BaseMetric | None, say: Say) -> tuple[Screened, BaseMetric | None]:
        """The set's screen, and the base's metric (computed here where not given)."""
        used = self.budget.used
        with signals_raise(), EvaluationPool(self.dataset, self.choice, self.space.free,
                                             self.budget, self.workers) as pool:
            search = SearchState(self.space, pool, self.budget, self.seed, False)
            labelled = [*(("typical size", x) for x in self._typical_point()),
                        *(("spread point", x) for x in self._spread_points())]
            outcomes = search.evaluate([self.x0, *(x for _, x in labelled)],
                                       reread=[False] + [True] * len(labelled))
            o0 = outcomes[0]
            if o0.status != OK or o0.vector is None:
                say(f"  screened {' + '.join(self.effects)}: the model itself cannot be run")
                return (Screened(self.effects, math.inf, 0.0, self.budget.used - used, "off"),
                        metric)
            r0 = o0.vector
            if metric is None or metric.Q.shape[0] != r0.shape[0]:
                search.cols = self.base
                metric = BaseMetric.of(search.jacobian(self.x0, r0)[:, self.base],
                                       [self.space.free[i].name for i in self.base])
            Q = metric.Q
            found = [(profiled_cost(r0, Q), "off", self.x0, r0)]
            found += [(profiled_cost(o.vector, Q), label, x, o.vector)
                      for (label, x), o in zip(labelled, outcomes[1:], strict=True)
                      if o.status == OK and o.vector is not None]
            reread = [(f"{label}, levels re-read", self._with_base(x, o.reread))
                      for (label, x), o in zip(labelled, outcomes[1:], strict=True)
                      if o.reread]  # None where the point failed
            found += [(profiled_cost(o.vector, Q), label, x, o.vector)
                      for (label, x), o in zip(reread, search.evaluate([x for _, x in reread]),
                                               strict=True)
                      if o.status == OK and o.vector is not None]
            score = 0.0
            if self.on:
                search.cols = self.on
                Je = search.jacobian(self.x0, r0)[:, self.on]
                G = Je - Q @ (Q.T @ Je)
                r_perp = r0 - Q @ (Q.T @ r0)
                prior = np.diag(1.0 / self.space.std[self.on] ** 2)
                d = -np.linalg.solve(G.T @ G + prior, G.T @ r_perp)
                rd = r_perp + G @ d
                score = max(float(r_perp @ r_perp - rd @ rd), 0.0)
                x = self.x0.copy()
                x[self.on] += d
                (o,) = search.evaluate([x])
                if o.status == OK and o.vector is not None:
                    found.append((profiled_cost(o.vector, Q), "score step", x, o.vector))
        cost, where, x_at, r_at = min(found, key=lambda f: f[0])
        error = screened_error(self.model.error, cost, found[0][0], float(r0 @ r0))
        start = None if where == "off" else self._start(x_at, r_at, metric)
        out = Screened(self.effects, error, score, self.budget.used - used, where, start,
                       len(self.on))
        return out, metric

    def _start(self, x: FloatArray, r: FloatArray, metric: BaseMetric) -> ModelChoice:
        """The set's point ``x`` (residual ``r``) with the base moved by the linear re-fit: where
        the screened error was found, as a start for the full fit."""
        x = x.copy()
        for i, d in metric.step(r, self.space).items():
            x[i] += d
        x = np.clip(x, self.space.lower, self.space.upper)
        return self.choice.with_values(self.space.values(x))

    def _with_base(self, x: FloatArray, values: dict[str, float]) -> FloatArray:
        """``x`` with the base coordinates set to ``values`` (within their bounds)."""
        return np.clip(self.space.with_values(x, values, self.base), self.space.lower,
                       self.space.upper)

    def _typical_point(self) -> list[FloatArray]:
        """The set at its typical size (:func:`~rigctl.workbench.search_space.typical_point`),
        the base at the model's values: none where that is the off point."""
        typical = typical_point(self.dataset, self.choice, self.effects)
        if typical is None:
            return []
        x = self.space.vector(typical)
        return [] if np.array_equal(x, self.x0) else [x]

    def _spread_points(self) -> list[FloatArray]:
        idx = [i for i in self.coords if i in self.space.spread]
        if not idx:
            return []
        return self.space.sobol_points(self.x0, idx, SPREAD_POINTS, self.seed)


def score_screen(
    dataset: Dataset, model: FitResult, sets: Sequence[tuple[str, ...]], *,
    workers: int | None = None, budget: Budget | None = None, seed: int = 1,
    say: Say = lambda _m: None,
) -> list[Screened]:
    """Each effect set of ``sets`` added to the fitted ``model`` and screened (module docstring),
    best (lowest screened error) first. ``budget`` counts the screen's evaluations and cancels it
    (:meth:`~rigctl.workbench.budget.Budget.cancel`); a set's cost is fixed (module docstring), so
    no evaluation limit is applied."""
    budget = budget or Budget()
    n_workers = default_workers() if workers is None else workers
    metric: BaseMetric | None = None
    if model.jacobian is not None and model.jacobian.size and \
            model.jacobian.shape[1] == len(model.free):
        metric = BaseMetric.of(model.jacobian, model.free)
    out = []
    clock = RoundClock([1.0] * len(sets))
    for i, effects in enumerate(sets):
        one = _SetScreen(dataset, model, tuple(effects), budget, n_workers, seed)
        s, metric = one.run(metric, say)
        out.append(s)
        if math.isfinite(s.error):
            say(f"  screened {' + '.join(s.effects)}: {s.error:.3g} (score {s.score:.3g}, best "
                f"at the {s.best_at}, {s.evaluations} evaluations) {clock.finished(i)}")
    return sorted(out, key=lambda s: (s.error, -s.score))
