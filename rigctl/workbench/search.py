"""Identification as one search: data-scale starts, CMA-ES, a least-squares polish, one budget.

(``compare``, the ranking and ``diagnose --auto`` identify every model with it,
:mod:`rigctl.workbench.auto`. docs/identification.md, "The search".)

1. **Space** (:mod:`rigctl.workbench.search_space`): every ``identify`` parameter of the base and
   the effects, the slider mass and drive damping where the data do not state them (the mass tied
   to a resolved ringing by :class:`~rigctl.workbench.identify.Objective` is no coordinate), and
   log2 of the element count where an effect spreads the elements' thresholds; each coordinate with
   an initial standard deviation, a quarter of where its optimum is expected.
2. **Starts**: the model's current values, the same at the data's scale
   (:func:`~rigctl.workbench.data_start.data_scaled`), the effects being added at their typical size
   (:func:`~rigctl.workbench.search_space.typical_point`) and the ratio guess
   (:mod:`rigctl.workbench.guess`), the mass the drops' shape states where they resolve the slip
   (:mod:`rigctl.workbench.drop_shape`), and where the model states no mass (the preset's guess)
   each given start's mass along its line at half a decade a step
   (:meth:`~rigctl.workbench.search_space.SearchSpace.mass_line`); each given start and the best
   with every effect off (a
   fit with an effect added is a point of its search); from the best, Sobol points
   (``scipy.stats.qmc``) over the effects' plausible ranges, not only near off (an effect whose
   influence vanishes smoothly at off, a Stribeck velocity going to 0, gives no slope there to
   follow), the damping following the mass (:class:`~rigctl.workbench.search_space.SearchSpace`).
3. **Metric** (:meth:`SearchState.metric`): one Jacobian J at the best start, the Gauss-Newton
   metric of the least-squares problem; the starts ranked by the cost their damped Gauss-Newton
   step would reach under J, the best steps evaluated; CMA-ES's initial covariance from J^T J.
4. **Global stage: CMA-ES** (``cma``, Hansen & Ostermeier 2001; Hansen, *The CMA Evolution
   Strategy: A Tutorial*, 2016) in the coordinates that whiten that covariance. Why: it is
   invariant to linear maps of the internal coordinates (the stiffness split, mass and friction
   levels are strongly correlated); it uses only the rank of the costs, so it is robust on the
   piecewise-constant, slightly noisy objective that event features make (a slip gained or lost
   is a step); it has few settings, all derived below; and it is at its best at 3-20
   dimensions, where this search lives. Differential evolution needs populations of 10-15 times
   the dimension; basinhopping assumes smooth local minima a local method can descend. The
   objective is |r|^2 of :class:`~rigctl.workbench.identify.Objective`'s residual vector; a
   point whose model misses most measured slips ranks after every point that does not, and one
   that cannot be run after both, so the trap (a flat error no step leaves) is never the answer
   while another point exists. It ends when its best cost stops falling by more than the
   scatter (TOL_COST).
5. **Polish**: bounded least squares (scipy's trust-region reflective) from the best point, in
   coordinates measured in each column's resolvable finite-difference step (:meth:`SearchState.
   polish`: the trust region then spans about one such step per coordinate, whatever the
   parameters' units), its Jacobians' columns evaluated in parallel, until a step gains less
   than the scatter or a trial step is shorter than the residual resolves; then the answer's
   uncertainties (:func:`~rigctl.workbench.identify.with_uncertainties`).
6. **From the data's mass and damping** (a fit that adds effects to a model whose mass or damping
   are fitted values): a second pass of stages 2-5
   from the given starts with the slider mass and drive damping at the data-scale start's
   (:func:`dynamics_guessed`), each along its mass line, begun while the budget pays for one like
   the first; the better pass is the answer.
7. **Restarts** (``restarts``, where a caller asks for them): further passes of stages 2-5 from the
   same given starts with their own random draws (Sobol starts, CMA-ES samples), begun while the
   budget pays for one like the first; the best pass is the answer. A pass is one random draw,
   and on a multimodal objective two draws can end in different local minima.

The population is evaluated in parallel worker processes holding the dataset once
(:mod:`rigctl.workbench.search_pool`). One :class:`~rigctl.workbench.budget.Budget` bounds
everything: evaluations and/or wall seconds, cancel, progress with an ETA.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Sequence
from dataclasses import replace

import cma
import numpy as np
from scipy.optimize import least_squares

from rigctl.errors import SimulationError
from rigctl.model import ParameterError
from rigctl.records.dataset import Dataset
from rigctl.records.rig_description import check_names
from rigctl.records.signals import FloatArray
from rigctl.workbench.budget import Budget, Progress
from rigctl.workbench.data_start import data_scaled
from rigctl.workbench.drop_shape import drop_shape_mass
from rigctl.workbench.element_count import spreads_elements
from rigctl.workbench.guess import initial_guess
from rigctl.workbench.identify import (
    DYNAMIC_PARAMS,
    FAILED_FACTOR,
    FAILED_RESIDUAL,
    FD_CHANGE_MAX,
    FD_CHANGE_MIN,
    FD_STEP,
    FitResult,
    Objective,
    fn_range,
    free_params,
    next_fd_step,
    physically_valid,
)
from rigctl.workbench.interrupts import signals_raise
from rigctl.workbench.model_choice import ModelChoice, effect_of
from rigctl.workbench.parallel import default_workers
from rigctl.workbench.search_pool import (
    FAILED,
    OK,
    TRAPPED,
    EvaluationPool,
    FinishTask,
    Outcome,
)
from rigctl.workbench.search_space import (
    SearchSpace,
    build_space,
    effects_at_data_scale,
    typical_point,
)

MIN_GENERATIONS = 10
"""Default budget, a cap the search rarely reaches (it ends where it stops gaining): at least this
many CMA-ES generations. In a basin the step size shrinks by about a factor e every few
generations (its cumulation time is about (n + mu_eff) / mu_eff, Hansen 2016, table 1), so ten
take the spread from a quarter of a plausible range down to the polish's scale."""
GENERATIONS_PER_DIM = 2
"""... and this many more per dimension: 2n generations let the step size and the correlations
the one Jacobian of the start misjudged adapt."""
POLISH_ITERATIONS = 4
"""Gauss-Newton iterations kept for the polish when the global stage ends on the budget: from a
point in the basin Gauss-Newton converges in a few steps."""
TOL_COST = 1.0
"""A change of the cost |r|^2 smaller than this is not a gain. |r|^2 is in squared scatter units
(each feature's block z values weighted so that |r|^2 = n_features x E^2), and one squared unit
is one feature moved by its own scatter: below what the data resolve. CMA-ES stops once the best
cost has not fallen by this much for STALL generations (or its population's costs differ by less,
cma's ``tolfun``); the polish stops once a Gauss-Newton step gains less."""
FD_TRIES = 3
"""Forward differences tried per Jacobian column at most: identify's adaptive rule (its step
grows or shrinks until the residual moves by FD_CHANGE_MIN-FD_CHANGE_MAX scatter units)."""
RESOLVED_STEP = FD_CHANGE_MIN / FD_CHANGE_MAX
"""The polish's shortest trial step, in units of each coordinate's finite-difference step (the
step that moved the residual by FD_CHANGE_MIN-FD_CHANGE_MAX scatter units): over a tenth of it
even the steepest column moves the residual by FD_CHANGE_MIN at most, the jitter floor below
which identify's step rule does not trust a change, so a shorter step cannot be judged."""
RESTART_SEED_STRIDE = 7919
"""A restart's seed is the search's plus this many times its number (a prime: the passes' Sobol
scrambles and CMA-ES samples are independent draws)."""
METRIC_QUANTILE = 0.25
"""CMA-ES's initial standard deviation along each direction is this fraction of the interval where
the optimum is expected (Hansen 2016, appendix B: sigma0 about a quarter of the search interval)."""


