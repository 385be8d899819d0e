"""The automatic choice of effects: the one search, the score screen, forward selection.

:func:`auto_select` is what ``rigctl model diagnose --auto`` does on a dataset, as one call: the
model identified by :func:`~rigctl.workbench.search.search_model`, then
:func:`~rigctl.workbench.selection.select_effects` over the candidates the model lacks, each step
screened by :func:`~rigctl.workbench.screening.score_screen` and its kept sets fitted by the same
search (from the screen's best point as well), the model's own unfinished fit caught by
:func:`~rigctl.workbench.selection.unfinished_model`. docs/identification.md, "Choosing the
effects".
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable, Sequence

from rigctl.errors import SimulationError
from rigctl.model import ParameterError
from rigctl.records.dataset import Dataset
from rigctl.workbench.budget import Budget, SearchCancelledError
from rigctl.workbench.identify import FitResult, fn_range
from rigctl.workbench.model_choice import ModelChoice, candidate_effects
from rigctl.workbench.run_deadline import RunDeadline
from rigctl.workbench.screening import Screened, score_screen
from rigctl.workbench.search import search_model
from rigctl.workbench.selection import Selection, rank_effects, select_effects
from rigctl.workbench.start_error import error_or_inf

Say = Callable[[str], None]

def auto_select(
    dataset: Dataset, model: ModelChoice | FitResult, *, workers: int | None = None,
    pool: Sequence[str] | None = None, cancel: threading.Event | None = None,
    say: Say = lambda _m: None, fit_wall_s: float | None = None,
    max_run_s: float | None = None, rank_only: bool = False,
) -> Selection:
    """Identify ``model`` (unless it is a fit already) and choose its effects from ``pool``
    (default: every library and plug-in effect it lacks); ``rank_only``: rank them in one forward
    step and add nothing (:func:`~rigctl.workbench.selection.rank_effects`: ``diagnose`` without
    ``--auto``). ``cancel``, an event shared by every
    search and screen of the run, ends it when set (the search running raises
    :class:`~rigctl.workbench.budget.SearchCancelledError`); each search keeps its own default
    budget. ``fit_wall_s``: the time limit of each fit after the model's own (``--timeout``): a
    fit that reaches it ends with its best point so far, judged like any other; the model's own
    fit has none but ``max_run_s``'s (every step is judged against it). ``max_run_s``: the time
    limit of the whole run (:class:`~rigctl.workbench.run_deadline.RunDeadline`: each fit gets its
    share of the time left, the model's own fit at most half, and the selection ends with the model
    it has at the limit, :attr:`Selection.time_limited`); None: none."""
    with RunDeadline(max_run_s, cancel) as deadline:
        return _auto_select(dataset, model, workers=workers, pool=pool, deadline=deadline,
                            say=say, fit_wall_s=fit_wall_s, rank_only=rank_only)


def _limit(*limits: float | None) -> float | None:
    given = [x for x in limits if x is not None]
    return min(given) if given else None


def _auto_select(
    dataset: Dataset, model: ModelChoice | FitResult, *, workers: int | None,
    pool: Sequence[str] | None, deadline: RunDeadline, say: Say, fit_wall_s: float | None,
    rank_only: bool = False,
) -> Selection:
    cancel = deadline.cancel

    def fit(ds: Dataset, choice: ModelChoice, *, starts: Sequence[ModelChoice] = (),
            max_wall_s: float | None = None) -> FitResult:
        limit = _limit(fit_wall_s, max_wall_s)
        if limit is not None and not limit > 0.0:
            raise SearchCancelledError("the run's time limit is reached")
        try:
            res = search_model(ds, choice, workers=workers, with_uncertainty=False,
                               starts=starts, cancel=cancel, max_wall_s=limit)
        except (ParameterError, SimulationError) as exc:
            # a candidate that cannot be identified (no valid start, a plug-in term that fails)
            # is a failed trial, scored at an infinite error: it is never added, and an effect
            # whose removal cannot be fitted is kept
            say(f"  {choice.label()}: no fit ({str(exc).splitlines()[0] if str(exc) else exc})")
            return FitResult(choice, math.inf, {}, (), message=f"fit failed: {exc}")
        _say_timed_out(res, say)
        if res.time_limited and limit is not None:
            why = "(--timeout)" if limit == fit_wall_s else "(its share of the run's --max-time)"
            say(f"  {choice.label()}: its fit reached its time limit of {limit:.0f} s {why}; "
                f"its best point so far is judged")
        return res

    def screen(ds: Dataset, fitted: FitResult, sets: Sequence[tuple[str, ...]]
               ) -> list[Screened]:
        return score_screen(ds, fitted, sets, workers=workers, say=say,
                            budget=Budget(cancel_event=cancel))

    base = model if isinstance(model, FitResult) else search_model(
        dataset, model, workers=workers, with_uncertainty=False, cancel=cancel,
        max_wall_s=deadline.share_s(1))
    say(f"{base.choice.label()}: E {base.error:.3g}")
    _say_timed_out(base, say)
    if base.time_limited:
        say(f"  {base.choice.label()}: its fit reached half the run's time limit (--max-time); "
            "its best point so far is the model every step is judged against")
    fns = fn_range(dataset)
    candidates = candidate_effects(base.choice) if pool is None else list(pool)
    choose = rank_effects if rank_only else select_effects
    return choose(dataset, base, candidates, fit=fit, screen=screen, say=say,
                  error_of=lambda ds, c: error_or_inf(ds, c, fns), deadline=deadline)


def _say_timed_out(res: FitResult, say: Say) -> None:
    """Say how many of a fit's points the per-evaluation time limit stopped: the part of a search
    that depends on the machine's speed and load (rigctl.workbench.search_pool)."""
    if res.n_timed_out:
        say(f"  {res.choice.label()}: {res.n_timed_out} of its {res.n_evaluations} simulations "
            f"were stopped at the per-evaluation time limit")
