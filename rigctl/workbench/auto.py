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
from rigctl.workbench.budget import Budget
from rigctl.workbench.fitting import error_or_inf
from rigctl.workbench.identify import FitResult, fn_range
from rigctl.workbench.model_choice import ModelChoice, candidate_effects
from rigctl.workbench.screening import Screened, score_screen
from rigctl.workbench.search import search_model
from rigctl.workbench.selection import Selection, select_effects

Say = Callable[[str], None]

def auto_select(
    dataset: Dataset, model: ModelChoice | FitResult, *, workers: int | None = None,
    pool: Sequence[str] | None = None, cancel: threading.Event | None = None,
    say: Say = lambda _m: None, fit_wall_s: float | None = None,
) -> Selection:
    """Identify ``model`` (unless it is a fit already) and choose its effects from ``pool``
    (default: every library and plug-in effect it lacks). ``cancel``, an event shared by every
    search and screen of the run, ends it when set (the search running raises
    :class:`~rigctl.workbench.budget.SearchCancelledError`); each search keeps its own default
    budget. ``fit_wall_s``: the time limit of each fit after the model's own (``--timeout``): a
    fit that reaches it ends with its best point so far, judged like any other; the model's own
    fit has none (every step is judged against it)."""

    def fit(ds: Dataset, choice: ModelChoice, *, starts: Sequence[ModelChoice] = ()) -> FitResult:
        try:
            res = search_model(ds, choice, workers=workers, with_uncertainty=False,
                               starts=starts, cancel=cancel, max_wall_s=fit_wall_s)
        except (ParameterError, SimulationError) as exc:
            # a candidate that cannot be identified (no valid start, a plug-in term that fails)
            # is a failed trial, scored at an infinite error: it is never added, and an effect
            # whose removal cannot be fitted is kept
            say(f"  {choice.label()}: no fit ({str(exc).splitlines()[0] if str(exc) else exc})")
            return FitResult(choice, math.inf, {}, (), message=f"fit failed: {exc}")
        _say_timed_out(res, say)
        if res.time_limited:
            say(f"  {choice.label()}: its fit reached its time limit of {fit_wall_s:.0f} s "
                f"(--timeout); its best point so far is judged")
        return res

    def screen(ds: Dataset, fitted: FitResult, sets: Sequence[tuple[str, ...]]
               ) -> list[Screened]:
        return score_screen(ds, fitted, sets, workers=workers, say=say,
                            budget=None if cancel is None else Budget(cancel_event=cancel))

    base = model if isinstance(model, FitResult) else search_model(
        dataset, model, workers=workers, with_uncertainty=False, cancel=cancel)
    say(f"{base.choice.label()}: E {base.error:.3g}")
    _say_timed_out(base, say)
    fns = fn_range(dataset)
    candidates = candidate_effects(base.choice) if pool is None else list(pool)
    return select_effects(dataset, base, candidates, fit=fit, screen=screen, say=say,
                          error_of=lambda ds, c: error_or_inf(ds, c, fns))


def _say_timed_out(res: FitResult, say: Say) -> None:
    """Say how many of a fit's points the per-evaluation time limit stopped: the part of a search
    that depends on the machine's speed and load (rigctl.workbench.search_pool)."""
    if res.n_timed_out:
        say(f"  {res.choice.label()}: {res.n_timed_out} of its {res.n_evaluations} simulations "
            f"were stopped at the per-evaluation time limit")
