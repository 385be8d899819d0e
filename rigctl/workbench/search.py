"""Identification as one search: data-scale starts, CMA-ES, a least-squares polish, one budget.

(New; not yet used by ``diagnose``, which still calls :func:`rigctl.workbench.fitting.
identify_model` and :func:`~rigctl.workbench.fitting.fit_candidate`. docs/workbench.md, "The
search".)

1. **Space** (:mod:`rigctl.workbench.search_space`): every ``identify`` parameter of the base and
   the effects, the slider mass and drive damping where the data do not state them (the mass tied
   to a resolved ringing by :class:`~rigctl.workbench.identify.Objective` is no coordinate), and
   log2 of the element count where an effect spreads the elements' thresholds; each coordinate with
   an initial standard deviation, a quarter of where its optimum is expected.
2. **Starts**: the model's current values and the same at the data's scale
   (:func:`~rigctl.workbench.fitting.data_scaled`); from the better, the effects switched off and
   Sobol points (``scipy.stats.qmc``) over the effects' plausible ranges, not only near off (an
   effect whose influence vanishes smoothly at off, a Stribeck velocity going to 0, gives no slope
   there to follow). The best start is the mean of the first CMA-ES population.
3. **Global stage: CMA-ES** (``cma``, Hansen & Ostermeier 2001; IPOP/BIPOP restarts, Auger & Hansen
   2005, Hansen 2009). Why: it is invariant to scaling and rotation of the internal coordinates
   (the stiffness split, mass and friction levels are strongly correlated); it uses only the rank
   of the costs, so it is robust on the piecewise-constant, slightly noisy objective that event
   features make (a slip gained or lost is a step); it has few settings, all derived below; and it
   is at its best at 3-20 dimensions, where this search lives. Differential evolution needs
   populations of 10-15 times the dimension (ten times the evaluations per generation);
   basinhopping assumes smooth local minima a local method can descend. The objective is |r|^2 of
   :class:`~rigctl.workbench.identify.Objective`'s residual vector; a point whose model misses most
   measured slips ranks after every point that does not, and one that cannot be run after both,
   so the trap (a flat error no step leaves) is never the answer while another point exists.
4. **Polish**: bounded least squares (:func:`~rigctl.workbench.identify.least_squares_fit`) from
   the best point with what is left of the budget, then the uncertainties
   (:func:`~rigctl.workbench.identify.with_uncertainties`), as ``identify_model`` reports them.

The population is evaluated in parallel worker processes holding the dataset once
(:mod:`rigctl.workbench.search_pool`). One :class:`~rigctl.workbench.budget.Budget` bounds
everything: evaluations and/or wall seconds, cancel, progress with an ETA.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace

import cma
import numpy as np
from scipy.stats import qmc

from rigctl.model import ParameterError
from rigctl.records.dataset import Dataset
from rigctl.records.rig_description import check_names
from rigctl.records.signals import FloatArray
from rigctl.workbench.budget import Budget
from rigctl.workbench.element_count import spreads_elements
from rigctl.workbench.fitting import data_scaled
from rigctl.workbench.identify import (
    FAILED_FACTOR,
    FAILED_RESIDUAL,
    FitResult,
    fn_range,
    free_params,
    physically_valid,
)
from rigctl.workbench.model_choice import ModelChoice
from rigctl.workbench.parallel import default_workers
from rigctl.workbench.search_pool import (
    OK,
    TRAPPED,
    EvaluationPool,
    Outcome,
    PolishTask,
)
from rigctl.workbench.search_space import SearchSpace, build_space

MIN_GENERATIONS = 10
"""Default budget: at least this many CMA-ES generations. In a basin the step size shrinks by
about a factor e every few generations (its cumulation time is about (n + mu_eff) / mu_eff,
Hansen 2016, table 1), so ten take the spread from a quarter of a plausible range down to the
polish's scale (TOL_X)."""
GENERATIONS_PER_DIM = 2
"""... and this many more per dimension: 2n generations let the step size and the main
correlations (stiffness split, mass, friction levels) adapt; learning the full covariance would
take about n^2 / mu_eff generations, and the polish's Jacobian does that locally instead."""
POLISH_ITERATIONS = 4
"""Trust-region iterations kept for the polish: from a point in the basin Gauss-Newton converges
in a few steps."""
TOL_COST = 1.0
"""CMA-ES stops once the population's costs differ by less than this: |r|^2 is in squared scatter
units, and one squared scatter unit is one feature moved by its own scatter, below what the data
resolve."""
TOL_X = 0.05
"""CMA-ES stops once its spread is below this in every internal coordinate (5 % of a parameter,
the polish's own first finite-difference step, identify.FD_STEP): below it the local least
squares converges faster than a population."""
MAX_RESTARTS = 9
"""Restarts CMA-ES may make within the budget (cma's default number when restarts are asked for):
the budget, not this, ends them."""


