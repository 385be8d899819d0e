"""Identification strategies: the model as given (baseline) and the model plus one candidate effect.

* :func:`identify_model` fits every ``identify`` parameter of a model, starting from the better of
  its current values and the data-informed guess (:mod:`rigctl.workbench.guess`).
* :func:`fit_candidate` adds one effect to an identified model and fits the effect's parameters
  together with the model's. Global where needed, in three stages:

  1. scan: the effect's identified parameters on a grid of 0.1, 0.3, 1 and 3 times their typical
     deviation from "off" (-1 ... 3 where the bounds allow both signs); at each point the base
     friction and stiffness levels are re-read from the data (the guess of
     :mod:`rigctl.workbench.guess`, since an effect can shift them far: aging raises every peak);
  2. the points are ranked by the cost a Gauss-Newton step of the base parameters would reach
     (with a Jacobian taken with the effect on), and the best four get two such steps;
  3. bounded least squares (:mod:`rigctl.workbench.identify`) from the best two, the better kept.

  If nothing beats the base model the effect is reported switched off. Everything a fit needs is
  picklable, so candidates fit in parallel processes or on a Dask cluster
  (:mod:`rigctl.workbench.parallel`).
"""

from __future__ import annotations

import itertools
import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from rigctl.errors import SimulationError
from rigctl.model import ParameterError
from rigctl.records.dataset import Dataset
from rigctl.records.rig_description import check_names
from rigctl.workbench.data_scale import (
    NEAR_PRESET,
    DataScale,
    base_start,
    measure_scale,
    scale_effect_values,
    scale_ratios,
)
from rigctl.workbench.evaluate import evaluate
from rigctl.workbench.guess import initial_guess
from rigctl.workbench.identify import (
    DYNAMIC_PARAMS,
    FitResult,
    FreeParam,
    HybridJacobian,
    Objective,
    broyden_update,
    fn_range,
    free_params,
    least_squares_fit,
    misses_most_slips,
    physically_valid,
)
from rigctl.workbench.metrics import Score
from rigctl.workbench.model_choice import ModelChoice, effect_class
from rigctl.workbench.parallel import TaskFailed, run_tasks

BASELINE_MAX_NFEV = 24  # solver evaluations for the model as given (its fit is done once)
CANDIDATE_MAX_NFEV = 10  # per candidate start: a dozen candidates are fitted per round
N_STARTS = 2  # candidate starts given the local fit after the scan (the better end is kept)
GN_SCAN_ITERATIONS = 2  # Gauss-Newton steps of the base parameters at each promising scan point
GN_MORE_ITERATIONS = 3  # further steps at the kept starts, while they gain
GN_MIN_GAIN = 0.1  # a step that lowers the best cost by less than this fraction did not gain
GN_STALL = 2  # the steps stop after this many in a row without gain
SCAN_FACTORS: tuple[float, ...] = (0.1, 0.3, 1.0, 3.0)  # x the effect's typical deviation from off
SIGNED_SCAN_FACTORS: tuple[float, ...] = (-1.0, -0.2, 0.2, 1.0, 3.0)  # the same, both signs allowed
MAX_SCAN_POINTS = 25  # scan points of an effect with several parameters (a 5 x 5 grid)
SWITCHED_OFF = "the effect does not improve the fit; reported switched off"
"""The message of a candidate fit that ended no better than the base model (the base reported)."""


