"""Parameter identification: bounded least squares on the event-aware residual vector.

The residual vector is the one whose squared norm is the error E^2 times the number of features
(:mod:`rigctl.workbench.metrics`), so identification minimises exactly the reported error. Solver:
``scipy.optimize.least_squares`` (trust-region reflective, bounds; Branch, Coleman & Li, SIAM J.
Sci. Comput. 21, 1999) in internal coordinates: ln(p) for parameters whose bounds are positive and
span more than a factor 20, p / s otherwise (s the typical size).

Derivatives are forward differences of the simulated features (the event-driven engine makes a
simulation cheap). Each parameter's step adapts so that the residual moves by 2-20 scatter units:
above the features' sampling-phase jitter, within the linear range. :class:`HybridJacobian`
differences chosen columns at every step and keeps the others current by Broyden rank-one updates
(Broyden, Math. Comp. 19, 1965).

Uncertainty: the covariance s^2 (J^T J)^-1 of the linearised problem, s^2 = |r|^2 / (m - p) (the
standard Gauss-Newton estimate, e.g. Seber & Wild, *Nonlinear Regression*, sec. 2.1), mapped to
parameter units. A parameter is flagged *undetermined* when its 1-sigma range exceeds 30 % (log
parameters) or half its value and 5 % of its bounds (linear ones), or when the data do not move the
residual at all. The Jacobian of the uncertainties is staircase-aware
(:meth:`HybridJacobian._staircase_column`): where the events jump rather than move with a
parameter, its sigma is at least the step over which they changed.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.optimize import least_squares

from rigctl.errors import SimulationError
from rigctl.model import ParameterError, ParamInfo, TimeLimitError, run_clock
from rigctl.records.dataset import Dataset
from rigctl.records.features import EventTable
from rigctl.records.rig_description import RigDescription
from rigctl.records.ringing import ringing_mass
from rigctl.records.signals import FloatArray
from rigctl.workbench.evaluate import evaluate
from rigctl.workbench.metrics import RunComparison, residual_length
from rigctl.workbench.model_choice import ModelChoice

FD_STEP = 0.05  # first finite-difference step in internal units (5 % of a log parameter)
FD_STEP_MIN = 1e-4  # smallest step: below it a stage count or a sample moves no feature
FD_STEP_MAX = 0.3  # largest step: 35 % of a log parameter, still a local slope
FD_CHANGE_MIN = 2.0  # residual change (scatter units) a step must reach: above the phase jitter
FD_CHANGE_MAX = 20.0  # residual change a step may reach and still be linear
FD_GROW_FROM_ZERO = 10.0
"""Factor a step grows by when it did not move the residual at all (features are read from sampled
signals: a small enough change of a parameter moves no event by a sample)."""
FAILED_RESIDUAL = 1e3
"""Norm of the residual vector of a point that cannot be evaluated (invalid or failed), at least;
:class:`Objective` raises it to FAILED_FACTOR times the first valid norm, so that on data far from
the model (a record of another rig) a failed point never looks better than a poor valid one."""
FAILED_FACTOR = 100.0
DYNAMIC_PARAMS = ("m_kg", "c0_N_s_per_m")
"""Mass and drive damping: fitted unless the rig description states them (a rig knows its own; the
simulated rig states them), since elsewhere the start is only a guess
(:func:`rigctl.workbench.search.search_model`)."""
DYNAMIC_SPAN = 1e3  # mass and damping fitted within a factor 1000 of their start either way


@dataclass(frozen=True)
class FreeParam:
    """A fitted parameter and its internal coordinate u."""

    name: str
    lower: float
    upper: float
    log: bool
    scale: float

    @staticmethod
    def from_info(info: ParamInfo) -> FreeParam:
        if info.name in DYNAMIC_PARAMS and info.value > 0.0:
            # mass and drive damping span decades between rigs and C0 may be 0 in its bounds:
            # fitted in log, within DYNAMIC_SPAN of the start
            lo = max(info.lower, info.value / DYNAMIC_SPAN, 1e-300)
            hi = min(info.upper, info.value * DYNAMIC_SPAN)
            return FreeParam(info.name, lo, hi, True, abs(info.value))
        log = info.lower > 0.0 and info.upper / info.lower > 20.0
        scale = max(abs(info.value), 0.01 * (info.upper - info.lower), 1e-300)
        return FreeParam(info.name, info.lower, info.upper, log, scale)

    def to_u(self, p: float) -> float:
        return math.log(p) if self.log else p / self.scale

    def to_p(self, u: float) -> float:
        p = math.exp(u) if self.log else u * self.scale
        return min(max(p, self.lower), self.upper)

    @property
    def u_bounds(self) -> tuple[float, float]:
        return self.to_u(self.lower), self.to_u(self.upper)

    def dp_du(self, p: float) -> float:
        return p if self.log else self.scale


@dataclass
class FitResult:
    """An identified model and how well the data determine it."""

    choice: ModelChoice
    error: float
    feature_error: dict[str, float]
    free: tuple[str, ...]
    sigma: dict[str, float] = field(default_factory=dict)
    undetermined: list[str] = field(default_factory=list)
    n_evaluations: int = 0
    message: str = ""
    jacobian: FloatArray | None = None
    """d(residual)/du at the solution (columns in the order of ``free``)."""
    elapsed_s: float = 0.0
    cpu_s: float = 0.0
    """Wall and CPU seconds of the fit (candidate fits; on a busy machine wall > CPU)."""
    misses_most_slips: bool = False
    """The fitted model misses most measured slips (:func:`misses_most_slips`): a trap, not a fit."""
    time_limited: bool = False
    """The search ended on its wall-time limit, not by converging (its best point so far)."""
    n_timed_out: int = 0
    """Points of the search stopped at the per-evaluation time limit (search_pool)."""

    @property
    def n_params(self) -> int:
        return len(self.free)


MAX_MISSING_FRACTION = 0.5
"""A model that misses more than this fraction of the measured slips is no description of the
data, whatever its error: each missing slip costs a fixed z (:data:`~rigctl.workbench.metrics.
MISSING_EVENT_Z`), so a model that makes no slips scores a flat error that no small step changes,
and that capped charge can score below a model that makes every slip but pairs them badly (a
trap). Half: beyond it the model describes fewer of the measured slips than it leaves out (the
case that showed the trap: docs/decisions.md). A point that misses them ranks after every point
that does not (:mod:`rigctl.workbench.search`), and a fit ends at the best point visited that
does not (:class:`Objective`)."""


def misses_most_slips(dataset: Dataset, comparisons: Sequence[RunComparison]) -> bool:
    """Whether the model of ``comparisons`` misses more than :data:`MAX_MISSING_FRACTION` of the
    dataset's measured slips.

    A measured slip paired with the model's first slip of its segment for want of a later one (a
    *stand-in*, :func:`~rigctl.workbench.alignment.stand_in_pairs`) is missed too: the model has no
    slip of its own for it, and the metric charges it as a missing slip (capped z). Counting only
    the unpaired ones would let the trap through in another form: a model that makes only the
    first slip of each segment, its followers stand-ins, charged at the cap (docs/decisions.md)."""
    missing = sum(int(np.count_nonzero(c.missing["drop_N"])) + int(np.count_nonzero(c.stand_in))
                  for c in comparisons)
    return missing > MAX_MISSING_FRACTION * max(dataset.n_events, 1)


def physically_valid(choice: ModelChoice, fn_range_N: tuple[float, float] = (0.0, 0.0)) -> bool:
    """The model can stick-slip over the campaign's normal forces (:meth:`ModelSpec.invalid_reason`:
    the base, each effect's own rule, the engine's friction laws at the lowest and highest Fn).
    The engine does not finish a run without it, so such points count as failed evaluations."""
    return choice.build().invalid_reason(fn_range_N) is None


class Objective:
    """Residual vector of a model on a dataset as a function of the internal coordinates."""

    def __init__(self, dataset: Dataset, choice: ModelChoice, free: Sequence[FreeParam]) -> None:
        self.dataset = dataset
        self.fn_range = fn_range(dataset)
        self.choice = choice
        self.free = list(free)
        self.n_evaluations = 0
        self._cache: dict[bytes, FloatArray] = {}
        self._last_events: tuple[bytes, list[EventTable]] | None = None
        """The slip events of the last point this objective ran the model at, by its key
        (:meth:`events_at`)."""
        self.best_u: FloatArray | None = None
        self.best_cost = math.inf
        self.failed_norm = FAILED_RESIDUAL
        self._seen_valid = False
        self._failed: set[bytes] = set()
        self._timed_out: set[bytes] = set()
        """Failed points whose model passed :attr:`time_limit_s` (a subset of the failed)."""
        self._trapped: set[bytes] = set()
        """Points whose model misses most measured slips (:data:`MAX_MISSING_FRACTION`): never
        :attr:`best_u`."""
        self.ringing = dataset.ringing if dataset.mass_from_ringing and all(
            fp.name != "m_kg" for fp in self.free) else None
        """Where set, the mass follows the stiffnesses at its measured frequency (ringing.py)."""
        table = choice.parameter_table()
        self._at_start = {p.name: p.value for p in table}
        self._m_bounds = next((p.lower, p.upper) for p in table if p.name == "m_kg")
        self.time_limit_s: float | None = None
        """CPU seconds an evaluation may take (:func:`rigctl.model.run_clock`; None: no limit);
        one that takes longer is a point that cannot be run (:mod:`rigctl.workbench.search_pool`
        sets it)."""

    def values(self, u: FloatArray) -> dict[str, float]:
        """The model's values at ``u``: the free parameters, and the mass where it follows the
        measured ringing (:attr:`ringing`)."""
        out = {fp.name: fp.to_p(float(x)) for fp, x in zip(self.free, u, strict=True)}
        if self.ringing is not None:
            stiff = {**self._at_start, **out}
            m = ringing_mass(self.ringing, stiff["k0_N_per_m"], stiff["kts_N_per_m"])
            out["m_kg"] = min(max(m, self._m_bounds[0]), self._m_bounds[1])
        return out

    def __call__(self, u: FloatArray) -> FloatArray:
        key = np.asarray(u, dtype=np.float64).tobytes()
        hit = self._cache.get(key)
        if hit is not None:
            return hit
        self.n_evaluations += 1
        candidate = self.choice.with_values(self.values(u))
        try:
            if not physically_valid(candidate, self.fn_range):
                raise ParameterError("mu_k >= mu_s")
            deadline = None if self.time_limit_s is None else \
                run_clock() + self.time_limit_s
            ev = evaluate(self.dataset, candidate, bounded=True, deadline=deadline)
            self._last_events = (key, ev.events)
            vec = ev.score.vector
            if misses_most_slips(self.dataset, ev.score.comparisons):
                self._trapped.add(key)
            if not np.all(np.isfinite(vec)):
                vec = np.where(np.isfinite(vec), vec, FAILED_RESIDUAL)
            elif not self._seen_valid:
                self._seen_valid = True
                self.failed_norm = max(FAILED_RESIDUAL,
                                       FAILED_FACTOR * float(np.linalg.norm(vec)))
        except TimeLimitError:  # past its time limit: the failure penalty, counted apart
            vec = None
            self._timed_out.add(key)
        except SimulationError:
            # not physically valid, or cannot be run (e.g. slips far more often than the record
            # can show: evaluate.slip_budget): the failure penalty
            vec = None
        if vec is None:
            n = self._length()
            vec = np.full(n, self.failed_norm / math.sqrt(max(n, 1)))
            self._failed.add(key)
        if len(self._cache) > 64:
            self._cache.clear()
        self._cache[key] = vec
        cost = float(vec @ vec)
        if cost < self.best_cost and key not in self._trapped:
            self.best_cost = cost
            self.best_u = np.array(u, dtype=np.float64)
        return vec

    def failed(self, u: FloatArray) -> bool:
        """Whether ``u`` was evaluated as not physically valid (its residual is the failure
        penalty, not the model's)."""
        return np.asarray(u, dtype=np.float64).tobytes() in self._failed

    def timed_out(self, u: FloatArray) -> bool:
        """Whether the model at ``u`` failed by passing :attr:`time_limit_s`."""
        return np.asarray(u, dtype=np.float64).tobytes() in self._timed_out

    def events_at(self, u: FloatArray) -> list[EventTable] | None:
        """The model's slip events at ``u`` where ``u`` is the last point this objective ran the
        model at (None otherwise: a point answered from the cache, or never run): what
        :func:`~rigctl.workbench.guess.guess_from_events` re-reads the base levels from without
        running the model again."""
        last = self._last_events
        key = np.asarray(u, dtype=np.float64).tobytes()
        return last[1] if last is not None and last[0] == key else None

    def trapped(self, u: FloatArray) -> bool:
        """Whether the model at ``u`` misses most measured slips (:data:`MAX_MISSING_FRACTION`)."""
        return np.asarray(u, dtype=np.float64).tobytes() in self._trapped

    def _length(self) -> int:
        """The residual vector's length: the data's (:func:`~rigctl.workbench.metrics.
        residual_length`), known without running a model (a model run here, unbounded, to learn
        it held a search for as long as a chattering model took to integrate)."""
        return residual_length(self.dataset)


def fn_range(dataset: Dataset) -> tuple[float, float]:
    """Lowest and highest normal force the campaign's drives apply."""
    lo = min(float(np.min(r.drive.fn_N)) for r in dataset.runs)
    hi = max(float(np.max(r.drive.fn_N)) for r in dataset.runs)
    return lo, hi


def broyden_update(J: FloatArray, du: FloatArray, df: FloatArray) -> FloatArray:
    """The Jacobian corrected by Broyden's rank-one update after a step ``du`` changed the residual
    by ``df``: J + (df - J du) du^T / |du|^2 (Broyden, Math. Comp. 19, 1965, the "good" update);
    ``J`` unchanged for a zero step."""
    nrm = float(du @ du)
    if nrm <= 0.0:
        return J
    return J + np.outer(df - J @ du, du) / nrm


class HybridJacobian:
    """Forward differences for the 'fresh' columns, Broyden updates for the others."""

    def __init__(
        self,
        objective: Objective,
        fresh: Sequence[int],
        initial: FloatArray | None = None,
        *,
        staircase_aware: bool = False,
    ) -> None:
        self.obj = objective
        self.fresh = list(fresh)
        self.staircase_aware = staircase_aware
        """Columns as :meth:`_staircase_column` (for uncertainties) instead of the plain adaptive
        difference the solver uses (:meth:`_column`)."""
        self.J = initial
        self.refresh_first = initial is None
        self.steps: dict[int, float] = {}
        self.resolution: dict[int, float] = {}
        """Columns taken as a secant over a staircase residual: the step (internal units)."""
        self._last: tuple[FloatArray, FloatArray] | None = None

    def _column(self, u: FloatArray, f0: FloatArray, j: int) -> FloatArray:
        """Forward difference with a step adapted per parameter: the residual change is kept
        between FD_CHANGE_MIN and FD_CHANGE_MAX (in units of scatter), large enough to rise above
        the sampling-phase jitter of the features and small enough to stay linear; the step found
        is remembered for the next call. (What the solver uses: on a staircase residual its slopes
        are jumps over small steps, see :meth:`_staircase_column`.)"""
        if self.staircase_aware:
            return self._staircase_column(u, f0, j)
        lo, hi = self.obj.free[j].u_bounds
        size = self.steps.get(j, FD_STEP)
        col = np.zeros_like(f0)
        for _ in range(3):
            h = _signed_step(float(u[j]), size, lo, hi)
            uj = u.copy()
            uj[j] += h
            diff = self.obj(uj) - f0
            col = diff / h
            nxt = next_fd_step(h, float(np.linalg.norm(diff)), grow_from_zero=False)
            if nxt is None:
                break
            size = nxt
        self.steps[j] = size
        return col

    def _staircase_column(self, u: FloatArray, f0: FloatArray, j: int) -> FloatArray:
        """The forward difference of :meth:`_column`, aware of a staircase residual.

        Event features make the residual a staircase where the events barely depend on a
        parameter (a slip gained or lost, a transition inside one sample): no step then gives a
        change inside the band. The column is then the secant over the largest step tried that
        moved the residual (the quotient of a jump and a small step would be huge, and its
        'uncertainty' tiny), and that step is kept in :attr:`resolution`: the data locate the
        parameter no better than it. A step into the invalid region (mu_k reaching mu_s) is
        taken the other way."""
        lo, hi = self.obj.free[j].u_bounds
        size = self.steps.get(j, FD_STEP)
        tried: list[tuple[float, float, FloatArray]] = []
        linear = False
        for _ in range(3):
            h = _signed_step(float(u[j]), size, lo, hi)
            uj = u.copy()
            uj[j] += h
            diff = self.obj(uj) - f0
            if self.obj.failed(uj) and lo <= u[j] - h <= hi:
                h = -h
                uj[j] = u[j] + h
                diff = self.obj(uj) - f0
            if self.obj.failed(uj):
                break  # pinned by validity both ways: no usable slope
            change = float(np.linalg.norm(diff))
            tried.append((abs(h), change, diff / h))
            nxt = next_fd_step(h, change, grow_from_zero=True)
            if nxt is None:
                linear = FD_CHANGE_MIN <= change <= FD_CHANGE_MAX
                break
            size = nxt
        self.steps[j] = size
        self.resolution.pop(j, None)
        if not tried:
            return np.zeros_like(f0)
        if linear or not _staircase(tried):
            return tried[-1][2]
        h_used, _, col = max((t for t in tried if t[1] > 0.0), key=lambda t: t[0])
        self.resolution[j] = h_used
        return col

    def __call__(self, u: FloatArray) -> FloatArray:
        u = np.asarray(u, dtype=np.float64)
        f0 = self.obj(u)
        n = u.shape[0]
        if self.J is None or (self._last is None and self.refresh_first):
            self.J = np.zeros((f0.shape[0], n))
            cols = list(range(n))
        else:
            if self._last is not None:
                self.J = broyden_update(self.J, u - self._last[0], f0 - self._last[1])
            cols = self.fresh
        for j in cols:
            self.J[:, j] = self._column(u, f0, j)
        self._last = (u.copy(), f0.copy())
        return self.J.copy()

    def full(self, u: FloatArray) -> FloatArray:
        """A fresh forward-difference Jacobian (all columns)."""
        u = np.asarray(u, dtype=np.float64)
        f0 = self.obj(u)
        J = np.zeros((f0.shape[0], u.shape[0]))
        for j in range(u.shape[0]):
            J[:, j] = self._column(u, f0, j)
        return J


def _signed_step(u_j: float, size: float, lo: float, hi: float) -> float:
    """A forward step of ``size`` from ``u_j``, backward where it would pass the upper bound, half
    the range where it would pass both."""
    h = size if u_j + size <= hi else -size
    if u_j + h < lo:
        h = 0.5 * (hi - lo)
    return h


def next_fd_step(h: float, change: float, *, grow_from_zero: bool) -> float | None:
    """The next forward-difference step size after step ``h`` (internal units) moved the residual
    by ``change`` (its norm, scatter units): shrunk above FD_CHANGE_MAX, grown below FD_CHANGE_MIN
    (from no change at all only with ``grow_from_zero``: the step fell between two samples' worth
    of feature change), within FD_STEP_MIN..FD_STEP_MAX; None when ``h`` is to be kept. The rule
    of every adaptive Jacobian column of the workbench: this module's solver and uncertainties,
    and the one search's Jacobians (:mod:`rigctl.workbench.search`)."""
    if change > FD_CHANGE_MAX and abs(h) > FD_STEP_MIN:
        return max(abs(h) * FD_CHANGE_MAX / change, FD_STEP_MIN)
    if change < FD_CHANGE_MIN and abs(h) < FD_STEP_MAX and (change > 0.0 or grow_from_zero):
        grow = FD_CHANGE_MIN / change if change > 0.0 else FD_GROW_FROM_ZERO
        return min(abs(h) * grow, FD_STEP_MAX)
    return None


STAIRCASE_RATIO = 3.0
"""Two forward differences of one column whose changes scale with their steps to within this
factor count as a slope; otherwise (or a change above FD_CHANGE_MAX at the smallest step, or none
at one step and a real one at another) the residual is a staircase there."""


def _staircase(tried: Sequence[tuple[float, float, FloatArray]]) -> bool:
    """Whether the (step, change, column) differences of one column show a staircase residual
    (:data:`STAIRCASE_RATIO`), not a slope."""
    if len(tried) == 1:
        h, change, _ = tried[0]
        return change > FD_CHANGE_MAX and h <= FD_STEP_MIN
    for (h1, c1, _), (h2, c2, _) in itertools.pairwise(tried):
        if c1 == 0.0 or c2 == 0.0:
            if max(c1, c2) > FD_CHANGE_MIN:
                return True
            continue
        ratio = (c2 / c1) / (h2 / h1)
        if not 1.0 / STAIRCASE_RATIO <= ratio <= STAIRCASE_RATIO:
            return True
    return False


def free_params(choice: ModelChoice, names: Sequence[str] | None = None,
                rig: RigDescription | None = None) -> list[FreeParam]:
    """The parameters to fit: ``names``, or every parameter marked ``identify``; a rig description
    (:mod:`rigctl.records.rig_description`) removes those it fixes and narrows those it bounds."""
    table = {p.name: p for p in choice.parameter_table()}
    if names is None:
        names = [p.name for p in table.values() if p.identify]
    out = []
    for name in names:
        if name not in table:
            raise ParameterError(f"cannot fit '{name}': not a parameter of {choice.label()}")
        if rig is not None and name in rig.fixed:
            continue
        fp = FreeParam.from_info(table[name])
        if rig is not None and name in rig.bounds:
            lo, hi = rig.bounds[name]
            lo, hi = max(lo, fp.lower), min(hi, fp.upper)
            if not lo < hi:
                raise ParameterError(f"rig description bounds of '{name}' lie outside its "
                                     f"range [{fp.lower:g}, {fp.upper:g}]")
            fp = replace(fp, lower=lo, upper=hi)
        out.append(fp)
    return out


def uncertainties(
    free: Sequence[FreeParam], values: Mapping[str, float], J: FloatArray, residual: FloatArray,
    resolution: Mapping[int, float] | None = None,
) -> tuple[dict[str, float], list[str]]:
    """1-sigma uncertainties in parameter units and the parameters the data cannot determine.

    ``resolution``: columns whose residual is a staircase (:meth:`HybridJacobian._column`) and the
    step of their secant; such a parameter's sigma is at least that step, since the data do not
    locate it more finely. The residuals are in units of the measured scatter, so their variance
    is taken as at least 1: a fit inside the scatter floors (the force features of a simulated run
    fit 5-20 times inside theirs) does not locate its parameters better than the noise allows."""
    m, p = J.shape
    s2 = max(float(residual @ residual) / max(m - p, 1), 1.0)
    col_norm = np.linalg.norm(J, axis=0)
    cov = np.linalg.pinv(J.T @ J, rcond=1e-10) * s2
    sig_u = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    for j, h in (resolution or {}).items():
        sig_u[j] = max(float(sig_u[j]), h)
    sigma: dict[str, float] = {}
    undetermined: list[str] = []
    tiny = 1e-9 * (float(col_norm.max()) if col_norm.size else 1.0)
    for j, fp in enumerate(free):
        v = values[fp.name]
        sp = float(sig_u[j] * fp.dp_du(v))
        sigma[fp.name] = sp
        if col_norm[j] <= tiny:
            undetermined.append(fp.name)
        elif fp.log:
            if sig_u[j] > 0.3:
                undetermined.append(fp.name)
        elif sp > 0.5 * abs(v) and sp > 0.05 * (fp.upper - fp.lower):
            undetermined.append(fp.name)
    return sigma, undetermined


def _uncertainties_at(
    obj: Objective, free: Sequence[FreeParam], values: Mapping[str, float], u: FloatArray,
    residual: FloatArray,
) -> tuple[FloatArray, dict[str, float], list[str]]:
    """The Jacobian at ``u`` and the uncertainties it gives. A staircase-aware Jacobian, its steps
    adapted afresh from FD_STEP (a solver's may have shrunk onto a jump): a jump of the events over
    a tiny step is not a slope that pins the parameter."""
    careful = HybridJacobian(obj, [], staircase_aware=True)
    J = careful.full(u)
    sigma, undetermined = uncertainties(free, dict(values), J, residual, careful.resolution)
    return J, sigma, undetermined


def with_uncertainties(dataset: Dataset, result: FitResult) -> FitResult:
    """``result`` with uncertainties and the Jacobian taken at its own values (no further fit)."""
    free = free_params(result.choice, list(result.free))
    if not free:
        return result
    obj = Objective(dataset, result.choice, free)
    table = {p.name: p.value for p in result.choice.parameter_table()}
    values = {fp.name: table[fp.name] for fp in free}
    u = np.array([fp.to_u(values[fp.name]) for fp in free])
    # the residual at u is the Jacobian's own base point (the objective caches it)
    J, sigma, undetermined = _uncertainties_at(obj, free, values, u, obj(u))
    return replace(result, sigma=sigma, undetermined=undetermined, jacobian=np.array(J),
                   n_evaluations=result.n_evaluations + obj.n_evaluations)


def least_squares_fit(
    dataset: Dataset,
    choice: ModelChoice,
    free: Sequence[FreeParam],
    *,
    start: Mapping[str, float] | None = None,
    initial_jacobian: FloatArray | None = None,
    fresh_columns: Sequence[int] | None = None,
    max_nfev: int = 20,
    with_uncertainty: bool = False,
) -> FitResult:
    """Least-squares fit of ``free`` (others as in ``choice``), from ``start`` or the choice."""
    current = {p.name: p.value for p in choice.parameter_table()}
    if start:
        current.update(start)
    obj = Objective(dataset, choice, free)
    u0 = np.array([fp.to_u(current[fp.name]) for fp in free])
    bounds = (np.array([fp.u_bounds[0] for fp in free]), np.array([fp.u_bounds[1] for fp in free]))
    u0 = np.clip(u0, bounds[0], bounds[1])
    fresh = list(range(len(free))) if fresh_columns is None else list(fresh_columns)
    jac = HybridJacobian(obj, fresh, initial_jacobian)
    message = "no free parameters"
    if free:
        sol = least_squares(
            obj, u0, jac=jac, bounds=bounds, method="trf", x_scale=1.0, max_nfev=max_nfev,
            ftol=1e-4, xtol=1e-4, gtol=1e-6,
        )
        # the solver's end unless a point it visited scored better, or its end misses most slips
        # and a point that does not was visited
        if obj.best_u is not None and (sol.cost * 2 > obj.best_cost or obj.trapped(sol.x)):
            u = obj.best_u
        else:
            u = sol.x
        message = str(sol.message)
    else:
        u = u0
    values = obj.values(u)
    fitted = choice.with_values(values)
    ev = evaluate(dataset, fitted)
    J = jac.J
    sigma: dict[str, float] = {}
    undetermined: list[str] = []
    if free and with_uncertainty:
        J, sigma, undetermined = _uncertainties_at(obj, free, values, u, ev.score.vector)
    return FitResult(
        choice=fitted,
        error=ev.score.error,
        feature_error=ev.score.feature_error,
        free=tuple(fp.name for fp in free),
        sigma=sigma,
        undetermined=undetermined,
        n_evaluations=obj.n_evaluations + 1,
        message=message,
        jacobian=None if J is None else np.array(J),
        misses_most_slips=misses_most_slips(dataset, ev.score.comparisons),
    )
