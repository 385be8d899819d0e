"""A global search of the slider mass, the other free parameters refitted at each mass.

The mass is the one parameter a local fit hardly moves on another rig's data: the drop shape, the
overshoot and the ringing are not smooth in M, and where the sampling or a filtered sensor hides
the ringing the error has valleys decades apart. Moving the mass alone from a fitted model says
little, since the friction levels and stiffnesses fitted at the old mass no longer match: a
mass in a better valley scores worse than the fitted model until the rest is refitted there (the
case that showed it: docs/decisions.md).

:func:`refit_over_mass` therefore refits the model's free parameters (a local least-squares fit of
:data:`REFIT_MAX_NFEV` evaluations) from each of
:data:`REFIT_MASS_FACTORS` times its mass (the drive damping moved with sqrt(M), keeping the damping
ratio, where it is free too) and keeps the best end that beats the model. Each point is a task of
:func:`~rigctl.workbench.parallel.run_tasks`, so they fit in parallel. It applies only where the
mass is free: not where the rig description states it, nor where the resolved ringing ties it to
the stiffnesses (:attr:`~rigctl.records.dataset.Dataset.mass_from_ringing`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from rigctl.errors import SimulationError
from rigctl.model import ParameterError
from rigctl.records.dataset import Dataset
from rigctl.workbench.identify import (
    FitResult,
    fn_range,
    free_params,
    least_squares_fit,
    physically_valid,
)
from rigctl.workbench.model_choice import ModelChoice
from rigctl.workbench.parallel import TaskFailed, run_tasks

REFIT_MASS_FACTORS: tuple[float, ...] = (0.01, 0.03, 0.1, 0.3, 3.0, 10.0)
"""Multiples of the model's mass each refit starts from, in half decades (the error's valleys in M
lie decades apart, module docstring): two decades below, one above. The asymmetry is tuned, not
derived (docs/decisions.md)."""
REFIT_MAX_NFEV = 24
"""Evaluations of each refit (the base fit's budget: each starts away from a fitted model)."""


@dataclass(frozen=True)
class RefitTask:
    """One start of a refit search (a mass point here, an effect parameter's point in
    :mod:`rigctl.workbench.effect_search`), as data for a worker."""

    dataset: Dataset
    choice: ModelChoice
    free: tuple[str, ...]


def refit_over_mass(
    dataset: Dataset, result: FitResult, *, say: Callable[[str], None] | None = None,
    **run: Any,
) -> FitResult:
    """``result``, or the best refit from another mass where one scores better and does not miss
    most of the slips (module docstring). ``run``: :func:`~rigctl.workbench.parallel.run_tasks`'s
    workers, scheduler, timeout_s and in_process."""
    if "m_kg" not in result.free:
        return result
    tasks = [RefitTask(dataset, c, result.free) for c in _mass_points(dataset, result)]
    if not tasks:
        return result
    best = best_end(result, run_tasks(refit_task, tasks, **run))
    if best is None:
        if say is not None:
            say(f"mass search of {result.choice.label()} ({len(tasks)} masses refitted): no "
                f"better end than {result.error:.3g}")
        return result
    if say is not None:
        m0, m1 = _mass(result.choice), _mass(best.choice)
        say(f"mass search of {result.choice.label()}: refitted from another mass, error "
            f"{result.error:.3g} -> {best.error:.3g} (M {m0:.3g} -> {m1:.3g} kg)")
    best.message = f"refitted from another mass ({result.error:.3g} at M = " \
                   f"{_mass(result.choice):.3g} kg)"
    return best


def best_end(result: FitResult, ends: Sequence[FitResult | TaskFailed]) -> FitResult | None:
    """The best of ``ends`` that scores better than ``result`` and does not miss most of the slips,
    or None."""
    fits = [r for r in ends if isinstance(r, FitResult) and not r.misses_most_slips
            and math.isfinite(r.error)]
    best = min(fits, key=lambda r: r.error, default=None)
    return best if best is not None and best.error < result.error else None


def _mass(choice: ModelChoice) -> float:
    return next(p.value for p in choice.parameter_table() if p.name == "m_kg")


def _mass_points(dataset: Dataset, result: FitResult) -> list[ModelChoice]:
    """The model at each of REFIT_MASS_FACTORS times its mass, within the mass's bounds and
    physically valid."""
    values = {p.name: p.value for p in result.choice.parameter_table()}
    m0 = values["m_kg"]
    c0 = values.get("c0_N_s_per_m", 0.0)
    bounds = {fp.name: (fp.lower, fp.upper)
              for fp in free_params(result.choice, list(result.free), rig=dataset.rig)}
    if "m_kg" not in bounds:  # the rig description states it
        return []
    lo, hi = bounds["m_kg"]
    fns = fn_range(dataset)
    out: list[ModelChoice] = []
    for f in REFIT_MASS_FACTORS:
        m = m0 * f
        if not lo <= m <= hi:
            continue
        trial = {"m_kg": m}
        if "c0_N_s_per_m" in bounds and c0 > 0.0:
            c_lo, c_hi = bounds["c0_N_s_per_m"]
            trial["c0_N_s_per_m"] = min(max(c0 * math.sqrt(f), c_lo), c_hi)
        choice = valid_start(result.choice, trial, fns)
        if choice is not None:
            out.append(choice)
    return out


def valid_start(choice: ModelChoice, trial: dict[str, float],
                fns: tuple[float, float]) -> ModelChoice | None:
    """``choice`` with ``trial``'s values, or None where a parameter's range refuses them or the
    model there is not physically valid (no start for a refit)."""
    try:
        moved = choice.with_values(trial)
    except ParameterError:
        return None
    return moved if physically_valid(moved, fns) else None


def refit_task(task: RefitTask) -> FitResult:
    """A local fit of ``task.free`` (REFIT_MAX_NFEV evaluations) from ``task.choice``; a start that
    cannot be run gives an end with an infinite error."""
    try:
        free = free_params(task.choice, list(task.free), rig=task.dataset.rig)
        return least_squares_fit(task.dataset, task.choice, free, max_nfev=REFIT_MAX_NFEV)
    except (SimulationError, ParameterError) as exc:  # a point that cannot be run is no end
        return FitResult(choice=task.choice, error=math.inf, feature_error={}, free=task.free,
                         message=f"not fitted: {exc}")