def identify_model(
    dataset: Dataset, choice: ModelChoice, with_uncertainty: bool = True,
    max_nfev: int = BASELINE_MAX_NFEV, workers: int = 1,
) -> FitResult:
    """Fit all identifiable parameters of ``choice`` on ``dataset``.

    Two starts: the model's current values and the same carried to the data's own scale
    (:mod:`rigctl.workbench.data_scale`: a record of another rig lies decades from the preset).
    Where the data-scale start lies on another rig (:func:`_another_rig`) both are fitted and the
    better end is kept; else the fit starts from the better of the two by the event-aware error.
    Mass and drive damping are fitted too (where both starts are fitted: from the data-scale start,
    and from the preset's end where that one is kept) unless
    the rig description states them (a rig knows its own; the simulated rig states them in every
    run, :data:`rigctl.model.simulator.STATED_RIG_PARAMS`): the preset's are this rig's, and
    another rig's data, stiff or soft, heavy or light, need their own (held at the preset's, their
    misfit is taken up by whatever other parameter moves the ringing, a damper or an effect, and
    that one is then reported falsely; docs/decisions.md). Each
    start is replaced by the ratio guess of
    :mod:`rigctl.workbench.guess` where that scores better. Parameters the rig description fixes
    are set and left out of the fit; those it bounds are fitted inside its range.

    With ``workers`` > 1 the two starts are fitted at once, each in a worker process
    (:func:`~rigctl.workbench.parallel.run_tasks`, no time limit: a base fit has no other to fall
    back on); the ends are the same as one after the other.
    """
    rig = dataset.rig
    check_names(rig, [p.name for p in choice.parameter_table()])
    if rig.fixed:
        choice = choice.with_values(rig.fixed)
    free = free_params(choice, rig=rig)
    fns = fn_range(dataset)
    if not physically_valid(choice, fns):
        raise ParameterError(f"{choice.label()}: kinetic friction is not below static friction")
    e_model = error_or_inf(dataset, choice, fns)
    starts = [(choice, e_model, True)]
    scaled = data_scaled(dataset, choice, free)
    if scaled is not None:
        another = _another_rig(choice, scaled)
        if another:
            # on another rig's data both starts are fitted and the better end is kept: the error
            # of a start far from the data says little about where its fit ends (a start that
            # slips at the wrong level can score better than one at the data's scale whose fit
            # then goes much further; docs/decisions.md); the
            # preset's start keeps its mass and damping in its first fit (a mass scan from the
            # preset would search decades away from the data, and small masses cost the engine
            # most): they are fitted on from its end where that end is kept (below)
            starts = [(choice, e_model, False), (scaled, error_or_inf(dataset, scaled, fns), True)]
        else:
            starts = [min([*starts, (scaled, error_or_inf(dataset, scaled, fns), True)],
                          key=lambda start: start[1])]
    tasks = [_StartFit(dataset, c, e, free, fns, dyn, max_nfev, with_uncertainty)
             for c, e, dyn in starts]
    results = _fit_starts(tasks, workers)
    # an end whose model misses most slips is a trap, not a fit, whatever its error: from a start
    # that already missed them the fit cannot move (each missing slip costs a fixed z), and its
    # capped error can still beat a fit that makes the slips
    ends = [(r, dyn) for r, (_, _, dyn) in zip(results, starts, strict=True)]
    made_slips = [end for end in ends if not end[0].misses_most_slips]
    best, fitted_dynamics = min(made_slips or ends, key=lambda end: end[0].error)
    if not fitted_dynamics and _dynamics_to_fit(dataset, best.free):
        # the preset's start won on another rig's data: its stiffness and friction are now the
        # data's, so its mass and damping (still the preset's) are scanned and fitted on from
        # there; kept as they were they would stay the preset's through every later fit (a local
        # fit hardly moves the mass: the drop shape and the ringing are not smooth in it), and
        # the effects fitted later would take up their misfit (docs/decisions.md)
        best = _fit_from(dataset, best.choice, best.error, free, fns, free_dynamics=True,
                         max_nfev=max_nfev, with_uncertainty=with_uncertainty)
    return best


@dataclass(frozen=True)
class _StartFit:
    """One start of :func:`identify_model`, as a task a worker process can run."""

    dataset: Dataset
    choice: ModelChoice
    e_start: float
    free: list[FreeParam]
    fns: tuple[float, float]
    free_dynamics: bool
    max_nfev: int
    with_uncertainty: bool


def _fit_start(task: _StartFit) -> FitResult:
    return _fit_from(task.dataset, task.choice, task.e_start, task.free, task.fns,
                     free_dynamics=task.free_dynamics, max_nfev=task.max_nfev,
                     with_uncertainty=task.with_uncertainty)