def search_model(
    dataset: Dataset,
    choice: ModelChoice,
    *,
    budget: Budget | None = None,
    workers: int | None = None,
    with_uncertainty: bool = True,
    seed: int = 1,
) -> FitResult:
    """Identify ``choice`` on ``dataset`` by the one search (module docstring).

    ``budget``: evaluations and/or seconds (default: :func:`default_budget`); ``workers``: worker
    processes evaluating a population (default: the CPUs; 0 evaluates in this process).
    Raises :class:`~rigctl.workbench.budget.SearchCancelledError` when the budget is cancelled."""
    t0, c0 = time.perf_counter(), time.process_time()
    rig = dataset.rig
    check_names(rig, [p.name for p in choice.parameter_table()])
    if rig.fixed:
        choice = choice.with_values(rig.fixed)
    if not physically_valid(choice, fn_range(dataset)):
        raise ParameterError(f"{choice.label()}: kinetic friction is not below static friction")
    identify_free = free_params(choice, rig=rig)
    scaled = data_scaled(dataset, choice, identify_free)
    space = build_space(dataset, choice, scaled or choice, spreads_elements(choice))
    budget = budget or default_budget(space.dim)
    n_workers = default_workers() if workers is None else workers
    with EvaluationPool(dataset, choice, space.free, budget, n_workers) as pool:
        search = _Search(space, pool, budget, seed)
        search.starts([choice, *([scaled] if scaled is not None else [])])
        search.cma(reserve=polish_reserve(len(space.free), with_uncertainty))
        result = search.polish(choice, with_uncertainty)
    return replace(result, n_evaluations=budget.used, elapsed_s=time.perf_counter() - t0,
                   cpu_s=time.process_time() - c0)


def default_budget(dim: int) -> Budget:
    """Evaluations for MIN_GENERATIONS + GENERATIONS_PER_DIM x ``dim`` CMA-ES generations of the
    default population, the starts (about one population), the probes (2 ``dim``), the polish
    and the uncertainties."""
    generations = MIN_GENERATIONS + GENERATIONS_PER_DIM * dim + 1
    return Budget(max_evaluations=generations * popsize(dim) + 2 * dim
                  + polish_reserve(dim, True))


def popsize(dim: int) -> int:
    """CMA-ES's default population, 4 + floor(3 ln n): the smallest that estimates the covariance
    update reliably (Hansen 2016, table 1); IPOP/BIPOP restarts enlarge it where the landscape
    is multimodal."""
    return 4 + int(3.0 * math.log(max(dim, 1)))


def jacobian_cost(n: int) -> int:
    """Evaluations of one finite-difference Jacobian of ``n`` parameters, at most: identify's
    adaptive forward difference tries up to three steps per column."""
    return 3 * n


def polish_reserve(n: int, with_uncertainty: bool) -> int:
    """Evaluations kept from the global stage for POLISH_ITERATIONS of the polish (each one
    residual and one Jacobian at most), its final evaluation, and the uncertainties' Jacobian."""
    return POLISH_ITERATIONS * (1 + jacobian_cost(n)) + 1 \
        + (jacobian_cost(n) if with_uncertainty else 0)