def search_model(
    dataset: Dataset,
    choice: ModelChoice,
    *,
    budget: Budget | None = None,
    workers: int | None = None,
    with_uncertainty: bool = True,
    seed: int = 1,
    progress: Progress | None = None,
    starts: Sequence[ModelChoice] = (),
    cancel: threading.Event | None = None,
    max_wall_s: float | None = None,
    restarts: int = 0,
) -> FitResult:
    """Identify ``choice`` on ``dataset`` by the one search (module docstring).

    ``restarts``: at most this many further passes (:data:`RESTART_SEED_STRIDE`), each from
    the same given starts with its own Sobol starts and CMA-ES samples, the best pass the
    answer. With the default budget each pass has the default cap of its own; a pass is begun
    only while the budget left (its evaluations, and its seconds with ``max_wall_s``) pays for
    one like the first.

    ``starts``: more starts, the same model at other values (a screen's best point of the
    effects being added, :class:`~rigctl.workbench.screening.Screened`), ranked with the others.
    ``cancel``: an event that cancels the search as the budget's own does (one event shared by
    the searches of a longer run: a diagnose's Cancel). ``max_wall_s``: a wall-time limit on the
    default budget (refused with ``budget``, which carries its own): the search ends within
    about one batch of evaluations of it, with its best point so far polished (the stages keep
    the polish's share of the time at the measured cost per evaluation), and its result says so
    (``time_limited``).

    ``budget``: evaluations and/or seconds (default: :func:`default_budget`, a cap: the search
    ends where it stops gaining); ``workers``: worker processes evaluating a batch of points
    (default: the CPUs; 0 evaluates in this process); ``progress``: the budget's progress
    callback where it has none (fraction done, seconds left, stage). Raises
    :class:`~rigctl.workbench.budget.SearchCancelledError` when the budget is cancelled."""
    t0, c0 = time.perf_counter(), time.process_time()
    rig = dataset.rig
    check_names(rig, [p.name for p in choice.parameter_table()])
    if rig.fixed:
        choice = choice.with_values(rig.fixed)
    added = added_effects(choice)
    choice = effects_at_data_scale(dataset, choice, added)
    identify_free = free_params(choice, rig=rig)
    scaled = data_scaled(dataset, choice, identify_free)
    space = build_space(dataset, choice, scaled or choice,
                        spreads_elements(choice)).switching_off(added)
    fns = fn_range(dataset)
    # an effect being added is searched from off too: its library defaults may make the given
    # start invalid (a load-dependent friction whose default slope takes mu_k above mu_s at the
    # campaign's loads) while the model it is added to is valid; that start is then one that
    # cannot be run, not an error
    at_off = choice.with_values(space.values(space.off_point(space.vector(choice))))
    if not (physically_valid(choice, fns) or physically_valid(at_off, fns)):
        raise ParameterError(f"{choice.label()}: kinetic friction is not below static friction")
    if max_wall_s is not None and not max_wall_s > 0.0:
        raise ValueError(f"max_wall_s must be positive, not {max_wall_s}")
    if max_wall_s is not None and budget is not None:
        raise ValueError("max_wall_s limits the default budget; with a budget given, set its "
                         "max_wall_s instead")
    per_pass = None  # the default budget is a cap per pass; a budget given is all there is
    if budget is None:
        budget = default_budget(space.dim)
        budget.max_wall_s = max_wall_s
        per_pass = budget.max_evaluations
    if budget.progress is None:
        budget.progress = progress
    if cancel is not None:
        budget.cancel_event = cancel
    n_workers = default_workers() if workers is None else workers
    with signals_raise(), EvaluationPool(dataset, choice, space.free, budget, n_workers) as pool:
        search = SearchState(space, pool, budget, seed, with_uncertainty)
        typical = typical_point(dataset, choice, added)
        given = [choice, *([scaled] if scaled is not None else []),
                 *([typical] if typical is not None else []), *starts]
        search.starts(given)
        search.descend()
        best, first = search, budget.used
        fitted = any(k in choice.values for k in DYNAMIC_PARAMS if k not in rig.fixed)
        guessed = dynamics_guessed(given, scaled, space) if added and fitted else []
        if guessed and not search.time_limited and _affords_a_pass(search, per_pass, first):
            search = SearchState(space, pool, budget, seed + RESTART_SEED_STRIDE,
                                 with_uncertainty)
            search.starts(guessed, mass_guessed=True)
            best = _better_pass(best, search, "from the data's mass and damping")
        for k in range(1, restarts + 1):
            if not _affords_a_pass(search, per_pass, first):
                break  # a pass costs about what the first did: one that cannot end is not begun
            search = search.restarted(seed + RESTART_SEED_STRIDE * k)
            best = _better_pass(best, search, f"restart {k}")
        result = best.finish(choice)
    return replace(result, n_evaluations=budget.used, elapsed_s=time.perf_counter() - t0,
                   cpu_s=time.process_time() - c0,
                   time_limited=best.time_limited or search.time_limited,
                   n_timed_out=pool.n_timed_out)