def _fit_starts(tasks: Sequence[_StartFit], workers: int) -> list[FitResult]:
    """Each start's fit; at once in worker processes when there are several starts and workers.
    A start whose worker failed is fitted again here, so that its error is raised as it would be
    in this process (a model that cannot be simulated, an invalid parameter)."""
    if workers <= 1 or len(tasks) <= 1:
        return [_fit_start(t) for t in tasks]
    outcomes = run_tasks(_fit_start, tasks, workers=min(workers, len(tasks)), timeout_s=math.inf)
    return [_fit_start(task) if isinstance(res, TaskFailed) else res
            for task, res in zip(tasks, outcomes, strict=True)]


def _fit_from(dataset: Dataset, choice: ModelChoice, e_start: float, free: list[FreeParam],
              fns: tuple[float, float], *, free_dynamics: bool, max_nfev: int,
              with_uncertainty: bool) -> FitResult:
    """The local fit from one start; with ``free_dynamics`` the mass, unless the rig description
    states it, is scanned first, and mass and drive damping are fitted too; the ratio guess
    replaces the start where it scores better."""
    rig = dataset.rig
    best_choice, e_best = choice, e_start
    if free_dynamics:
        # mass and damping not stated are guesses (the preset's, or data_scale.py's); the
        # post-slip dynamics (ringing, drop shape) determine them where the sampling resolves
        # them, else the fit reports them as not determined
        # where the ringing is resolved the mass follows the stiffnesses at its frequency
        # (Objective.values), and is neither scanned nor fitted
        extra = _dynamics_to_fit(dataset, [fp.name for fp in free])
        if "m_kg" in extra:
            best_choice, e_best = _scan_mass(dataset, best_choice, e_best, fns,
                                             keep_damping="c0_N_s_per_m" in extra)
        free = free + free_params(best_choice, extra, rig=rig)
    start: dict[str, float] = {}
    try:
        guess = initial_guess(dataset, best_choice, free)
    except SimulationError:
        guess = {}
    if guess and error_or_inf(dataset, best_choice.with_values(guess), fns) <= e_best:
        start = guess
    return least_squares_fit(dataset, best_choice, free, start=start, max_nfev=max_nfev,
               with_uncertainty=with_uncertainty)


def _dynamics_to_fit(dataset: Dataset, have: Sequence[str]) -> list[str]:
    """Mass and drive damping not among ``have`` that a fit with free dynamics adds: not those the
    rig description fixes, nor the mass where the resolved ringing ties it to the stiffnesses."""
    return [n for n in DYNAMIC_PARAMS if n not in have and n not in dataset.rig.fixed
            and not (n == "m_kg" and dataset.mass_from_ringing)]


MASS_SCAN_FACTORS: tuple[float, ...] = (0.01, 0.03, 0.1, 0.3, 3.0, 10.0, 30.0, 100.0)
"""Mass multiples tried before the local fit on another rig's data (a global search of the one
parameter the local fit does not move: the drop shape and ringing are not smooth in M)."""


def _scan_mass(dataset: Dataset, choice: ModelChoice, e_now: float, fns: tuple[float, float],
               keep_damping: bool) -> tuple[ModelChoice, float]:
    """The best mass of MASS_SCAN_FACTORS x the start (C0 moved with sqrt(M), keeping the damping
    ratio, when it is fitted too), by the event-aware error."""
    values = {p.name: p.value for p in choice.parameter_table()}
    m0, c0 = values["m_kg"], values.get("c0_N_s_per_m", 0.0)
    best, e_best = choice, e_now
    for f in MASS_SCAN_FACTORS:
        trial = {"m_kg": m0 * f}
        if keep_damping and c0 > 0:
            trial["c0_N_s_per_m"] = c0 * f**0.5
        try:
            cand = choice.with_values(trial)
        except ParameterError:
            continue
        e = error_or_inf(dataset, cand, fns)
        if e < e_best:
            best, e_best = cand, e
    return best, e_best


def error_or_inf(dataset: Dataset, choice: ModelChoice, fns: tuple[float, float]) -> float:
    """The event-aware error of ``choice`` as a start; inf where :func:`_score_or_none` has none."""
    score = _score_or_none(dataset, choice, fns)
    return float("inf") if score is None else float(score.error)


