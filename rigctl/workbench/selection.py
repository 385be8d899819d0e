"""Which effects a model needs: forward selection and backward elimination over one search.

(``diagnose --auto``: :mod:`rigctl.workbench.auto`. docs/identification.md, "Choosing the effects".)

The candidates of a step are *effect sets*: every library effect (and plug-in) the model lacks on
its own, and pairs of them. A pair is the same kind of candidate as a single effect, fitted by the
same search and judged by the same rule; it exists because two effects can each leave most of a
joint signature unexplained (each alone is not significant) while together they are.

One step:

1. **Screen** every single effect (``screen``: the score screen of :mod:`rigctl.workbench.
   screening`, about one Jacobian per set, or short fits, :func:`by_short_fits`: the same search on
   a small budget). The screened error ranks the candidates.
2. **Gate** (:func:`gate`): of the best ``SCREEN_KEEP`` singles those whose screened error is
   significant against the model by the rule below go on (:func:`promising`): a set's screened
   error is that of a point the screen evaluated, so it is about what the full fit reaches at
   worst. Free places among the SCREEN_KEEP then go to singles whose *score statistic* is
   significant (:func:`score_significant`: the score test, chi-square at SCORE_ALPHA over the
   step's singles), strongest first: a significant slope at the effect's off values is evidence
   that the data contain its direction even where no screened point shows a significant gain (the
   gain lies beyond the linear re-fit of the base, which the full fit is not limited to).
3. **Fit** those singles fully (``fit``), each also from the point where its screen found its
   error (so a fit does not end worse than what the screen saw), and score each against the model
   (:func:`~rigctl.workbench.ranking.score_candidate`: delta BIC with the slip events as the
   samples, at least 10 % of the error, E^2 down by 0.5).
4. **Pairs** (:func:`pair_sets`) of the best ``PAIR_POOL`` screened singles are screened the same
   way, but not those holding the best significant single: a pair holding it is added only where
   it is significant against it (rule 5), which is the question the next step asks of its partner
   with that single in the model, by the partner's own screen and fit. Of the best SCREEN_KEEP
   pairs, those whose screened error is significant against what a pair must beat (the best
   significant single, with the parameters the pair has beyond it; the model where no single is
   significant) are fitted fully (:func:`worth_fitting`). Where no single or pair passes, the step
   ends there.
5. **Add** the best significant single; a pair instead only where it is significant against that
   single (or against the model, where no single is): forward selection takes two effects at once
   only where the data demand both.
6. **Or say the data cannot decide**: where another significant set, not nested in the chosen one
   nor containing it, is within INDISTINGUISHABLE_DELTA_BIC (6, "strong" evidence on Kass &
   Raftery's scale, the ranking's rule) of the chosen set's delta BIC, the data do not tell them
   apart. Nothing is added, and the step's contenders are reported as indistinguishable with the
   runs that would reveal each (:attr:`Round.undecided`). A nested set is no contender: between an
   effect and a pair containing it, the pair rule of 5 decides.

Steps repeat until nothing is significant, the data cannot decide (or ``max_steps``). Then
**backward elimination**: each effect of the final model is refitted out (the model without it,
from the final values and from the values the model had before the effect was added, the later
effects at their final values: :func:`before_added`); an effect whose removal is not
significantly worse by the same rule goes, the weakest first, until every effect left earns its
place. Forward and backward use one rule, so a model the procedure returns is one from which no
single addition or removal is significant.

Everything that fits or screens is injected (``fit``: ``(dataset, choice, starts=) ->
FitResult``; ``screen``: ``(dataset, model, sets) -> [Screened]``), so the procedure is
independent of how one model is identified (:mod:`rigctl.workbench.search`).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Protocol

from scipy.stats import chi2

from rigctl.records.dataset import Dataset
from rigctl.workbench.budget import SearchCancelledError
from rigctl.workbench.identify import FitResult
from rigctl.workbench.model_choice import (
    ModelChoice,
    effect_class,
    effect_of,
    with_effects,
    without_effect,
    without_effects,
)
from rigctl.workbench.ranking import INDISTINGUISHABLE_DELTA_BIC, CandidateScore, score_candidate
from rigctl.workbench.round_eta import RoundClock
from rigctl.workbench.run_deadline import RunDeadline
from rigctl.workbench.screening import Screened


class FitFn(Protocol):
    """Identify one model on a dataset: its current values are the search's start, ``starts``
    the same model at other values (a screen's best point) are more; ``max_wall_s``: the fit's
    share of the run's time (:class:`~rigctl.workbench.run_deadline.RunDeadline`), None: no
    share."""

    def __call__(self, dataset: Dataset, choice: ModelChoice, /, *,
                 starts: Sequence[ModelChoice] = (),
                 max_wall_s: float | None = None) -> FitResult: ...


ScreenFn = Callable[[Dataset, FitResult, Sequence[tuple[str, ...]]], list[Screened]]
"""Screen effect sets added to a fitted model: each set's screen (its error and best point), best
first."""
ShortFitFn = Callable[[Dataset, ModelChoice], FitResult]
"""A short fit of one model (:func:`by_short_fits`)."""
ErrorFn = Callable[[Dataset, ModelChoice], float]
"""The error of one model on a dataset at its values (one evaluation, no fit)."""
Say = Callable[[str], None]

SCREEN_KEEP = 3
"""Singles (and pairs) a screen passes to the full fit. A screen ranks candidates with the noise
of an unfinished search (a short fit) or of a linear re-fit (the score screen); the candidate that a
full fit would rank first is among the first three of the screen unless the screen's errors differ
by less than their own spread, which keeping three allows for at a third of the cost of fitting
everything."""
PAIR_POOL = 4
"""Pairs are formed from the best this many screened singles (six pairs): an effect of an
interacting pair still lowers the error alone, if less than significantly, and so ranks near the
top of the singles' screen."""
SCORE_ALPHA = 0.01
"""The score gate's false-alarm probability per step, over all its singles (Bonferroni: each
single's score is tested at SCORE_ALPHA / their number). The residual is in units of the measured
scatter with each feature weighted by the inverse of its block count, so on a model right up to
noise the score statistic of k coordinates is at most chi-square with k degrees of freedom (its
weights are at most 1, and the prior's damping only lowers it): a step of a right model sends a set
to a full fit by its score once in a hundred. A false alarm costs a full fit's time, never a wrong
effect: the fit is judged by the same rule as every other."""
MAX_STEPS = 5
"""Forward steps at most (each adds one or two effects): bounds the run time on data that keep
rewarding more parameters."""


@dataclass(frozen=True)
class Trial:
    """One candidate set fitted on a model: its fit and its evidence against that model."""

    effects: tuple[str, ...]
    fit: FitResult
    score: CandidateScore
    screened_error: float
    """The screened error (the screen's ranking)."""

    @property
    def name(self) -> str:
        return " + ".join(self.effects)


@dataclass(frozen=True)
class Step:
    """One change of the model: effects added (forward) or removed (backward)."""

    kind: str
    """``add``, ``remove``, or ``refit`` (the model itself fitted better, no effect changed)."""
    effects: tuple[str, ...]
    error_before: float
    error_after: float
    delta_bic: float
    model: FitResult


@dataclass(frozen=True)
class Round:
    """One forward step's evidence: the model it started from, every screen (singles and pairs,
    best first), the sets fitted fully (none where no screen was significant) and the set added
    (None: nothing significant, the data cannot decide, or the model refitted and the step
    repeated)."""

    model: FitResult
    screens: list[Screened]
    trials: list[Trial]
    chosen: Trial | None
    undecided: tuple[Trial, ...] = ()
    """The sets the data cannot tell apart (module docstring, 6), best first; empty otherwise."""


@dataclass
class Selection:
    """The outcome: the model at each step, and every round's evidence (the ranking tables)."""

    base: FitResult
    final: FitResult
    steps: list[Step] = field(default_factory=list)
    rounds: list[Round] = field(default_factory=list)
    time_limited: str = ""
    """Where the run's time limit ended the selection (empty: it ran to its end)."""


def _score(name: str, base: FitResult, cand: FitResult, n_events: int) -> CandidateScore:
    return score_candidate(name, base.error, cand.error, n_events, cand.n_params - base.n_params)


def _finite(e: float) -> float:
    return e if math.isfinite(e) else math.inf


def screen_sets(
    dataset: Dataset, model: FitResult, sets: Sequence[tuple[str, ...]], *, screen: ShortFitFn,
    say: Say = lambda _m: None,
) -> list[Screened]:
    """Each effect set added to ``model`` and fitted by the short fit ``screen``: the sets'
    screens (error, and the short fit's end as the full fit's start), best first (a fit that fails
    ranks last). The first SCREEN_KEEP are the ones a forward step fits fully."""

    def short(effects: tuple[str, ...]) -> Screened:
        res = screen(dataset, with_effects(model.choice, effects))
        say(f"  screened {' + '.join(effects)}: {res.error:.3g}")
        return Screened(effects, _finite(res.error), 0.0, res.n_evaluations, "short fit",
                        res.choice if math.isfinite(res.error) else None)

    return sorted((short(s) for s in sets), key=lambda s: s.error)


def by_short_fits(short_fit: ShortFitFn, say: Say = lambda _m: None) -> ScreenFn:
    """A screen that fits each set with ``short_fit`` (:func:`screen_sets`)."""
    return lambda dataset, model, sets: screen_sets(dataset, model, sets, screen=short_fit,
                                                    say=say)


def promising(model: FitResult, s: Screened, n_events: int) -> bool:
    """Whether the screened set ``s`` is significant against ``model`` by the rule a fit is
    judged by.

    A set's screened error is what a point the screen evaluated adds to the model's own linear
    re-fit (:func:`~rigctl.workbench.screening.screened_error`), and the set's full fit starts
    there: it is about what the fit reaches at worst. A set that does
    not screen significant would need its full fit to find a gain none of the screen's points
    shows (an effect whose gain lies outside its plausible ranges, or that needs the base to move
    far from the model): that is the screen's miss, and such a set is not fitted."""
    return math.isfinite(s.error) and score_candidate(
        " + ".join(s.effects), model.error, s.error, n_events,
        added_parameters(model, s)).significant


def score_significant(s: Screened, n_sets: int) -> bool:
    """Whether the score statistic of ``s`` is significant: its chi-square tail probability with
    the score's degrees of freedom is below SCORE_ALPHA / ``n_sets`` (the score test, Rao 1948;
    Seber & Wild, *Nonlinear Regression*, 1989, sec. 5.9)."""
    return s.score_df > 0 and math.isfinite(s.error) and \
        float(chi2.sf(s.score, s.score_df)) < SCORE_ALPHA / max(n_sets, 1)


def gate(model: FitResult, singles: Sequence[Screened], n_events: int) -> list[Screened]:
    """The screened singles a step fits fully (module docstring, 2): of the first SCREEN_KEEP
    those :func:`promising`, then, in the free places among SCREEN_KEEP, the singles whose score
    is significant (:func:`score_significant`), the smallest tail probability first."""
    kept = [s for s in singles[:SCREEN_KEEP] if promising(model, s, n_events)]
    chosen = {s.effects for s in kept}
    by_score = sorted((s for s in singles
                       if s.effects not in chosen and score_significant(s, len(singles))),
                      key=lambda s: float(chi2.logsf(s.score, s.score_df)))
    return kept + by_score[:SCREEN_KEEP - len(kept)]


def pair_sets(singles: Sequence[Screened], best: Trial | None) -> list[tuple[str, ...]]:
    """The pairs a step screens (module docstring, 4): of the best PAIR_POOL screened singles,
    every two, but not those holding the step's best significant single ``best``."""
    lead = [s.effects[0] for s in singles[:PAIR_POOL]]
    return [tuple(sorted((a, b))) for a, b in itertools.combinations(lead, 2)
            if best is None or best.effects[0] not in (a, b)]


def worth_fitting(model: FitResult, best: Trial | None, pairs: Sequence[Screened],
                  n_events: int, say: Say = lambda _m: None) -> list[Screened]:
    """Of the first SCREEN_KEEP screened ``pairs`` those whose screened error is significant
    against what a pair must beat to be added (module docstring, 5): the step's best significant
    single ``best`` (with the parameters the pair has beyond it), or the model where no single is
    significant (:func:`promising`)."""
    if best is None:
        return [p for p in pairs[:SCREEN_KEEP] if promising(model, p, n_events)]
    out: list[Screened] = []
    for p in pairs[:SCREEN_KEEP]:
        extra = added_parameters(model, p) - effect_parameters(model, best.effects)
        sc = score_candidate(" + ".join(p.effects), best.fit.error, p.error, n_events, extra)
        if math.isfinite(p.error) and sc.significant:
            out.append(p)
        else:
            say(f"  {' + '.join(p.effects)}: screened {p.error:.3g}, not significant against "
                f"{best.name} ({best.fit.error:.3g}): not fitted")
    return out


def added_parameters(model: FitResult, s: Screened) -> int:
    """Parameters the screened set adds to ``model``: its effects' identified parameters (at least
    one each), the count a screen is judged with."""
    return effect_parameters(model, s.effects)


def effect_parameters(model: FitResult, effects: Sequence[str]) -> int:
    """The identified parameters of ``effects`` (at least one each) as ``model``'s files define
    them (:func:`added_parameters`)."""
    n = 0
    for effect in effects:
        cls = effect_class(effect, model.choice.effect_files)
        n += max(1, sum(1 for p in cls.params if p.identify)) if cls is not None else 1
    return n


def forward_step(
    dataset: Dataset, model: FitResult, pool: Sequence[str], *, fit: FitFn, screen: ScreenFn,
    say: Say, deadline: RunDeadline | None = None, error_of: ErrorFn | None = None,
) -> tuple[Trial | None, list[Trial], list[Screened]]:
    """One forward step from ``model``: the set to add (None: nothing significant), the trials
    (none where no screened set passes its gate) and every screen. With ``deadline``,
    each fit gets its share of the run's time left (:meth:`RunDeadline.share_s`); with
    ``error_of``, each single is judged at the best point known for it (:func:`best_known`)."""
    n = dataset.n_events
    singles = screen(dataset, model, [(c,) for c in pool])
    trials = _fit_sets(dataset, model, gate(model, singles, n), fit=fit, say=say,
                       deadline=deadline, fits_after=SCREEN_KEEP)
    best = _best_significant(trials)
    pairs = screen(dataset, model, pair_sets(singles, best))
    trials += _fit_sets(dataset, model, worth_fitting(model, best, pairs, n, say), fit=fit,
                        say=say, deadline=deadline)
    screens = sorted([*singles, *pairs], key=lambda s: s.error)
    if not trials:
        say(f"  no screened set is significant against {model.choice.label()} by its error "
            f"or its score ({model.error:.3g}; best {screens[0].error:.3g})" if screens else
            "  nothing to screen")
        return None, [], screens
    if error_of is not None:
        trials = best_known(dataset, model, trials, error_of=error_of, say=say)
    trials.sort(key=lambda t: _finite(t.fit.error))
    best_single = next((t for t in trials if len(t.effects) == 1 and t.score.significant), None)
    best_pair = next((t for t in trials if len(t.effects) == 2 and t.score.significant), None)
    if best_pair is not None:
        against = best_single.fit if best_single is not None else model
        if _score(best_pair.name, against, best_pair.fit, n).significant:
            return best_pair, trials, screens
    return best_single, trials, screens


def _fit_sets(
    dataset: Dataset, model: FitResult, sets: Sequence[Screened], *, fit: FitFn, say: Say,
    deadline: RunDeadline | None, fits_after: int = 0,
) -> list[Trial]:
    """Each screened set of ``sets`` fitted fully on ``model`` (also from its screen's point),
    as trials; each fit's share of the run's time left counts the ``fits_after`` that may follow
    these."""
    n = dataset.n_events
    trials: list[Trial] = []
    clock = RoundClock([1.0] * len(sets))
    for i, s in enumerate(sets):
        name = " + ".join(s.effects)
        if not promising(model, s, n):
            say(f"  {name}: its screened error is not significant, its score "
                f"is ({s.score:.3g}, {s.score_df} coordinates): fitted fully")
        res = fit(dataset, with_effects(model.choice, s.effects),
                  starts=() if s.start is None else (s.start,),
                  max_wall_s=_share(deadline, len(sets) - i + fits_after))
        took = f" in {res.elapsed_s:.0f} s" if res.elapsed_s > 0.0 else ""
        say(f"  fitted {name}: {model.error:.3g} -> {res.error:.3g}{took} {clock.finished(i)}")
        trials.append(Trial(s.effects, res, _score(name, model, res, n), s.error))
    return trials


def _best_significant(trials: Sequence[Trial]) -> Trial | None:
    """The significant trial of lowest error (None where none is significant)."""
    return min((t for t in trials if t.score.significant),
               key=lambda t: _finite(t.fit.error), default=None)


def best_known(dataset: Dataset, model: FitResult, trials: Sequence[Trial], *,
               error_of: ErrorFn, say: Say = lambda _m: None) -> list[Trial]:
    """The trials with each single at the best point known for its model: its own fit, or a
    pair's fitted values with the pair's other effect off, where those score lower.

    A pair's fit moves its members' parameters and the model's as well as the other effect's, so
    it can find a better point for one member alone than that member's own fit reached. Two fits
    of the same model to the same data: the lower error is the better estimate, and a pair must
    not be credited with what its member's fit could have reached (the rule of
    :func:`unfinished_model`, one effect down). Costs one evaluation per pair and member."""
    n = dataset.n_events
    out: list[Trial] = []
    for t in trials:
        best = t.fit
        holding = [p for p in trials if len(t.effects) == 1 and len(p.effects) > 1
                   and t.effects[0] in p.effects and math.isfinite(p.fit.error)]
        for p in holding:
            others = [e for e in p.effects if e != t.effects[0]]
            choice = without_effects(p.fit.choice, others)
            e = error_of(dataset, choice)
            if math.isfinite(e) and e < best.error:
                best = FitResult(choice, e, {}, t.fit.free, n_evaluations=t.fit.n_evaluations,
                                 elapsed_s=t.fit.elapsed_s, cpu_s=t.fit.cpu_s,
                                 message=f"at {p.name}'s fitted values without "
                                         f"{' + '.join(others)}")
        if best is t.fit:
            out.append(t)
            continue
        say(f"  {t.name}: {t.fit.error:.3g} -> {best.error:.3g} {best.message}")
        out.append(Trial(t.effects, best, _score(t.name, model, best, n), t.screened_error))
    return out


def contenders(chosen: Trial, trials: Sequence[Trial]) -> tuple[Trial, ...]:
    """``chosen`` and the significant trials the data cannot tell from it (module docstring, 6):
    within INDISTINGUISHABLE_DELTA_BIC of its delta BIC and not nested with it; empty where there
    are none."""
    mine = set(chosen.effects)
    close = [t for t in trials if t is not chosen and t.score.significant
             and not (set(t.effects) <= mine or mine <= set(t.effects))
             and t.score.delta_bic - chosen.score.delta_bic < INDISTINGUISHABLE_DELTA_BIC]
    return (chosen, *sorted(close, key=lambda t: t.score.delta_bic)) if close else ()


def before_added(model: ModelChoice, effect: str, path: Sequence[Step],
                 base: FitResult) -> ModelChoice | None:
    """``model`` without ``effect``, its values where ``path`` (the forward steps) had them
    before ``effect`` was added: the base's and earlier effects' values from the model that
    step started from, the later effects' from ``model``. None where no step added it (an
    effect the user gave).

    An effect that takes up part of what the model's fit left moves the model's other
    parameters with it, and a later effect is fitted on those values. The same model without the
    effect, refitted only from ``model``'s values, starts where the effect put the others and
    can end short of the fit they had without it; two starts of the same model, the fit keeps
    the better."""
    at = next((i for i, s in enumerate(path) if s.kind == "add" and effect in s.effects), None)
    if at is None:
        return None
    before = path[at - 1].model.choice if at > 0 else base.choice
    rest = without_effect(model, effect)
    kept = set(rest.effects)
    return rest.with_values({k: v for k, v in before.values.items()
                             if effect_of(k) == "" or effect_of(k) in kept})


def backward_elimination(
    dataset: Dataset, model: FitResult, *, fit: FitFn, protected: Sequence[str], say: Say,
    deadline: RunDeadline | None = None, path: Sequence[Step] = (),
    base: FitResult | None = None,
) -> tuple[FitResult, list[Step]]:
    """Remove, weakest first, every effect of ``model`` (but ``protected``, the user's) whose
    removal is not significantly worse (each fit at its share of ``deadline``'s time left).
    With ``path`` (the forward steps from ``base``), each removal's fit also starts from the
    values the model had before the effect was added (:func:`before_added`)."""
    steps: list[Step] = []
    while True:
        outs: list[tuple[str, FitResult, CandidateScore]] = []
        removable = [e for e in model.choice.effects if e not in protected]
        clock = RoundClock([1.0] * len(removable))
        for i, effect in enumerate(removable):
            earlier = None if base is None else before_added(model.choice, effect, path, base)
            try:
                rest = fit(dataset, without_effect(model.choice, effect),
                           starts=() if earlier is None else (earlier,),
                           max_wall_s=_share(deadline, len(removable) - i))
            except SearchCancelledError:
                if not _time_is_up(deadline):
                    raise
                return model, steps  # the removals so far stand; the caller says the rest
            outs.append((effect, rest, _score(effect, rest, model, dataset.n_events)))
            say(f"  without {effect}: {rest.error:.3g} (with it {model.error:.3g}) "
                f"{clock.finished(i)}")
        weak = [o for o in outs if not o[2].significant]
        if not weak:
            return model, steps
        effect, rest, sc = max(weak, key=lambda o: o[2].delta_bic)
        say(f"removing {effect}: it does not earn its place ({model.error:.3g} with it, "
            f"{rest.error:.3g} without)")
        steps.append(Step("remove", (effect,), model.error, rest.error, -sc.delta_bic, rest))
        model = rest


def unfinished_model(
    dataset: Dataset, model: FitResult, trials: Sequence[Trial], *, error_of: ErrorFn,
) -> ModelChoice | None:
    """The model at a trial's fitted values with the trial's effects off, where that is
    significantly better than ``model`` (None otherwise; the best such point).

    A trial's fit moves the model's own parameters as well as the effects'; where the same model
    without the effects is significantly better at those values, the gain was the model's
    unfinished fit, not the effects, and must not be credited to them: the model is refitted from
    there and the step repeated. The rule is the one every candidate is judged by
    (:func:`~rigctl.workbench.ranking.score_candidate`, here with no extra parameter), so each
    refit lowers the error significantly and the repetitions end."""
    best: tuple[float, ModelChoice] | None = None
    for t in trials:
        if not t.fit.error < model.error:
            continue
        choice = without_effects(t.fit.choice, t.effects)
        e = error_of(dataset, choice)
        if math.isfinite(e) and (best is None or e < best[0]):
            best = (e, choice)
    if best is None:
        return None
    sc = score_candidate("refit", model.error, best[0], dataset.n_events, 0)
    return best[1] if sc.significant else None


def _share(deadline: RunDeadline | None, fits_left: int) -> float | None:
    return None if deadline is None else deadline.share_s(fits_left)


def _time_is_up(deadline: RunDeadline | None) -> bool:
    """Whether a cancelled search was stopped by the run's time limit (not by the user)."""
    return deadline is not None and deadline.expired()


def select_effects(
    dataset: Dataset, base: FitResult, pool: Sequence[str], *, fit: FitFn, screen: ScreenFn,
    max_steps: int = MAX_STEPS, say: Say = lambda _m: None, error_of: ErrorFn | None = None,
    deadline: RunDeadline | None = None,
) -> Selection:
    """Forward selection from ``base`` over ``pool``, then backward elimination (module docstring).
    Effects ``base`` already has are the user's and are never removed. With ``error_of``, a step
    whose trials show the model's own fit unfinished (:func:`unfinished_model`) refits the model
    from there (a ``refit`` step) and is repeated.

    With ``deadline`` (the run's time limit; its :attr:`~RunDeadline.cancel` is the event every
    ``fit`` and ``screen`` watches), each fit gets its share of the time left, and where the limit
    ends a step, the steps taken so far stand: the step it ended adds nothing, backward elimination
    is skipped (or ends where it was), and :attr:`Selection.time_limited` says where."""
    sel = Selection(base, base)
    try:
        model = _forward(dataset, sel, pool, fit=fit, screen=screen, max_steps=max_steps,
                         say=say, error_of=error_of, deadline=deadline)
    except SearchCancelledError:
        if not _time_is_up(deadline):
            raise
        model = sel.steps[-1].model if sel.steps else base
        sel.time_limited = (f"the run's time limit ended forward step {len(sel.rounds) + 1} "
                            "before it was judged; backward elimination was not run")
        say(f"time limit: {sel.time_limited}; the model so far is {model.choice.label()}")
        sel.final = model
        return sel
    model, removals = backward_elimination(dataset, model, fit=fit,
                                           protected=base.choice.effects, say=say,
                                           deadline=deadline, path=list(sel.steps), base=base)
    if _time_is_up(deadline):
        sel.time_limited = "the run's time limit ended backward elimination before its end"
        say(f"time limit: {sel.time_limited}")
    sel.steps += removals
    sel.final = model
    return sel


def rank_effects(
    dataset: Dataset, base: FitResult, pool: Sequence[str], *, fit: FitFn, screen: ScreenFn,
    say: Say = lambda _m: None, error_of: ErrorFn | None = None,
    deadline: RunDeadline | None = None,
) -> Selection:
    """The candidates of ``pool`` ranked on ``base`` and nothing added: one forward step (screens,
    gate, full fits, the model refitted where its trials show its own fit unfinished) whose round
    is the ranking and whose chosen set is the verdict; the final model is the one the step was
    judged against (``diagnose`` without ``--auto``). A step repeated after the model's refit
    leaves its last round only (the refit is a ``refit`` step). Where ``deadline`` ends the step,
    the selection holds no round and says so (:attr:`Selection.time_limited`)."""
    sel = Selection(base, base)
    try:
        sel.final = _forward(dataset, sel, pool, fit=fit, screen=screen, max_steps=1, say=say,
                             error_of=error_of, deadline=deadline, add=False)
        sel.rounds = sel.rounds[-1:]
    except SearchCancelledError:
        if not _time_is_up(deadline):
            raise
        sel.final = sel.steps[-1].model if sel.steps else base
        sel.rounds = []
        sel.time_limited = "the run's time limit ended the ranking before its step was judged"
        say(f"time limit: {sel.time_limited}")
    return sel


def _forward(
    dataset: Dataset, sel: Selection, pool: Sequence[str], *, fit: FitFn, screen: ScreenFn,
    max_steps: int, say: Say, error_of: ErrorFn | None, deadline: RunDeadline | None,
    add: bool = True,
) -> FitResult:
    """Forward selection into ``sel`` (its rounds and steps as they happen): the model it ends
    at. ``add`` False: each step's chosen set is its round's verdict only, never added."""
    model, pool = sel.base, list(pool)
    steps = 0
    while steps < max_steps:
        if not pool:
            break
        chosen, trials, screens = forward_step(dataset, model, pool, fit=fit, screen=screen,
                                               say=say, deadline=deadline, error_of=error_of)
        undecided = contenders(chosen, trials) if chosen is not None else ()
        again = None if error_of is None else unfinished_model(dataset, model, trials,
                                                                error_of=error_of)
        if again is not None:
            refit = fit(dataset, again, max_wall_s=_share(deadline, 1))
            if refit.error < model.error:
                sel.rounds.append(Round(model, screens, trials, None))
                say(f"{model.choice.label()} fits better from a trial's values without its "
                    f"effects: {model.error:.3g} -> {refit.error:.3g}; the step again")
                sc = score_candidate("refit", model.error, refit.error, dataset.n_events, 0)
                sel.steps.append(Step("refit", (), model.error, refit.error, sc.delta_bic, refit))
                model = refit
                continue
        steps += 1
        if undecided:
            say("  the data cannot decide between " + " and ".join(t.name for t in undecided)
                + ": nothing added")
            sel.rounds.append(Round(model, screens, trials, None, undecided))
            break
        sel.rounds.append(Round(model, screens, trials, chosen))
        if chosen is None or not add:
            break
        say(f"adding {chosen.name}: {model.error:.3g} -> {chosen.fit.error:.3g}")
        sel.steps.append(Step("add", chosen.effects, model.error, chosen.fit.error,
                              chosen.score.delta_bic, chosen.fit))
        model = chosen.fit
        pool = [c for c in pool if c not in chosen.effects]
    return model