def _affords_a_pass(search: SearchState, per_pass: int | None, first: int) -> bool:
    """Whether another pass is begun after ``search`` (``first``: the evaluations the first pass
    used): with the default budget, a cap of ``per_pass`` more evaluations is set first; a pass
    costs about what the first did, and one that cannot end is not begun."""
    budget = search.budget
    if per_pass is not None and budget.max_evaluations is not None:
        budget.max_evaluations = budget.used + per_pass
    return not search.time_limited and budget.evaluations_left() - search.reserve() >= first


def _better_pass(best: SearchState, other: SearchState, label: str) -> SearchState:
    """``other`` (its starts ranked) descended, its stages told in ``best``'s message under
    ``label``: the better of the two, ``other`` only where it gains more than TOL_COST."""
    other.descend()
    best.stages.append(f"{label}: " + ", ".join(other.stages) + f", |r|^2 {other.cost_best:.4g}")
    if other.cost_best < best.cost_best - TOL_COST:
        other.stages = [*best.stages, f"{label} kept"]
        return other
    return best


def dynamics_guessed(given: Sequence[ModelChoice], scaled: ModelChoice | None,
                     space: SearchSpace) -> list[ModelChoice]:
    """The ``given`` starts with the slider mass and drive damping at the data-scale start's
    (``scaled``), where the search fits them and the start has other values: the starts of the
    second pass of a fit that adds effects to a model whose mass or damping are fitted values (a
    model with none, a fresh one, walks every given start's mass line, the data-scale start's
    included, in its first pass).

    Mass and damping are seen only through the slips' shape and timing, which the effects being
    added change (a load-dependent stiffness moves the slip's frequency, a sensor's lag its
    drop, a velocity-dependent friction its damping). A model without them imitates them through
    its mass and damping, and its fit can settle decades from the values the same model with the
    effects needs (a damping ratio of 1e-4 against 1e-2), in a basin the mass line, which keeps
    the start's damping ratio, does not leave. The data-scale values are a guess independent of
    that fit (docs/identification.md, "The search")."""
    if scaled is None:
        return []
    free = {fp.name for fp in space.free}
    dyn = {k: scaled.values[k] for k in DYNAMIC_PARAMS if k in free and k in scaled.values}
    if not dyn:
        return []
    out: list[ModelChoice] = []
    for c in given:
        if any(c.values.get(k) != v for k, v in dyn.items()):
            out.append(c.with_values(dyn))
    return out


def added_effects(choice: ModelChoice) -> list[str]:
    """The effects of ``choice`` being added: those it states no value of (an effect added to a
    model, :meth:`ModelChoice.with_effect`, has none; a fitted one has all its fitted values).
    The start with these off is the model they are added to."""
    stated = {effect_of(name) for name in choice.values} - {""}
    return [e for e in choice.effects if e not in stated]


