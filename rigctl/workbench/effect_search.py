"""A global search of the effects' own parameters, the rest of the model refitted from each point.

A candidate or pair fit scans an effect's parameters once, at the start, from the model it is added
to (:mod:`rigctl.workbench.fitting`); the local fit then moves them only as far as its valley goes.
Two effects fitted together can end in a valley that no local step leaves: where the valleys of an
effect parameter are separated by a ridge (the model scores worse between them until the rest of
the model is refitted), a local fit from one side never crosses it, and moving the parameter alone
to the other side looks worse. Only a refit of the whole model from a point across the ridge shows
the other valley (the case that showed it: docs/decisions.md).

:func:`refit_over_effects` therefore refits each model's free parameters (the local fit of
:func:`~rigctl.workbench.mass_search.refit_task`) from :data:`EFFECT_SEARCH_FACTORS` times each of
its effects' fitted parameters in turn, the others kept, and keeps the best end that beats the
model. A parameter at zero (an effect switched off, a signed coefficient at its origin) has no scale
to multiply and is not searched. Every point of every model is one task of
:func:`~rigctl.workbench.parallel.run_tasks`, so they fit in parallel.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

from rigctl.records.dataset import Dataset
from rigctl.workbench.identify import FitResult, fn_range, free_params
from rigctl.workbench.mass_search import RefitTask, best_end, refit_task, valid_start
from rigctl.workbench.model_choice import ModelChoice
from rigctl.workbench.parallel import run_tasks

EFFECT_SEARCH_FACTORS: tuple[float, ...] = (0.3, 3.0)
"""Multiples of an effect parameter's fitted value each refit starts from: one step of the candidate
scan's half-decade grid (:data:`~rigctl.workbench.fitting.SCAN_FACTORS`) either side, now about the
fitted value instead of the typical one - the nearest points that lie in another valley if the
fit's valley is narrower than the grid's spacing, two refits per parameter."""


def effect_points(dataset: Dataset, result: FitResult,
                  effects: Sequence[str]) -> list[tuple[str, ModelChoice]]:
    """(what was moved, the model there) for each free parameter of ``effects`` at each of
    EFFECT_SEARCH_FACTORS times its value, within its bounds (a point clipped back to the value
    itself is left out) and physically valid."""
    prefixes = tuple(f"{e}." for e in effects)
    names = [n for n in result.free if n.startswith(prefixes)]
    if not names:
        return []
    values = {p.name: p.value for p in result.choice.parameter_table()}
    fns = fn_range(dataset)
    out: list[tuple[str, ModelChoice]] = []
    for fp in free_params(result.choice, names, rig=dataset.rig):
        v0 = values[fp.name]
        if v0 == 0.0:
            continue
        for f in EFFECT_SEARCH_FACTORS:
            v = min(max(v0 * f, fp.lower), fp.upper)
            if v == v0:
                continue
            choice = valid_start(result.choice, {fp.name: v}, fns)
            if choice is not None:
                out.append((f"{fp.name} {v0:.3g} -> {v:.3g}", choice))
    return out


def refit_over_effects(
    dataset: Dataset, results: Sequence[FitResult], effects: Sequence[Sequence[str]], *,
    say: Callable[[str], None] | None = None, **run: Any,
) -> list[FitResult]:
    """Each of ``results``, or the best refit from a point of :func:`effect_points` of its
    ``effects`` where one scores better and does not miss most of the slips (module docstring).
    ``run``: :func:`~rigctl.workbench.parallel.run_tasks`'s workers, scheduler, timeout_s and
    in_process."""
    owners: list[int] = []
    moved: list[str] = []
    tasks: list[RefitTask] = []
    for i, (res, effs) in enumerate(zip(results, effects, strict=True)):
        for what, choice in effect_points(dataset, res, effs):
            owners.append(i)
            moved.append(what)
            tasks.append(RefitTask(dataset, choice, res.free))
    if not tasks:
        return list(results)
    ends = run_tasks(refit_task, tasks, **run)
    out = list(results)
    for i, res in enumerate(results):
        mine = [k for k, owner in enumerate(owners) if owner == i]
        best = best_end(res, [ends[k] for k in mine])
        label = res.choice.label()
        if best is None:
            if say is not None and mine:
                say(f"effect search of {label} ({len(mine)} points refitted): no better end than "
                    f"{res.error:.3g}")
            continue
        k = next(k for k in mine if ends[k] is best)
        if say is not None:
            say(f"effect search of {label}: refitted from {moved[k]}, error {res.error:.3g} -> "
                f"{best.error:.3g}")
        best.message = f"refitted from {moved[k]} ({res.error:.3g} before)"
        out[i] = best
    return out
