"""``diagnose --auto`` over the one search: a :class:`~rigctl.workbench.selection.Selection` told
as a :class:`~rigctl.workbench.diagnose.Diagnosis`.

:func:`diagnose_auto` runs :func:`~rigctl.workbench.auto.auto_select` (the model identified by the
one search, forward selection with the score screen, backward elimination) and gives its outcome
the shape every reader of a diagnosis knows (the CLI's table, the JSON, the HTML report, the
Workbench tab): one round per forward step, its ranking the sets fitted fully and then those only
screened; a step per effect added (a pair as two, its first effect at its own fit where it had
one), per effect removed, and the model's own refits in the step's note.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from threading import Event

from rigctl.records.dataset import Dataset, protocols_present
from rigctl.workbench.auto import auto_select
from rigctl.workbench.diagnose import Diagnosis, DiagnosisStep, Round, explain, rig_fn
from rigctl.workbench.evaluate import evaluate
from rigctl.workbench.identify import FitResult
from rigctl.workbench.interrupts import signals_raise
from rigctl.workbench.model_choice import ModelChoice, candidate_effects
from rigctl.workbench.parallel import DEFAULT_TIMEOUT_S
from rigctl.workbench.ranking import (
    CandidateScore,
    Verdict,
    VerdictKind,
    score_candidate,
    suggest_protocol,
    suggest_runs,
    unexplained_text,
)
from rigctl.workbench.residual_map import ResidualMap, discrepancies, residual_map
from rigctl.workbench.run_deadline import DEFAULT_RUN_S
from rigctl.workbench.selection import Round as SelectionRound
from rigctl.workbench.selection import Selection, Step, Trial, added_parameters

Say = Callable[[str], None]
FitListener = Callable[[str, FitResult], None]


def diagnose_auto(
    dataset: Dataset, choice: ModelChoice, *, candidates: Sequence[str] | None = None,
    workers: int | None = None, progress: Say | None = None, baseline: FitResult | None = None,
    on_fit: FitListener | None = None, cancel: Event | None = None,
    fit_wall_s: float | None = DEFAULT_TIMEOUT_S, max_run_s: float | None = DEFAULT_RUN_S,
    rank_only: bool = False,
) -> Diagnosis:
    """``choice``'s effects chosen on ``dataset`` (module docstring). ``baseline``: the model
    already identified; ``on_fit``: each fully fitted set's fit, as the rounds end; ``cancel``:
    an event that ends the run (:class:`~rigctl.workbench.budget.SearchCancelledError`);
    ``fit_wall_s``: each fit's time limit after the model's own (``--timeout``, None: none;
    :func:`~rigctl.workbench.auto.auto_select`); ``max_run_s``: the whole run's (``--max-time``,
    :class:`~rigctl.workbench.run_deadline.RunDeadline`; None: none); ``rank_only``: the
    candidates ranked in one step and nothing added (``diagnose`` without ``--auto``)."""
    say = progress or (lambda _m: None)
    pool = list(candidates) if candidates is not None else candidate_effects(choice)
    what = "ranking" if rank_only else "choosing among"
    say(f"identifying {choice.label()} on {dataset.n_events} slip events, then {what} "
        f"{len(pool)} candidate effects ...")
    with signals_raise():  # Ctrl-C and SIGTERM end the run: every pool terminated
        sel = auto_select(dataset, baseline or choice, workers=workers, pool=pool,
                          cancel=cancel, say=say, fit_wall_s=fit_wall_s, max_run_s=max_run_s,
                          rank_only=rank_only)
    if on_fit is not None:
        for rnd in sel.rounds:
            for t in rnd.trials:
                on_fit(t.name, t.fit)
    return as_diagnosis(dataset, sel)


def as_diagnosis(dataset: Dataset, sel: Selection) -> Diagnosis:
    """The selection's rounds and steps as a :class:`Diagnosis` (module docstring)."""
    diag = Diagnosis(dataset, [], protocols=protocols_present(dataset),
                     time_limited=sel.time_limited)
    diag.steps.append(DiagnosisStep(0, sel.base.choice.label(), None, sel.base.error, None))
    for step in sel.steps:
        _tell_step(diag, step, sel)
    map_of = _Maps(dataset)
    diag.rounds = [_round(dataset, r, map_of) for r in sel.rounds]
    if not diag.rounds or diag.rounds[-1].model is not sel.final:
        text = unexplained_text(None, sel.final.error, discrepancies(map_of(sel.final)))
        diag.rounds.append(Round(sel.final, [], Verdict(VerdictKind.NONE, [], None, text), {},
                                 diag.rounds[-1].discrepancies if diag.rounds else []))
    return diag