def default_budget(dim: int) -> Budget:
    """A cap: evaluations for MIN_GENERATIONS + GENERATIONS_PER_DIM x ``dim`` CMA-ES generations
    of the default population, the starts (about one population), the start's Jacobian, the
    polish and the uncertainties, each Jacobian at its worst (FD_TRIES per column)."""
    generations = MIN_GENERATIONS + GENERATIONS_PER_DIM * dim + 1
    return Budget(max_evaluations=generations * popsize(dim) + FD_TRIES * dim + 2
                  + polish_reserve(dim, True, FD_TRIES * dim))


def popsize(dim: int) -> int:
    """CMA-ES's default population, 4 + floor(3 ln n): the smallest that estimates the covariance
    update reliably (Hansen 2016, table 1)."""
    return 4 + int(3.0 * math.log(max(dim, 1)))


def stall_generations(dim: int, mueff: float) -> int:
    """Generations without a gain after which CMA-ES has stopped finding one: the backward time
    horizon 1 / c_sigma of its step-size path, c_sigma = (mu_eff + 2) / (n + mu_eff + 5) (Hansen
    2016, eq. 55): over that many generations the step size has adapted to the landscape, so a
    population that still gains nothing above the scatter (TOL_COST) is sampling noise."""
    return math.ceil((dim + mueff + 5.0) / (mueff + 2.0))


def polish_reserve(n: int, with_uncertainty: bool, jacobian: int) -> int:
    """Evaluations kept from the global stage for POLISH_ITERATIONS of the polish (each one
    residual and one Jacobian of ``jacobian`` evaluations), the answer's final evaluation and
    its uncertainties' Jacobian."""
    return POLISH_ITERATIONS * (1 + jacobian) + 1 + (jacobian if with_uncertainty else 0)


class _ConvergedError(Exception):
    """The polish's last step gained less than TOL_COST, its trial steps fell below
    RESOLVED_STEP, or the budget cannot pay its next Jacobian: it ends at the best point seen
    (the message says which)."""


