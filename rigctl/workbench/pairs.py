"""Two effects at once, where no single one halves a misfit that stays structured.

``diagnose --auto`` adds one effect per round: the candidate that alone improves the model most.
That greedy forward step misses effects that act together: each can gain little alone from the
model's fit and much together, so neither is significant alone while the pair is.

So where the misfit stays structured (E^2 > :data:`~rigctl.workbench.ranking.STRUCTURED_E2`) and no
single candidate of the round halves it (none is significant, or the one ``--auto`` would add does
not earn its place by :func:`~rigctl.workbench.ranking.earns_its_place`), the :data:`PAIR_FIRSTS`
candidates that removed the largest fraction of their model's error alone are each continued with
every other candidate added (a :class:`~rigctl.workbench.fitting.CandidateTask` on the first one's fit). Their
fits may come from before ``diagnose`` refitted the model from a candidate's point: a first
effect's fit is a start, whatever model it began from, and a refit of the model is a new start,
not a better one for every candidate. The second effect may show nothing alone; the first must
have removed at least MIN_ERROR_REDUCTION of its model's error alone (the gain a significant
candidate must make: less shows nothing to continue from). The fit is local and the error surface
of two interacting effects is not convex, so which of the two is fitted first can decide where
the pair's fit ends (where both are among the firsts, both orders are fitted and the better kept).
The best pair is kept when it is significant against the model with both effects' parameters counted
(:func:`~rigctl.workbench.ranking.score_candidate`) after the pairs within CLOSE_FACTOR of the best
(at most MAX_CLOSE, each in its better order) were fitted on
(:func:`~rigctl.workbench.fitting.fit_on`: the pair fits are short, so their ends rank where each
fit stopped, not where it would converge) and then searched over their effects' parameters
(:func:`~rigctl.workbench.effect_search.refit_over_effects`: the candidate scan placed each effect's
parameters once, from the model it was added to, and a local fit of two effects can stay in the
valley it started in), and against the single effect ``--auto`` would otherwise add
(:func:`beats_single`); each of its effects must then earn its place in the final model like any
other (``diagnose``'s pruning). The cases that led to each rule: docs/decisions.md.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from rigctl.records.dataset import Dataset
from rigctl.workbench.effect_search import refit_over_effects
from rigctl.workbench.fitting import SWITCHED_OFF, CandidateTask, fit_candidate, fit_on
from rigctl.workbench.identify import FitResult
from rigctl.workbench.parallel import DEFAULT_TIMEOUT_S, TaskFailed, run_tasks
from rigctl.workbench.ranking import (
    MIN_ERROR_REDUCTION,
    STRUCTURED_E2,
    CandidateScore,
    earns_its_place,
    score_candidate,
)

PAIR_FIRSTS = 2
"""Candidates continued with each other one (those that removed most of their model's error alone):
with eleven candidates, 20 pair fits, about two rounds' work."""


@dataclass
class Pair:
    """Two effects fitted together: ``first`` alone (its own candidate fit), then ``second`` added."""

    first: str
    second: str
    first_fit: FitResult
    fit: FitResult
    score: CandidateScore


def wants_pairs(model: FitResult, best: CandidateScore | None) -> bool:
    """Pairs are tried where the misfit is structured and no single candidate (``best``: the one
    ``--auto`` would add, None if none is significant) halves it
    (:func:`~rigctl.workbench.ranking.earns_its_place`)."""
    if not model.error**2 > STRUCTURED_E2:
        return False
    return best is None or not earns_its_place(best.error, model.error)


def beats_single(pair: Pair, single: CandidateScore | None, single_fit: FitResult | None,
                 n_events: int) -> bool:
    """The pair is taken over the single effect ``--auto`` would add when it is significant
    against that one too, its extra parameters counted (None: no single is significant)."""
    if single is None or single_fit is None:
        return True
    return score_candidate(pair.score.effect, single.error, pair.fit.error, n_events,
                           pair.fit.n_params - single_fit.n_params).significant


Tried = Mapping[str, tuple[FitResult, float]]
"""Candidate fits by effect, each with the error of the model it was fitted on."""


def firsts(tried: Tried, n: int = PAIR_FIRSTS) -> list[str]:
    """The ``n`` candidates that removed the largest fraction of their model's error alone, of
    those that removed at least MIN_ERROR_REDUCTION of it (the gain a significant candidate must
    make): a fit that ended at or near its model's error (its effect switched off, or left where
    it started) shows nothing to continue from."""
    ok = [(-(e0 - res.error) / e0, name) for name, (res, e0) in tried.items()
          if name in res.choice.effects and math.isfinite(res.error)
          and res.error <= (1.0 - MIN_ERROR_REDUCTION) * e0
          and not res.misses_most_slips and not res.message.startswith(SWITCHED_OFF)]
    return [name for _, name in sorted(ok)[:n]]


def best_pair(
    dataset: Dataset, model: FitResult, tried: Tried, *,
    workers: int | None, scheduler: Any = None, progress: Callable[[str], None] | None = None,
    timeout_s: float = DEFAULT_TIMEOUT_S, in_process: bool = False,
    n: int = PAIR_FIRSTS,
) -> Pair | None:
    """The best significant pair of the candidates ``tried`` on this model (module docstring), or
    None. ``tried`` may hold fits on an earlier fit of the same model (before ``diagnose`` refitted
    it from a candidate's point): a first effect's fit is a start, whatever model it began from."""
    fits = {name: res for name, (res, _e0) in tried.items()}
    order = [(a, b) for a in firsts(tried, n) for b in fits if b != a]
    if not order:
        return None
    tasks = [CandidateTask(dataset, fits[a], b) for a, b in order]

    def done(i: int, res: FitResult | TaskFailed) -> None:
        if not progress:
            return
        a, b = order[i]
        if isinstance(res, TaskFailed):
            progress(f"  {a} + {b}: fit failed: {res.message.splitlines()[0]}")
        else:
            progress(f"  fitted {a} + {b}: error {res.error:.3g} (base {model.error:.3g}, "
                     f"{a} alone {fits[a].error:.3g}; {res.elapsed_s:.1f} s)")

    outcomes = run_tasks(fit_candidate, tasks, workers=workers, scheduler=scheduler,
                         on_done=done, timeout_s=timeout_s, in_process=in_process)
    found = [Pair(a, b, fits[a], res, _score(dataset, model, a, b, res))
             for (a, b), res in zip(order, outcomes, strict=True)
             if not isinstance(res, TaskFailed) and not res.misses_most_slips
             and b in res.choice.effects]
    found = sorted((p for p in found if p.score.significant), key=lambda p: p.fit.error)
    if not found:
        return None
    # the pair fits are short: their ends rank where each stopped, so those near the best are
    # fitted on before one is chosen
    close = _one_order_each([p for p in found if p.fit.error <= CLOSE_FACTOR * found[0].fit.error])
    close = close[:MAX_CLOSE]
    if progress and len(close) > 1:
        progress(f"fitting on the {len(close)} pairs within {CLOSE_FACTOR:g} times the best: "
                 f"{', '.join(p.score.effect for p in close)}")
    ends = run_tasks(_fit_on, [(dataset, p.fit) for p in close], workers=workers,
                     scheduler=scheduler, timeout_s=timeout_s, in_process=in_process)
    for p, end in zip(close, ends, strict=True):
        if isinstance(end, FitResult) and end.error < p.fit.error:
            if progress:
                progress(f"  {p.score.effect}: error {p.fit.error:.3g} -> {end.error:.3g}")
            p.fit = end
    # and searched over their effects' parameters: a local fit of two effects can stay in the
    # valley it started in (effect_search's module docstring)
    searched = refit_over_effects(dataset, [p.fit for p in close], [(p.first, p.second) for p in close],
                                  say=progress, workers=workers, scheduler=scheduler,
                                  timeout_s=timeout_s, in_process=in_process)
    for p, end in zip(close, searched, strict=True):
        p.fit = end
        p.score = _score(dataset, model, p.first, p.second, end)
    return min(close, key=lambda p: p.fit.error)


CLOSE_FACTOR = 1.5
"""Pairs whose fit ends within this factor of the best one's are fitted on before one is chosen
(a short fit still descending can end this far above where it converges). The value is tuned, not
derived (docs/decisions.md)."""
MAX_CLOSE = 3
"""At most this many pairs (each in its better order) are fitted on: a cost bound, each fit-on
refitting the whole model. The value is tuned, not derived (docs/decisions.md)."""


def _one_order_each(found: list[Pair]) -> list[Pair]:
    """The better order of each pair (``found`` sorted best first): both orders fit the same model,
    so fitting both on would spend a place of the MAX_CLOSE on a second start of one pair and could
    push another pair out of the places."""
    seen: set[frozenset[str]] = set()
    kept = []
    for p in found:
        key = frozenset((p.first, p.second))
        if key not in seen:
            seen.add(key)
            kept.append(p)
    return kept


def _score(dataset: Dataset, model: FitResult, a: str, b: str, res: FitResult) -> CandidateScore:
    return score_candidate(f"{a} + {b}", model.error, res.error, dataset.n_events,
                           res.n_params - model.n_params)


def _fit_on(task: tuple[Dataset, FitResult]) -> FitResult:
    return fit_on(*task)
