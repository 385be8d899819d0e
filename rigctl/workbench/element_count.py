"""The element count N of a model whose effects spread the elements' static thresholds.

N, the number of Jenkins elements the contact is cut into (paper Sec. 5.1), is an integer no
least-squares step moves, and another rig's data do not state it. The paper model alone hardly
tells N apart: in its stable stage all elements reach their threshold together (uniform P,
docs/model.md), so N shows only in the steps of the initial stage. An effect that spreads the
thresholds over the elements (``presliding``:
:meth:`rigctl.model.effects.base.Effect.element_threshold_factors`) makes every stick ramp round
off in N steps, one per element reaching its own threshold, and there N shapes every ramp (the
figures that showed both: docs/decisions.md). So once such an effect is in the model, the model
is refitted at each count of :data:`ELEMENT_COUNTS`, then at the counts next to the best of them
(:func:`refine_counts`), and the best kept. The refits are independent and run in parallel like
the candidate fits (:mod:`rigctl.workbench.parallel`: the same workers, time limit and Dask
scheduler).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from rigctl.errors import SimulationError
from rigctl.model import ParameterError
from rigctl.model.effects import Effect
from rigctl.records.dataset import Dataset
from rigctl.workbench.identify import FitResult, free_params, least_squares_fit
from rigctl.workbench.model_choice import ModelChoice, effect_class
from rigctl.workbench.parallel import DEFAULT_TIMEOUT_S, TaskFailed, run_tasks

ELEMENT_COUNTS: tuple[int, ...] = (5, 10, 20, 40)
"""Counts tried first, a factor 2 apart (a geometric grid: the ramp's rounding goes in steps of
1/N); the best of them is then refined (REFINE_SPAN)."""
REFINE_SPAN = 0.2
"""The counts within this fraction of the best coarse count (at least one either side) are tried
next, at unit steps: with few elements one more or less changes the rounding of every stick ramp
(each step is 1/N of it). The fraction is tuned, not derived: the coarse grid's factor 2 would
call for about +-40 % (docs/decisions.md)."""
REFINE_MAX = 6
"""At most this many refinement counts, the nearest first: a cost bound (each count is a refit);
the value is tuned, not derived (docs/decisions.md)."""
MIN_GAIN = 0.1
"""Another count is taken only where it removes at least this fraction of the model's error: it gets
``max_nfev`` more evaluations than the model, which alone gains a little. Among the other counts,
each refitted alike, the lowest error wins."""
MAX_NFEV = 12
"""Least-squares evaluations of the refit at each count."""


def spreads_elements(choice: ModelChoice) -> bool:
    """Some effect of ``choice`` scales the elements' thresholds one by one."""
    for name in choice.effects:
        cls = effect_class(name, choice.effect_files)
        if cls is not None and \
                cls.element_threshold_factors is not Effect.element_threshold_factors:
            return True
    return False


@dataclass(frozen=True)
class CountTask:
    """One refit at another element count, as data (sent to a worker)."""

    dataset: Dataset
    choice: ModelChoice
    free: tuple[str, ...]
    max_nfev: int


def fit_at_count(task: CountTask) -> FitResult | TaskFailed:
    """The model of ``task`` refitted at its element count; a model that cannot be built or
    simulated at that count is a :class:`TaskFailed` with the reason."""
    try:
        free = free_params(task.choice, list(task.free))
        return least_squares_fit(task.dataset, task.choice, free, max_nfev=task.max_nfev)
    except (ParameterError, SimulationError) as exc:
        return TaskFailed(f"{type(exc).__name__}: {exc}")


def best_element_count(
    dataset: Dataset, result: FitResult, say: Callable[[str], None] = lambda _m: None,
    max_nfev: int = MAX_NFEV, *, workers: int | None = None, scheduler: Any = None,
    timeout_s: float = DEFAULT_TIMEOUT_S, in_process: bool = False,
) -> FitResult:
    """``result`` refitted at the element count that fits best, or ``result`` itself where no
    effect spreads the thresholds, the rig description fixes N, or no count gains MIN_GAIN.
    ``workers``, ``scheduler``, ``timeout_s`` and ``in_process`` as for
    :func:`rigctl.workbench.parallel.run_tasks`."""
    if "n_elements" in dataset.rig.fixed or not spreads_elements(result.choice):
        return result
    n_now = result.choice.build().n_elements
    run = {"workers": workers, "scheduler": scheduler, "timeout_s": timeout_s,
           "in_process": in_process}
    coarse = [n for n in ELEMENT_COUNTS if n != n_now]
    best = _best_of(dataset, result, result, coarse, n_now, max_nfev, say, run)
    n_best = best.choice.build().n_elements
    fine = [n for n in refine_counts(n_best) if n != n_now and n not in coarse]
    return _best_of(dataset, result, best, fine, n_now, max_nfev, say, run)


def refine_counts(n_best: int) -> list[int]:
    """The counts within REFINE_SPAN of ``n_best`` at unit steps (at least one either side), at
    most REFINE_MAX of them, the nearest first."""
    reach = max(1, int(REFINE_SPAN * n_best))
    near = sorted(range(max(1, n_best - reach), n_best + reach + 1),
                  key=lambda n: (abs(n - n_best), n))
    return [n for n in near if n != n_best][:REFINE_MAX]


def _best_of(dataset: Dataset, result: FitResult, best: FitResult, counts: list[int], n_now: int,
             max_nfev: int, say: Callable[[str], None], run: dict[str, Any]) -> FitResult:
    """``best``, or the refit of ``result`` at one of ``counts`` that removes MIN_GAIN of
    ``result``'s error and scores below ``best``: MIN_GAIN offsets the extra evaluations a count's
    refit has over ``result``, while the counts, refitted alike, are compared as equals (asking one
    to gain MIN_GAIN on another as well would keep the coarser of two good counts)."""
    tasks = [CountTask(dataset, result.choice.with_values({"n_elements": n}), tuple(result.free),
                       max_nfev) for n in counts]
    outcomes = run_tasks(fit_at_count, tasks, **run)
    for n, fit in zip(counts, outcomes, strict=True):
        if isinstance(fit, TaskFailed):
            say(f"  N = {n} elements: no fit ({fit.message.splitlines()[0]})")
            continue
        say(f"  N = {n} elements: error {fit.error:.3g} (N = {n_now}: {result.error:.3g})")
        if fit.misses_most_slips or not fit.error < min((1.0 - MIN_GAIN) * result.error,
                                                        best.error):
            continue
        best = fit
    return best