class _Search:
    """The state of one search: the best point seen and how each evaluated point ranks."""

    def __init__(self, space: SearchSpace, pool: EvaluationPool, budget: Budget,
                 seed: int) -> None:
        self.space, self.pool, self.budget, self.seed = space, pool, budget, seed
        self.best: tuple[float, FloatArray] | None = None
        """Lowest cost of a point whose model makes the slips, and that point."""
        self.best_any: tuple[float, FloatArray] | None = None
        """The best point by rank (trapped or failed too): the answer only where no point makes
        the slips."""
        self.failed_cost = FAILED_RESIDUAL**2
        self.stop_reason = ""

    def rank(self, xs: list[FloatArray]) -> list[float]:
        """Evaluate ``xs`` and give each its ranked cost: |r|^2 where the model makes the slips;
        after all of those the points that miss most slips (by their |r|^2), then the points that
        cannot be run (the failure penalty of identify.Objective, FAILED_FACTOR times the first
        valid norm)."""
        outcomes: list[Outcome] = self.pool.evaluate([self.space.point(x) for x in xs])
        if self.best is None and any(o.status == OK for o in outcomes):
            first = next(o.cost for o in outcomes if o.status == OK)
            self.failed_cost = max(FAILED_RESIDUAL, FAILED_FACTOR * math.sqrt(first))**2
        ranked = []
        for x, o in zip(xs, outcomes, strict=True):
            if o.status == OK:
                f = o.cost
                if self.best is None or f < self.best[0]:
                    self.best = (f, np.array(x))
            elif o.status == TRAPPED:
                f = self.failed_cost + min(o.cost, self.failed_cost)
            else:
                f = 3.0 * self.failed_cost
            if self.best_any is None or f < self.best_any[0]:
                self.best_any = (f, np.array(x))
            ranked.append(f)
        return ranked

    @property
    def x_best(self) -> FloatArray:
        pick = self.best or self.best_any
        assert pick is not None
        return pick[1]

    def starts(self, choices: list[ModelChoice]) -> None:
        """The model's values and its data-scale start; from the better, the effects off and
        Sobol points over their plausible ranges (as many as a population, rounded up to a power
        of two to keep the Sobol sequence balanced)."""
        self.rank([self.space.vector(c) for c in choices])
        if not self.space.spread:
            return
        x0 = self.x_best
        idx = sorted(self.space.spread)
        m = max(1, math.ceil(math.log2(popsize(self.space.dim))))
        unit = qmc.Sobol(d=len(idx), scramble=True, seed=self.seed).random_base2(m)
        lo = np.array([self.space.spread[i][0] for i in idx])
        hi = np.array([self.space.spread[i][1] for i in idx])
        points = []
        for row in [np.zeros(len(idx)), *unit]:  # the zero row: each effect at its off end
            x = x0.copy()
            x[idx] = lo + row * (hi - lo)
            points.append(x)
        self.rank(points)
        self.budget.report(f"starts: {self.budget.used} evaluated")

    def scaled_std(self) -> FloatArray:
        """Each coordinate's initial standard deviation, shrunk to the data's sensitivity.

        The space's standard deviations say where the optimum may lie; the data may pin a
        coordinate far more tightly (a friction level read from the peaks). Each coordinate is
        probed one deviation either side of the best start (one batch, 2n evaluations); where the
        cost rises by more than its own value there, the deviation is shrunk to where a
        quadratic through the probes rises by that much, sqrt(f0 / rise) of it: the variables
        scaled to similar sensitivity, as CMA-ES asks (Hansen 2016, appendix B). Never below
        TOL_X (a smaller spread is the polish's business)."""
        x0, std = self.x_best, self.space.std.copy()
        dim = self.space.dim
        if not self.best or self.budget.evaluations_left() < 2 * dim:
            return std
        f0 = self.best[0]
        probes = [np.clip(x0 + s * std[i] * np.eye(dim)[i], self.space.lower, self.space.upper)
                  for i in range(dim) for s in (-1.0, 1.0)]
        f = self.rank(probes)
        for i in range(dim):
            rise = max(f[2 * i], f[2 * i + 1]) - f0
            if rise > f0 > 0.0:
                std[i] = max(std[i] * math.sqrt(f0 / rise), TOL_X)
        return std

    def cma(self, reserve: int) -> None:
        """CMA-ES from the best start with IPOP/BIPOP restarts while the budget lasts."""
        std = self.scaled_std()
        x0 = np.clip(self.x_best, self.space.lower, self.space.upper)
        lam = popsize(self.space.dim)

        def out_of_budget(es: cma.CMAEvolutionStrategy) -> bool:
            return bool(self.budget.evaluations_left() - reserve < es.popsize)

        def progress(es: cma.CMAEvolutionStrategy) -> None:
            best = self.best[0] if self.best is not None else math.inf
            self.budget.report(f"global search: generation {es.countiter}, population "
                               f"{es.popsize}, best |r|^2 {best:.4g}")

        if self.budget.evaluations_left() - reserve < lam:
            self.stop_reason = "no budget left for a population"
            return
        opts = {
            "bounds": [list(self.space.lower), list(self.space.upper)],
            "CMA_stds": list(std), "popsize": lam, "tolfun": TOL_COST,
            "tolx": TOL_X, "seed": self.seed, "verbose": -9, "verb_log": 0, "verb_disp": 0,
            "termination_callback": [out_of_budget], "signals_filename": "",
            "eval_final_mean": False,
        }
        _, es = cma.fmin2(None, x0, 1.0, opts, restarts=MAX_RESTARTS, bipop=True,
                          parallel_objective=self.rank, callback=progress,
                          eval_initial_x=False)
        self.stop_reason = ", ".join(sorted(es.stop())) or "budget"

    def polish(self, choice: ModelChoice, with_uncertainty: bool) -> FitResult:
        """The local least-squares fit from the best point with what is left of the budget (as
        many iterations as it surely pays for; none where it pays for none: the best point is
        then evaluated as it is)."""
        values = self.space.values(self.x_best)
        n = len(self.space.free)
        model = choice
        if "n_elements" in values:
            model = choice.with_values({"n_elements": values.pop("n_elements")})
        free = self.space.free
        left = self.budget.evaluations_left() - 1 - (jacobian_cost(n) if with_uncertainty else 0)
        max_nfev = int(min(left, 1e6) // (1 + jacobian_cost(n)))
        if max_nfev < 1:
            model, free, with_uncertainty = model.with_values(values), (), False
            max_nfev = 1
        self.budget.report("local polish")
        result = self.pool.polish(PolishTask(model, free, values, max_nfev, with_uncertainty))
        result.free = tuple(fp.name for fp in self.space.free)
        result.message = f"CMA-ES ({self.stop_reason}), then least squares: {result.message}"
        self.budget.report("done", evaluations_left=0.0)
        return result