def _score_or_none(dataset: Dataset, choice: ModelChoice, fns: tuple[float, float]) -> Score | None:
    """The model's score, or None when it is not physically valid, cannot be run, or misses most of
    the measured slips (no description of the data, whatever its error: a start, scan point or
    step there would lead the fit into the no-slip trap, see
    :func:`~rigctl.workbench.identify.misses_most_slips`)."""
    if not physically_valid(choice, fns):
        return None
    try:
        score = evaluate(dataset, choice, bounded=True).score
    except SimulationError:
        return None
    return None if misses_most_slips(dataset, score.comparisons) else score


def _another_rig(model: ModelChoice, scaled: ModelChoice) -> bool:
    """The data lie far from the model's rig: the data-scale drive or interface stiffness is more
    than NEAR_PRESET times off the model's (a load or friction level alone does not make another
    rig: this rig runs 150-800 N)."""
    now = {p.name: p.value for p in model.parameter_table()}
    new = dict(scaled.values)
    for name in ("k0_N_per_m", "kts_N_per_m"):
        if name in new and now.get(name, 0.0) > 0.0:
            r = new[name] / now[name]
            if not 1.0 / NEAR_PRESET <= r <= NEAR_PRESET:
                return True
    return False


def campaign_scale(dataset: Dataset) -> DataScale:
    """What the campaign's measured events and post-slip ringing show directly (data_scale.py)."""
    return measure_scale(
        (r.events for r in dataset.runs),
        delta_measured=any(r.delta_measured for r in dataset.runs),
        ringing=dataset.ringing,
    )


def data_scaled(dataset: Dataset, choice: ModelChoice,
                free: list[FreeParam]) -> ModelChoice | None:
    """``choice`` with its base values at the data's scale (None when the events do not show it).

    Fitted parameters take the data-scale values within their (rig-description) bounds; the fixed
    ones keep what the rig description states."""
    current = {p.name: p.value for p in choice.parameter_table()}
    scale = campaign_scale(dataset)
    values = base_start(scale, current, dataset.rig.fixed)
    if not values:
        return None
    bounds = {fp.name: (fp.lower, fp.upper) for fp in free}
    table = {p.name: p for p in choice.parameter_table()}
    out = {}
    for k, v in values.items():
        lo, hi = bounds.get(k, (table[k].lower, table[k].upper))
        out[k] = float(min(max(v, lo), hi))
    if out.get("mu_k", 0.0) >= out.get("mu_s", 1.0):
        return None
    try:
        return choice.with_values(out)
    except ParameterError:
        return None