def _tell_step(diag: Diagnosis, step: Step, sel: Selection) -> None:
    n = len(diag.steps)
    label = step.model.choice.label()
    if step.kind == "refit":
        last = diag.steps[-1]
        note = (f"{last.model} fitted better from a trial's values without its effects "
                f"({step.error_before:.3g} -> {step.error_after:.3g})")
        last.note = "; ".join(filter(None, [last.note, note]))
        last.error = step.error_after
    elif step.kind == "remove":
        diag.steps.append(DiagnosisStep(
            n, label, None, step.error_after, None,
            f"removed {' + '.join(step.effects)}: without it the error is "
            f"{step.error_after:.3g}, with it {step.error_before:.3g} (not significantly worse)"))
    elif len(step.effects) == 1:
        diag.steps.append(DiagnosisStep(n, label, step.effects[0], step.error_after,
                                        step.delta_bic))
    else:
        first, second = step.effects[0], step.effects[1]
        alone = _single_trial(sel, step, first)
        diag.steps.append(DiagnosisStep(
            n, alone.fit.choice.label() if alone else label, first,
            alone.fit.error if alone else step.error_after,
            alone.score.delta_bic if alone else step.delta_bic,
            f"added with {second}" + (f": alone {alone.fit.error:.3g}" if alone else "")))
        diag.steps.append(DiagnosisStep(
            n + 1, label, second, step.error_after, step.delta_bic,
            f"together with {first}: {step.error_before:.3g} -> {step.error_after:.3g}"))


def _single_trial(sel: Selection, step: Step, effect: str) -> Trial | None:
    """The trial of ``effect`` alone in the round that added ``step``'s pair, if it was fitted."""
    for rnd in sel.rounds:
        if rnd.chosen is not None and rnd.chosen.fit is step.model:
            return next((t for t in rnd.trials if t.effects == (effect,)), None)
    return None


def _map(dataset: Dataset, model: FitResult) -> ResidualMap:
    return residual_map(dataset, evaluate(dataset, model.choice).score.comparisons)


class _Maps:
    """Each fit's residual map, evaluated once (a round's chosen fit is the next round's model)."""

    def __init__(self, dataset: Dataset) -> None:
        self.dataset = dataset
        self._maps: dict[int, tuple[FitResult, ResidualMap]] = {}

    def __call__(self, fit: FitResult) -> ResidualMap:
        hit = self._maps.get(id(fit))
        if hit is None or hit[0] is not fit:
            hit = (fit, _map(self.dataset, fit))
            self._maps[id(fit)] = hit
        return hit[1]


def _round(dataset: Dataset, rnd: SelectionRound, map_of: _Maps) -> Round:
    """One forward step as a diagnosis round: the set chosen (or the sets the data cannot tell
    apart) first, then the other fitted sets ranked by their evidence, then the sets only screened
    (never significant: a screen is no fit); the verdict the set chosen. A pair holding the chosen
    effect can show a lower delta BIC against the model than the effect alone while it is not
    significant against it (module docstring of :mod:`~rigctl.workbench.selection`, 5): the
    verdict's set leads the table so that the table and the verdict agree."""
    model, n = rnd.model, dataset.n_events
    base_map = map_of(model)
    fitted = [_trial_score(t, model, base_map, map_of) for t in rnd.trials]
    done = {t.effects for t in rnd.trials}
    screened = []
    for s in rnd.screens:
        if s.effects in done or not math.isfinite(s.error):
            continue
        sc = score_candidate(" + ".join(s.effects), model.error, s.error, n,
                             added_parameters(model, s))
        sc.significant = False
        sc.explains = f"screened only ({s.best_at}; not fitted)"
        screened.append(sc)
    lead = [t.name for t in rnd.undecided] or ([rnd.chosen.name] if rnd.chosen else [])
    ranking = sorted(fitted, key=lambda s: (lead.index(s.effect) if s.effect in lead else len(lead),
                                            not s.significant, s.delta_bic)) + screened
    base_disc = discrepancies(base_map)
    if rnd.chosen is not None:
        v = Verdict(rnd.chosen.name, [], None)
        return Round(model, ranking, v, {t.name: t.fit for t in rnd.trials}, base_disc)
    if rnd.undecided:
        names = [t.name for t in rnd.undecided]
        effects = list(dict.fromkeys(e for t in rnd.undecided for e in t.effects))
        files = model.choice.effect_files
        v = Verdict(VerdictKind.INDISTINGUISHABLE, names,
                    suggest_protocol(effects, files, protocols_present(dataset)),
                    runs=suggest_runs(effects, files, rig_fn(dataset)))
        return Round(model, ranking, v, {t.name: t.fit for t in rnd.trials}, base_disc)
    best = min(fitted, key=lambda s: s.error, default=None)
    residual = base_disc
    if best is not None and best.error < model.error:
        trial = next(t for t in rnd.trials if t.name == best.effect)
        residual = discrepancies(map_of(trial.fit))
    v = Verdict(VerdictKind.NONE, [], None, unexplained_text(best, model.error, residual))
    return Round(model, ranking, v, {t.name: t.fit for t in rnd.trials}, base_disc)


def _trial_score(t: Trial, model: FitResult, base_map: ResidualMap,
                 map_of: _Maps) -> CandidateScore:
    sc = t.score
    if t.fit.error < model.error:
        sc.explains = explain(base_map, map_of(t.fit), model, t.fit)
    else:
        sc.explains = "nothing (no improvement)"
    sc.values = {k: v for k, v in t.fit.choice.values.items()
                 if k.split(".", 1)[0] in t.effects}
    return sc