class SearchState:
    """The state of one search: the best point seen, how each evaluated point ranks, and what a
    Jacobian costs here."""

    def __init__(self, space: SearchSpace, pool: EvaluationPool, budget: Budget, seed: int,
                 with_uncertainty: bool) -> None:
        self.space, self.pool, self.budget, self.seed = space, pool, budget, seed
        self.with_uncertainty = with_uncertainty
        self.best: tuple[float, FloatArray, FloatArray] | None = None
        """Lowest cost of a point whose model makes the slips, that point and its residual."""
        self.best_any: tuple[float, FloatArray, FloatArray | None] | None = None
        """The best point by rank (trapped or failed too): the answer only where no point makes
        the slips."""
        self.failed_cost = FAILED_RESIDUAL**2
        self.stop_reason = ""
        self.time_limited = False
        """A stage ended on the budget while its wall limit was what limited it
        (:meth:`Budget.time_binds`): the search ended on its time, not by converging."""
        self.cols = list(range(len(space.free)))
        """The coordinates differenced: all but the element count (an integer: no slope)."""
        self.steps: dict[int, float] = {}
        """Each column's finite-difference step as last adapted."""
        self.jac_evaluations = 0
        self.jac_columns = 0
        self.mean: FloatArray | None = None
        self.cov: FloatArray | None = None
        self.metric_cost = math.nan
        self.stages: list[str] = []
        """What each stage spent, for the result's message."""
        self.start_points: list[tuple[FloatArray, FloatArray]] = []
        """The starts that can be run, and their residual vectors."""
        self.given: list[tuple[FloatArray, Outcome]] = []
        """The given (not random) starts as evaluated: a restart reuses them."""

    def _stopped_on_budget(self) -> None:
        """A stage stops because the budget left would not pay for its next step: where the
        wall limit is what limits it, the search ends on its time (:attr:`time_limited`)."""
        self.time_limited |= self.budget.time_binds()

    # -- evaluation ---------------------------------------------------------------------------

    def evaluate(self, xs: list[FloatArray], reread: Sequence[bool] = ()) -> list[Outcome]:
        """Evaluate ``xs`` (clipped to the bounds) and keep the best point seen; ``reread``: per
        point, also re-read the base levels there (:attr:`~rigctl.workbench.search_pool.Outcome.
        reread`)."""
        xs = [np.clip(x, self.space.lower, self.space.upper) for x in xs]
        flags = list(reread) or [False] * len(xs)
        outcomes: list[Outcome] = self.pool.evaluate(
            [replace(self.space.point(x), reread=f) for x, f in zip(xs, flags, strict=True)])
        self._take(xs, outcomes)
        return outcomes

    def _take(self, xs: list[FloatArray], outcomes: list[Outcome]) -> None:
        """Keep the best of evaluated points ``xs`` (within the bounds)."""
        if self.best is None and any(o.status == OK for o in outcomes):
            first = next(o.cost for o in outcomes if o.status == OK)
            self.failed_cost = max(FAILED_RESIDUAL, FAILED_FACTOR * math.sqrt(first))**2
        for x, o in zip(xs, outcomes, strict=True):
            if o.status == OK and o.vector is not None and (self.best is None
                                                            or o.cost < self.best[0]):
                self.best = (o.cost, np.array(x), o.vector)
            f = self.ranked_cost(o)
            if self.best_any is None or f < self.best_any[0]:
                self.best_any = (f, np.array(x), o.vector)

    def ranked_cost(self, o: Outcome) -> float:
        """|r|^2 where the model makes the slips; after all of those the points that miss most
        slips (by their |r|^2), then the points that cannot be run (the failure penalty of
        identify.Objective, FAILED_FACTOR times the first valid norm)."""
        if o.status == OK:
            return o.cost
        if o.status == TRAPPED:
            return self.failed_cost + min(o.cost, self.failed_cost)
        return 3.0 * self.failed_cost

    def rank_starts(self, xs: list[FloatArray], drawn: Sequence[FloatArray] = ()) -> None:
        """Evaluate starts in one batch, keeping those that can be run, with their residuals:
        ``xs`` given (not random), which every pass of the search shares (:meth:`restarted`),
        and ``drawn``, this pass's random ones."""
        outcomes = self.evaluate([*xs, *drawn])
        self.given += [(np.clip(x, self.space.lower, self.space.upper), o)
                       for x, o in zip(xs, outcomes, strict=False)]
        self._keep_starts([*xs, *drawn], outcomes)

    def _keep_starts(self, xs: list[FloatArray], outcomes: list[Outcome]) -> None:
        for x, o in zip(xs, outcomes, strict=True):
            if o.status != FAILED and o.vector is not None:
                self.start_points.append((np.clip(x, self.space.lower, self.space.upper),
                                          o.vector))

    def rank(self, xs: list[FloatArray]) -> list[float]:
        """Each point's ranked cost (:meth:`ranked_cost`)."""
        return [self.ranked_cost(o) for o in self.evaluate(xs)]

    @property
    def x_best(self) -> FloatArray:
        if self.best is not None:
            return self.best[1]
        assert self.best_any is not None
        return self.best_any[1]

    @property
    def residual_best(self) -> tuple[FloatArray, FloatArray] | None:
        """The best point and its residual vector: of a point whose model makes the slips, else
        of the best by rank (a model that misses most slips still has a residual to descend)."""
        if self.best is not None:
            return self.best[1], self.best[2]
        if self.best_any is not None and self.best_any[2] is not None:
            return self.best_any[1], self.best_any[2]
        return None

    @property
    def cost_best(self) -> float:
        if self.best is not None:
            return self.best[0]
        return self.best_any[0] if self.best_any is not None else math.inf

    def jacobian_cost(self) -> int:
        """Evaluations a Jacobian of all columns costs: as measured in this search so far, else
        the worst case (FD_TRIES per column)."""
        per_column = self.jac_evaluations / self.jac_columns if self.jac_columns else FD_TRIES
        return math.ceil(per_column * len(self.cols))

    def reserve(self) -> int:
        """Evaluations the polish and the answer keep from the global stage."""
        return polish_reserve(len(self.cols), self.with_uncertainty, self.jacobian_cost())

    def jacobian(self, x0: FloatArray, f0: FloatArray) -> FloatArray:
        """The residual's forward-difference Jacobian at ``x0`` (columns :attr:`cols`), each
        column's step adapted as identify's solver adapts it (identify.next_fd_step: until the
        residual moves by FD_CHANGE_MIN-FD_CHANGE_MAX scatter units, at most FD_TRIES steps), and
        every column of a round evaluated in one batch. A step into a point that cannot be run
        is taken the other way; a column with no usable step is zero."""
        J = np.zeros((f0.shape[0], self.space.dim))
        size = {j: self.steps.get(j, FD_STEP) for j in self.cols}
        sign = {j: 1.0 for j in self.cols}
        pending = list(self.cols)
        for _ in range(FD_TRIES):
            if not pending:
                break
            xs, hs = [], []
            for j in pending:
                h = sign[j] * size[j]
                if not self.space.lower[j] <= x0[j] + h <= self.space.upper[j]:
                    h = -h
                x = x0.copy()
                x[j] += h
                xs.append(x)
                hs.append(h)
            outcomes = self.evaluate(xs)
            self.jac_evaluations += len(xs)
            again = []
            for j, h, o in zip(pending, hs, outcomes, strict=True):
                if o.status == FAILED or o.vector is None:
                    if sign[j] > 0.0:  # the other side, once
                        sign[j] = -1.0
                        again.append(j)
                    continue
                diff = o.vector - f0
                J[:, j] = diff / h
                nxt = next_fd_step(h, float(np.linalg.norm(diff)), grow_from_zero=False)
                if nxt is not None:
                    size[j] = nxt
                    again.append(j)
            pending = again
        self.steps.update(size)
        self.jac_columns += len(self.cols)
        return J

    # -- stages -------------------------------------------------------------------------------

    def starts(self, choices: list[ModelChoice], mass_guessed: bool | None = None) -> None:
        """The model's values and its data-scale start; where the mass is a guess
        (``mass_guessed``; default: the model states no mass), each given start along its mass
        line (:meth:`SearchSpace.mass_line`); each of them and the
        best with the effects being added off (:func:`added_effects`: the model's values with them off are the
        fit they were added to, its own fitted effects kept: a search from there never ends worse
        than that fit); from the best, Sobol points over the
        plausible ranges of the coordinates whose start is a guess (as many as a population,
        rounded up to a power of two to keep the Sobol sequence balanced)."""
        used = self.budget.used
        given = list({x.tobytes(): x for x in (self.space.vector(c) for c in choices)}.values())
        self.rank_starts(given)
        guess = self.ratio_guess(choices[0])
        if guess is not None:
            self.rank_starts([guess])
        drop = self.drop_shape_start(choices[0])
        if drop is not None:
            self.rank_starts([drop])
        if mass_guessed is None:
            mass_guessed = "m_kg" not in choices[0].values  # the preset's guess
        if mass_guessed:
            self.rank_starts([x for g in given for x in self.space.mass_line(g)])
        if self.space.spread:
            x0 = self.x_best
            points = []
            seen = {x.tobytes() for x in given}
            for x in (*given, x0):  # each start with its effects off: the model's own values
                off = self.space.off_point(x)  # off are the fit the effects were added to
                if off.tobytes() not in seen:
                    seen.add(off.tobytes())
                    points.append(off)
            self.spread_starts(x0, points)
        self.stages.append(f"starts {self.budget.used - used}")
        self.budget.report(f"starts: {self.budget.used} evaluated")

    def spread_starts(self, x0: FloatArray, given: list[FloatArray]) -> None:
        """From ``x0``, Sobol points (this pass's seed) over the plausible ranges of the
        coordinates whose start is a guess, evaluated in one batch with more ``given`` starts."""
        self.rank_starts(given, self.space.sobol_points(x0, sorted(self.space.spread),
                                                        popsize(self.space.dim), self.seed))

    def descend(self) -> None:
        """The stages after the starts: the metric, CMA-ES, the polish."""
        self.metric()
        self.cma()
        self.polish()

    def restarted(self, seed: int) -> SearchState:
        """Another pass of the search (:func:`search_model`'s ``restarts``): a state with the
        given starts as this one evaluated them (not evaluated again) and this one's
        finite-difference steps, drawing its own Sobol starts and CMA-ES samples from ``seed``."""
        other = SearchState(self.space, self.pool, self.budget, seed, self.with_uncertainty)
        other.failed_cost = self.failed_cost
        other.steps = dict(self.steps)
        other.jac_evaluations, other.jac_columns = self.jac_evaluations, self.jac_columns
        xs = [x for x, _ in self.given]
        outcomes = [o for _, o in self.given]
        other.given = list(self.given)
        other._take(xs, outcomes)
        other._keep_starts(xs, outcomes)
        used = self.budget.used
        if self.space.spread:
            other.spread_starts(other.x_best, [])
        other.stages.append(f"starts {self.budget.used - used}")
        return other

    def ratio_guess(self, choice: ModelChoice) -> FloatArray | None:
        """The ratio guess of :mod:`rigctl.workbench.guess` from the best start: each level and
        stiffness rescaled by the ratio of the measured to the simulated feature it mainly sets
        (one simulation, counted). A start at the data's levels that misses most slips is not
        left to a cost that is flat there."""
        names = [fp.name for fp in self.space.free]
        model = choice.with_values({k: v for k, v in self.space.values(self.x_best).items()
                                    if k in names})
        self.budget.check()
        try:
            values = initial_guess(self.pool.dataset, model, list(self.space.free))
        except (SimulationError, ParameterError):
            return None
        finally:
            self.budget.spend(1)
        if not values:
            return None
        return self.space.with_values(self.x_best, values)

    def drop_shape_start(self, choice: ModelChoice) -> FloatArray | None:
        """The best start with the mass the drops' shape states (:mod:`rigctl.workbench.
        drop_shape`: the slip is half a period of the mass on the drive spring, resolved where it
        spans a few samples) and the drive damping moved with it at the same damping ratio
        (:attr:`SearchSpace.follows`); None where the mass is no coordinate or the drops do not
        resolve the slip. The data-scale start keeps the preset's slip frequency there, decades
        from another rig's, and a spread start draws the mass and the damping ratio independently
        over decades: neither is likely to land near both."""
        names = [fp.name for fp in self.space.free]
        if "m_kg" not in names:
            return None
        values = {**{p.name: p.value for p in choice.parameter_table()},
                  **self.space.values(self.x_best)}
        m = drop_shape_mass(self.pool.dataset, values["k0_N_per_m"])
        if not math.isfinite(m):
            return None
        i = names.index("m_kg")
        fp = self.space.free[i]
        x = self.space.spread_point(self.x_best, {i: fp.to_u(min(max(m, fp.lower), fp.upper))})
        return np.clip(x, self.space.lower, self.space.upper)

    def metric(self) -> None:
        """One Jacobian J at the best start: the local metric of the least-squares problem.

        A start's own cost says little of where a fit from it ends (it is dominated by levels and
        stiffnesses a first step corrects), so every start r_k is ranked by the cost its
        Gauss-Newton step would reach under J, |r_k + J d_k|^2 + d_k^T S^-1 d_k, the step taken
        with the prior (each coordinate's standard deviation s from the space: where its optimum
        is expected) as Levenberg-Marquardt damping, (J^T J + S^-1) d_k = -J^T r_k (the fitting
        chain's scan ranked its points the same way). The steps of the mu best predicted (mu =
        lambda / 2, as CMA-ES selects its parents) are evaluated, one batch. From the best point
        then (cost f) the optimum of the linearised problem lies where its cost is at most f,
        d^T J^T J d <= f, so CMA-ES starts with a covariance of METRIC_QUANTILE^2 f (J^T J)^-1
        there (a quarter of that interval per direction, as CMA-ES's sigma0 rule asks), combined
        with the prior by adding precisions: C^-1 = S^-1 + J^T J / (METRIC_QUANTILE^2 f). A
        direction the data do not move keeps its prior spread. This replaces learning the
        covariance from scratch, about n^2 / mu_eff generations (Hansen 2016, table 1)."""
        prior_cov = self.space.prior_cov()
        prior = np.linalg.inv(prior_cov)
        self.mean, self.cov = self.x_best.copy(), prior_cov
        at = self.residual_best
        if at is None:
            return
        if self.budget.evaluations_left() - self.reserve() < \
                FD_TRIES * len(self.cols) + popsize(self.space.dim) // 2:
            self._stopped_on_budget()
            return
        used = self.budget.used
        x0, r0 = at
        self.budget.report(f"metric: a Jacobian at the best start, |r|^2 {self.cost_best:.4g}")
        J = self.jacobian(x0, r0)
        jtj = J.T @ J
        if np.all(np.isfinite(jtj)):
            solve = np.linalg.inv(jtj + prior)
            predicted = []
            for x, r in self.start_points:
                d = -solve @ (J.T @ r)
                rd = r + J @ d
                predicted.append((float(rd @ rd + d @ prior @ d), x + d))
            predicted.sort(key=lambda p: p[0])
            self.rank([x for _, x in predicted[:max(popsize(self.space.dim) // 2, 1)]])
            f = max(self.cost_best, TOL_COST)
            precision = prior + jtj / (METRIC_QUANTILE**2 * f)
            self.mean = self.x_best.copy()
            self.cov = np.asarray(np.linalg.inv(precision), dtype=np.float64)
            self.metric_cost = f
        self.stages.append(f"Jacobian and Gauss-Newton steps {self.budget.used - used}")
        self.budget.report(f"metric: best |r|^2 {self.cost_best:.4g}")

    def cma(self) -> None:
        """CMA-ES from the best point with the metric's covariance, while it gains.

        It runs in whitened coordinates y, x = m + L y with L L^T the covariance of
        :meth:`metric` (CMA-ES is invariant under this linear map, Hansen 2016, sec. 1.4: starting
        it with identity in y is starting it with that covariance in x). A point outside the
        bounds is evaluated at its projection onto them, its cost raised by the metric's
        quadratic rise over the distance projected, f / 4 per squared unit of y (the box
        handling by projection and penalty, Hansen 2016, appendix B). Ends when the best cost
        has not fallen by TOL_COST for :func:`stall_generations` generations, at cma's own
        stops, or when the budget left would not pay for a population and the polish."""
        dim = self.space.dim
        if dim < 2 or self.mean is None or self.cov is None:
            self.stop_reason = "one coordinate: no global stage"
            return
        used = self.budget.used
        lam = popsize(dim)
        L = np.linalg.cholesky(self.cov)
        L_inv = np.linalg.inv(L)
        m = self.mean
        weight = METRIC_QUANTILE**2 * (self.metric_cost if math.isfinite(self.metric_cost)
                                       else max(self.cost_best, TOL_COST))
        opts = {"popsize": lam, "tolfun": TOL_COST, "seed": self.seed, "verbose": -9,
                "verb_log": 0, "verb_disp": 0, "signals_filename": ""}
        es = cma.CMAEvolutionStrategy(np.zeros(dim), 1.0, opts)
        stall = stall_generations(dim, float(es.sp.weights.mueff))
        last_gain, stalled = self.cost_best, 0
        self.stop_reason = "budget"
        while True:
            if self.budget.evaluations_left() - self.reserve() < lam:
                self.stop_reason = "budget"
                self._stopped_on_budget()
                break
            ys = es.ask()
            xs = [m + L @ y for y in ys]
            inside = [np.clip(x, self.space.lower, self.space.upper) for x in xs]
            costs = self.rank(inside)
            costs = [c + weight * float(np.sum((L_inv @ (x - xi))**2))
                     for c, x, xi in zip(costs, xs, inside, strict=True)]
            es.tell(ys, costs)
            self.budget.report(f"global search: generation {es.countiter}, population {lam}, "
                               f"best |r|^2 {self.cost_best:.4g}")
            if last_gain - self.cost_best > TOL_COST:
                last_gain, stalled = self.cost_best, 0
            else:
                stalled += 1
            if stalled >= stall:
                self.stop_reason = f"no gain above the scatter in {stall} generations"
                break
            if es.stop():
                self.stop_reason = ", ".join(sorted(es.stop()))
                break
        self.stages.append(f"CMA-ES {self.budget.used - used} ({self.stop_reason})")

    def polish(self) -> None:
        """Bounded least squares (trust-region reflective, as identify's fits) from the best
        point, the element count held, in coordinates measured in each column's resolvable step.

        Each coordinate j is scaled by its finite-difference step h_j as :meth:`jacobian` last
        adapted it, z_j = (u_j - u0_j) / h_j: h_j is the step over which the residual was
        measured to move by FD_CHANGE_MIN-FD_CHANGE_MAX scatter units, i.e. the scale on which
        the residual is both resolved and linear, and these steps differ by factors of 50 between
        coordinates (a friction level against a log stiffness). In z, least_squares' trust region
        (a sphere of its scaled variables; scipy's ``x_scale`` is the same rescaling) spans about
        one such step per coordinate, where its linear model holds, instead of one radius for all
        in internal units; and z starts at 0, so its first radius is scipy's default 1 (one
        resolvable step), not |u0|, a norm of log-values that depends on the parameters' units.
        For the same reason scipy's ``xtol`` (relative to |x|) is not used (None): the
        polish ends where a trial step is shorter than :data:`RESOLVED_STEP` in z (the residual
        moves by less than its jitter over it: no step that short can be judged), where a step
        gains less than TOL_COST (before that step's Jacobian is taken), or when the budget left
        would not pay for another Jacobian and the answer. Jacobians as :meth:`jacobian` (columns
        evaluated in parallel)."""
        at = self.residual_best
        if at is None or not self.cols:
            return
        used = self.budget.used
        cols = self.cols
        x_full = at[0].copy()
        u0 = np.clip(x_full[cols], self.space.lower[cols], self.space.upper[cols])
        h = np.array([self.steps.get(j, FD_STEP) for j in cols])
        lo = (self.space.lower[cols] - u0) / h
        hi = (self.space.upper[cols] - u0) / h
        vectors: dict[bytes, FloatArray] = {}
        m = at[1].shape[0]
        current = np.zeros(len(cols))
        """The polish's accepted point (z): where its last Jacobian was taken."""

        def point(z: FloatArray) -> FloatArray:
            x = x_full.copy()
            x[cols] = u0 + h * z
            return x

        def fun(z: FloatArray) -> FloatArray:
            z = np.asarray(z, dtype=np.float64)
            key = z.tobytes()
            if key not in vectors:
                if last and float(np.linalg.norm(z - current)) < RESOLVED_STEP:
                    raise _ConvergedError("a trial step was below the residual's resolution")
                o = self.evaluate([point(z)])[0]
                vec = o.vector
                with np.errstate(over="ignore"):
                    if vec is None or not math.isfinite(float(vec @ vec)):
                        # a model that cannot be run, or one diverging so far that its squared
                        # residual overflows: the failure's residual, a step the polish rejects
                        vec = np.full(m, math.sqrt(self.failed_cost / m))
                if len(vectors) > 64:
                    vectors.clear()
                vectors[key] = vec
            return vectors[key]

        last: list[float] = []

        def jac(z: FloatArray) -> FloatArray:
            z = np.asarray(z, dtype=np.float64)
            r = fun(z)
            cost = float(r @ r)
            if last and last[-1] - cost < TOL_COST:
                raise _ConvergedError("a step gained less than the scatter")
            left = self.budget.evaluations_left() - 1 - \
                (self.jacobian_cost() if self.with_uncertainty else 0)
            if left < self.jacobian_cost() + 1:
                self._stopped_on_budget()
                raise _ConvergedError("the budget would not pay another Jacobian")
            last.append(cost)
            current[:] = z
            self.budget.report(f"local polish: Jacobian {len(last)} at |r|^2 {cost:.4g}")
            J = self.jacobian(point(z), r)[:, cols] * h
            with np.errstate(over="ignore"):
                if not math.isfinite(float(np.sum(J * J))):
                    raise _ConvergedError("the residual's slopes are beyond floating point "
                                          "(a neighbour diverges)")
            return J

        self.budget.report("local polish")
        try:
            with np.errstate(over="ignore"):  # squares of residuals near a diverging model
                sol = least_squares(fun, np.zeros(len(cols)), jac=jac, bounds=(lo, hi),
                                    method="trf", x_scale=1.0, ftol=1e-4, xtol=None, gtol=1e-6)
            message = str(sol.message)
        except _ConvergedError as stop:
            message = f"ended where {stop}"
        self.stages.append(f"polish {self.budget.used - used} ({len(last)} Jacobians; "
                           f"{message})")

    def finish(self, choice: ModelChoice) -> FitResult:
        """The best point seen as the answer: its model evaluated once, with uncertainties.

        Its values are those the search evaluated there (:meth:`Objective.values`): with the mass
        a resolved ringing ties to the stiffnesses, which is no coordinate of the space."""
        point = self.space.point(self.x_best)
        values = Objective(self.pool.dataset, choice, list(self.space.free)).values(point.u)
        if point.n_elements is not None:
            values["n_elements"] = float(point.n_elements)
        model = choice.with_values(values)
        used = self.budget.used
        with_uncertainty = self.with_uncertainty and \
            self.budget.evaluations_left() >= 1 + self.jacobian_cost()
        self.budget.report("answer and uncertainties")
        names = tuple(fp.name for fp in self.space.free)
        result = self.pool.finish(FinishTask(model, names, "", with_uncertainty))
        self.stages.append(f"answer {self.budget.used - used}")
        result.message = "; ".join(self.stages)
        self.budget.report("done", evaluations_left=0.0)
        return result