def _scan(
    dataset: Dataset, choice: ModelChoice, base_free: list[FreeParam], J_base: np.ndarray | None,
    points: list[dict[str, float]], n_check: int = 4, n_keep: int = 1,
) -> tuple[list[tuple[float, dict[str, float]]], np.ndarray | None]:
    """Best start among ``points``.

    At each point the base parameters would take a Gauss-Newton step with the base Jacobian to
    absorb what the effect shifts on average (e.g. a mean friction rise); the points are ranked by
    the cost that step predicts (|r - J J^+ r|^2, no extra simulation), the best ``n_check`` take
    GN_SCAN_ITERATIONS such steps and the best ``n_keep`` of them up to GN_MORE_ITERATIONS more
    while they gain (:class:`_BaseWalk`). Returns the ``n_keep`` best starts (cost, values), best first,
    from distinct scan points, and the base Jacobian taken with the effect on (None if none was
    taken).
    """
    fns = fn_range(dataset)
    lo = np.array([fp.u_bounds[0] for fp in base_free])
    hi = np.array([fp.u_bounds[1] for fp in base_free])
    evaluated: list[tuple[dict[str, float], np.ndarray]] = []
    current = {p.name: p.value for p in choice.parameter_table()}
    base_now = {fp.name: current[fp.name] for fp in base_free}
    for raw_pt in points:
        if not physically_valid(choice.with_values(raw_pt), fns):
            continue
        # the friction and stiffness levels re-read from the data with the effect on (an effect
        # may shift them far: aging raises every peak), as for the base model's first guess
        try:
            pt = {**raw_pt, **initial_guess(dataset, choice.with_values(raw_pt), base_free)}
        except SimulationError:
            continue
        if not physically_valid(choice.with_values(pt), fns):
            pt = {**base_now, **raw_pt}  # valid: checked above
        vec = _vector_or_none(dataset, choice.with_values(pt), fns)
        if vec is not None and np.all(np.isfinite(vec)):
            evaluated.append((pt, vec))
    if not evaluated:
        return [(np.inf, dict(points[0]))], None
    ranked = _rank_points(evaluated, J_base)
    J_effect_on: np.ndarray | None = None
    if J_base is not None and base_free and len(evaluated) > 1:
        # the base Jacobian was taken with the effect off; take one afresh with the effect on at
        # the most promising point and rank again with it
        top = ranked[0][2]
        obj = Objective(dataset, choice.with_values(top), base_free)
        J_on = HybridJacobian(obj, []).full(np.array([fp.to_u(top[fp.name]) for fp in base_free]))
        if np.all(np.isfinite(J_on)):
            J_base = J_effect_on = J_on
            ranked = _rank_points(evaluated, J_base)
    walks: list[_BaseWalk] = []
    for _, e_raw, pt, vec, gn_step in ranked[:n_check]:
        walk = _BaseWalk(pt, (e_raw, dict(pt)))
        if gn_step is not None and J_base is not None:
            walk.start(base_free, J_base, vec, gn_step)
            walk.advance(dataset, choice, base_free, (lo, hi), fns, GN_SCAN_ITERATIONS)
        walks.append(walk)
    walks.sort(key=lambda w: w.best[0])
    for walk in walks[:n_keep]:
        # the kept starts walk on while a step still gains (up to GN_MORE_ITERATIONS steps, until
        # GN_STALL in a row gain less than GN_MIN_GAIN): a Gauss-Newton walk from a scan point
        # far from the base's optimum need not be monotone, and where the local fit starts
        # decides where it ends
        walk.advance(dataset, choice, base_free, (lo, hi), fns, GN_MORE_ITERATIONS)
    walks.sort(key=lambda w: w.best[0])
    return [w.best for w in walks[:n_keep]], J_effect_on


def _vector_or_none(dataset: Dataset, choice: ModelChoice,
                    fns: tuple[float, float]) -> np.ndarray | None:
    """The model's residual vector, or None where :func:`_score_or_none` has no score."""
    score = _score_or_none(dataset, choice, fns)
    return None if score is None else score.vector


def _rank_points(
    evaluated: list[tuple[dict[str, float], np.ndarray]], J: np.ndarray | None,
) -> list[tuple[float, float, dict[str, float], np.ndarray, np.ndarray | None]]:
    """(predicted cost after a Gauss-Newton step, raw cost, point, its residual vector, step),
    best first."""
    out: list[tuple[float, float, dict[str, float], np.ndarray, np.ndarray | None]] = []
    pinv = np.linalg.pinv(J, rcond=1e-8) if J is not None and J.shape[1] else None
    for pt, vec in evaluated:
        raw = float(vec @ vec)
        if pinv is not None and J is not None:
            step = -pinv @ vec
            pred = vec + J @ step
            out.append((float(pred @ pred), raw, pt, vec, step))
        else:
            out.append((raw, raw, pt, vec, None))
    out.sort(key=lambda x: x[0])
    return out


@dataclass
class _BaseWalk:
    """Gauss-Newton steps of the base parameters at a scan point (the effect's parameters held),
    the Jacobian corrected after each by a Broyden rank-one update (one simulation per step)."""

    pt: dict[str, float]
    best: tuple[float, dict[str, float]]
    """Lowest cost seen and its values (the point itself before any step)."""
    u: np.ndarray | None = None
    vec: np.ndarray | None = None
    J: np.ndarray | None = None
    step: np.ndarray | None = None
    stalled: int = 0
    """Steps in a row that did not lower the best cost by GN_MIN_GAIN."""

    def start(self, base_free: list[FreeParam], J: np.ndarray, vec_pt: np.ndarray,
              step: np.ndarray) -> None:
        """From the point's residual ``vec_pt`` (from the scan) and the first step ``step``."""
        self.u = np.array([fp.to_u(self.pt[fp.name]) for fp in base_free])
        self.vec, self.J, self.step = vec_pt, J.copy(), step

    def advance(self, dataset: Dataset, choice: ModelChoice, base_free: list[FreeParam],
                bounds: tuple[np.ndarray, np.ndarray], fns: tuple[float, float],
                iterations: int) -> None:
        """Up to ``iterations`` steps; stops once GN_STALL steps in a row gained less than
        GN_MIN_GAIN of the best cost (or a model cannot be run)."""
        for _ in range(iterations):
            if self.u is None or self.J is None or self.step is None or self.vec is None \
                    or self.stalled >= GN_STALL:
                return
            u_new = np.clip(self.u + self.step, bounds[0], bounds[1])
            moved = {fp.name: fp.to_p(float(x)) for fp, x in zip(base_free, u_new, strict=True)}
            values = {**self.pt, **moved}
            vec = _vector_or_none(dataset, choice.with_values(values), fns)
            if vec is None:
                self.u = None
                return
            cost = float(vec @ vec)
            if cost < (1.0 - GN_MIN_GAIN) * self.best[0]:
                self.stalled = 0
            else:
                self.stalled += 1
            if cost < self.best[0]:
                self.best = (cost, values)
            self.J = broyden_update(self.J, u_new - self.u, vec - self.vec)
            self.u, self.vec = u_new, vec
            self.step, *_ = np.linalg.lstsq(self.J, -vec, rcond=1e-8)


def _scan_points(fps: list[FreeParam], defaults: dict[str, float],
                 offs: dict[str, float]) -> list[dict[str, float]]:
    """Start points: each parameter at its off value plus a factor times its typical deviation
    (default - off); a full grid when it stays within MAX_SCAN_POINTS, else joint factors plus
    one-parameter-at-a-time variations."""
    factors: dict[str, tuple[float, ...]] = {}
    typical: dict[str, float] = {}
    for fp in fps:
        off = offs.get(fp.name, 0.0)
        typ = defaults[fp.name] - off
        if typ == 0.0:
            typ = 0.05 * (fp.upper - fp.lower)
        typical[fp.name] = typ
        signed = fp.lower < off < fp.upper and fp.lower < 0.0
        factors[fp.name] = SIGNED_SCAN_FACTORS if signed else SCAN_FACTORS

    def point(fs: dict[str, float]) -> dict[str, float]:
        return {
            fp.name: float(np.clip(offs.get(fp.name, 0.0) + fs[fp.name] * typical[fp.name],
                                   fp.lower, fp.upper))
            for fp in fps
        }

    n_grid = int(np.prod([len(f) for f in factors.values()])) if fps else 0
    if n_grid <= MAX_SCAN_POINTS:
        combos = itertools.product(*(factors[fp.name] for fp in fps))
        return [point(dict(zip([fp.name for fp in fps], c, strict=True))) for c in combos]
    pts = []
    joint = sorted(set().union(*[set(f) for f in factors.values()]))
    for f in joint:
        pts.append(point({fp.name: f for fp in fps}))
    for fp in fps:
        for f in factors[fp.name]:
            fs = {q.name: 1.0 for q in fps}
            fs[fp.name] = f
            pts.append(point(fs))
    return pts


@dataclass(frozen=True)
class CandidateTask:
    """One candidate fit, as data (sent to a worker)."""

    dataset: Dataset
    base: FitResult
    effect: str


def fit_candidate(task: CandidateTask, with_uncertainty: bool = False) -> FitResult:
    """Identify ``base`` + ``effect`` (base parameters re-fitted together with the effect's)."""
    t0, c0 = time.perf_counter(), time.process_time()
    result = _fit_candidate(task, with_uncertainty)
    result.elapsed_s = time.perf_counter() - t0
    result.cpu_s = time.process_time() - c0
    return result


def _at_data_scale(dataset: Dataset, choice: ModelChoice, effect: str) -> ModelChoice:
    """The effect's dimensional defaults carried to the data's scale (data_scale.py: only where
    the data lie more than a factor 3 from the preset), except what the rig description fixes."""
    scale = campaign_scale(dataset)
    if not scale.usable:
        return choice
    prefix = f"{effect}."
    table = [(p.name, p.value, p.lower, p.upper, p.scales_with)
             for p in choice.parameter_table()
             if p.name.startswith(prefix) and p.scales_with and p.name not in dataset.rig.fixed]
    base_vals = {k: v for k, v in choice.values.items() if "." not in k}
    rate = float(np.median([r.sample_rate_hz for r in dataset.runs]))
    changed = scale_effect_values(table, scale_ratios(scale, base_vals, rate))
    if not changed:
        return choice
    try:
        return choice.with_values(changed)
    except ParameterError:
        return choice


def _fit_candidate(task: CandidateTask, with_uncertainty: bool) -> FitResult:
    dataset, base, effect = task.dataset, task.base, task.effect
    choice = _at_data_scale(dataset, base.choice.with_effect(effect), effect)
    table = {p.name: p for p in choice.parameter_table()}
    cls = effect_class(effect, choice.effect_files)
    prefix = f"{effect}."
    eff_names = [n for n, p in table.items() if n.startswith(prefix) and p.identify]
    eff_free = free_params(choice, eff_names)
    defaults = {n: table[n].value for n in eff_names}
    offs: dict[str, float] = {}
    if cls is not None:
        base_vals = {n: p.value for n, p in table.items() if "." not in n}
        try:
            offs = {prefix + k: v for k, v in cls().off_values(base_vals).items()}
        except NotImplementedError:
            offs = {}
    base_free = free_params(choice, list(base.free))
    free = base_free + eff_free
    J_base = base.jacobian if base.jacobian is not None and \
        base.jacobian.shape[1] == len(base_free) else None
    # the scan leaves out the off point: effects switch the engine to another integration path
    # when they turn on, so derivatives taken right at "off" can mislead; the fit is compared with
    # the base model (the effect off) at the end instead
    starts, J_on = _scan(dataset, choice, base_free, J_base,
                         _scan_points(eff_free, defaults, offs), n_keep=N_STARTS)
    if offs and not math.isfinite(starts[0][0]):
        # no scan point is physically valid on this model: a fit from an invalid start has no
        # valid point to step from and runs into the time limit (docs/decisions.md); the
        # effect is reported switched off at once
        return _switched_off(base, choice, offs, tuple(fp.name for fp in free), 0,
                             f"{SWITCHED_OFF} (no physically valid start on this model)")
    # the effect's columns are differenced at every step; the base columns start from the
    # Jacobian the scan took with the effect on (an effect can change how the base parameters
    # act: a new slip law, a filtered force) and are then updated by Broyden
    fresh = list(range(len(base_free), len(free)))
    init = None
    if J_on is not None:
        init = np.hstack([J_on, np.zeros((J_on.shape[0], len(eff_free)))])
    fits = [
        least_squares_fit(dataset, choice, free, start=start, fresh_columns=fresh, initial_jacobian=init,
            max_nfev=CANDIDATE_MAX_NFEV, with_uncertainty=with_uncertainty)
        for _, start in starts
    ]
    valid = [r for r in fits if not r.misses_most_slips and math.isfinite(r.error)]
    result = min(valid or fits, key=lambda r: r.error)
    result.n_evaluations = sum(r.n_evaluations for r in fits)
    if (result.error > base.error or not valid) and offs:
        # nothing better than leaving the effect off, or every end misses most of the slips (a
        # trap, not a fit: identify.MAX_MISSING_FRACTION): report the base model, effect off
        result = _switched_off(base, choice, offs, result.free, result.n_evaluations, SWITCHED_OFF)
    return result


def _switched_off(base: FitResult, choice: ModelChoice, offs: Mapping[str, float],
                  free: tuple[str, ...], n_evaluations: int, message: str) -> FitResult:
    """The base model reported as the candidate's fit, its effect switched off."""
    return FitResult(
        choice=choice.with_values({**dict(base.choice.values), **offs}), error=base.error,
        feature_error=dict(base.feature_error), free=free, n_evaluations=n_evaluations,
        message=message,
    )
