"""Learn what is missing: fit every candidate effect, rank by evidence, optionally add and repeat.

:func:`diagnose` identifies the model on the campaign, fits base + each candidate effect in parallel
(:mod:`rigctl.workbench.parallel`), ranks them (:mod:`rigctl.workbench.ranking`) and explains each
by the residual structure it removes (:mod:`rigctl.workbench.residual_map`). With ``auto`` the best
significant effect is added, the model re-identified, and the round repeated until nothing
significant is left; every step's error is kept for the error-fall chart.
"""

from __future__ import annotations

import contextlib
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from rigctl.errors import SimulationError
from rigctl.model import MAX_NORMAL_FORCE_N, ParameterError
from rigctl.records.dataset import Dataset, protocols_present
from rigctl.records.drive_profile import DriveProfile
from rigctl.records.feature_info import FEATURES
from rigctl.workbench.element_count import best_element_count
from rigctl.workbench.evaluate import evaluate, simulate_run
from rigctl.workbench.fitting import (
    FIT_ON_NFEV,
    CandidateTask,
    error_or_inf,
    fit_candidate,
    fit_on,
    identify_model,
)
from rigctl.workbench.identify import (
    FitResult,
    fn_range,
    free_params,
    least_squares_fit,
    physically_valid,
    with_uncertainties,
)
from rigctl.workbench.mass_search import refit_over_mass
from rigctl.workbench.model_choice import ModelChoice, candidate_effects, without_effect
from rigctl.workbench.pairs import Pair, beats_single, best_pair, wants_pairs
from rigctl.workbench.pairs import firsts as pair_firsts
from rigctl.workbench.parallel import DEFAULT_TIMEOUT_S, TaskFailed, default_workers, run_tasks
from rigctl.workbench.ranking import (
    MIN_ERROR_REDUCTION,
    CandidateScore,
    Verdict,
    VerdictKind,
    earns_its_place,
    excess_error,
    rank,
    score_candidate,
    suggest_runs,
    unexplained_text,
    verdict,
)
from rigctl.workbench.residual_map import (
    COVARIATE_NAMES,
    ResidualMap,
    discrepancies,
    residual_map,
    significant_trends,
)
from rigctl.workbench.round_eta import RoundClock

MAX_BASE_RESTARTS = 2
"""Times a round is run again from a better fit of its own model (:func:`better_model`)."""
MAX_AUTO_STEPS = 5  # rounds of --auto at most: each adds one effect, and this bounds its run time
PRUNE_MAX_NFEV = FIT_ON_NFEV
"""Least-squares evaluations of the refit without an effect when checking that it earns its place
(one pass of the final model's polishing, :func:`polish`)."""
COST_PROBE_S = 30.0  # seconds of the first run each candidate is timed on (several cycles)
Progress = Callable[[str], None]
FitListener = Callable[[str, FitResult], None]
"""``on_fit(candidate, fit)``: a candidate's fit as it arrives (:func:`run_round`)."""


@dataclass
class Round:
    """One diagnosis round: a model and its ranked candidates."""

    model: FitResult
    ranking: list[CandidateScore]
    verdict: Verdict
    fits: dict[str, FitResult]
    discrepancies: list[str]


@dataclass
class DiagnosisStep:
    index: int
    model: str
    added: str | None
    error: float
    delta_bic: float | None
    note: str = ""

    def to_json(self) -> dict[str, Any]:
        return {"step": self.index, "model": self.model, "added": self.added,
                "error": self.error, "delta_bic": self.delta_bic, "note": self.note}


@dataclass
class Diagnosis:
    dataset: Dataset
    rounds: list[Round]
    steps: list[DiagnosisStep] = field(default_factory=list)
    protocols: list[str] = field(default_factory=list)

    @property
    def first(self) -> Round:
        return self.rounds[0]

    @property
    def final_model(self) -> FitResult:
        return self.rounds[-1].model

    def to_json(self, include_steps: bool) -> dict[str, Any]:
        r0 = self.first
        out: dict[str, Any] = {
            "base": r0.model.choice.label(),
            "baseline_error": r0.model.error,
            "n_events": self.dataset.n_events,
            "ranking": [s.to_json() for s in r0.ranking],
            "verdict": r0.verdict.verdict,
            "candidates": r0.verdict.candidates,
            "suggest": r0.verdict.suggest,
            "suggest_runs": r0.verdict.runs,
            "unexplained": r0.verdict.unexplained,
            "discrepancies": r0.discrepancies,
            "protocols_present": self.protocols,
            "notes": list(self.dataset.notes),
        }
        if include_steps:
            out["steps"] = [s.to_json() for s in self.steps]
            out["final_model"] = self.final_model.choice.label()
            out["final_error"] = self.final_model.error
            out["final_unexplained"] = self.rounds[-1].verdict.unexplained
        return out


def explain(base_map: ResidualMap, cand_map: ResidualMap,
            base_fit: FitResult, cand_fit: FitResult) -> str:
    """What the candidate fixes, in words: preferably the covariate trend of the base model's
    residual it removes (at least half of it), else the feature whose error falls most."""
    cand_amp = {(t.feature, t.covariate): t.amplitude_z for t in cand_map.trends}
    best: tuple[float, str] | None = None
    for tr in significant_trends(base_map):
        after = cand_amp.get((tr.feature, tr.covariate), 0.0)
        frac = (tr.amplitude_z - after) / tr.amplitude_z
        if frac < 0.5:
            continue
        cov = ("log " if tr.log else "") + COVARIATE_NAMES[tr.covariate]
        text = f"{FEATURES[tr.feature].phrase} vs {cov} (trend {frac:.0%} removed)"
        score = tr.amplitude_z * frac
        if best is None or score > best[0]:
            best = (score, text)
    if best is not None:
        return best[1]
    feat_gain = [
        (base_fit.feature_error[k] - cand_fit.feature_error.get(k, math.inf), k)
        for k in base_fit.feature_error
    ]
    feat_gain = [g for g in feat_gain if math.isfinite(g[0]) and g[0] > 0]
    if feat_gain:
        _, k = max(feat_gain)
        return (f"{FEATURES[k].phrase} (error {base_fit.feature_error[k]:.1f} -> "
                f"{cand_fit.feature_error[k]:.1f})")
    return "nothing (no residual structure removed)"


def polish(dataset: Dataset, result: FitResult, say: Progress = lambda _m: None,
           **run: Any) -> FitResult:
    """The final model of ``--auto`` fitted on while it still gains (:func:`~rigctl.workbench.
    fitting.fit_on`: passes of the budget of each refit without an effect that it is then compared
    with), then searched over the slider mass (:func:`~rigctl.workbench.mass_search.
    refit_over_mass`, with ``run``'s workers). The candidate fits that chose each effect are short
    (a dozen candidates per round), so the model with all its effects may stop short of its
    minimum while the refit without one starts from there."""
    best = refit_over_mass(dataset, fit_on(dataset, result), say=say, **run)
    # uncertainties once, at the end values: a further fit would be one more pass
    return result if best is result else with_uncertainties(dataset, best)


def refine(dataset: Dataset, result: FitResult) -> FitResult:
    """Re-identify a chosen model with a fresh Jacobian (for uncertainties and the next round)."""
    return refit(dataset, result.choice, result.free)


def refit(dataset: Dataset, choice: ModelChoice, free_names: Sequence[str]) -> FitResult:
    """A short least-squares fit of ``free_names`` from ``choice``'s values, with uncertainties."""
    free = free_params(choice, list(free_names))
    return least_squares_fit(dataset, choice, free, max_nfev=8, with_uncertainty=True)


def better_model(dataset: Dataset, model: FitResult, fits: dict[str, FitResult]) -> FitResult | None:
    """The round's model fitted better, from a candidate's fit with the candidate removed, or None.

    A candidate fit re-reads the friction and stiffness levels at each scan point and takes
    Gauss-Newton steps of the model's own parameters from there (:mod:`rigctl.workbench.fitting`),
    so it may find a better point for them than the model's own fit reached. If the candidate's
    fitted values *without* the candidate beat the model by MIN_ERROR_REDUCTION or more, the
    candidate's gain was the model's unfinished fit, not the effect (the gain of a term must not be
    credited with what any fit of the model itself could reach): the model is refitted from the best
    such point and the round must be run again (history: docs/decisions.md)."""
    fns = fn_range(dataset)
    best: tuple[float, str] | None = None
    for name, res in fits.items():
        if not res.error < model.error or name not in res.choice.effects:
            continue
        e = error_or_inf(dataset, without_effect(res.choice, name), fns)
        if e <= (1.0 - MIN_ERROR_REDUCTION) * model.error and (best is None or e < best[0]):
            best = (e, name)
    if best is None:
        return None
    again = refit(dataset, without_effect(fits[best[1]].choice, best[1]), model.free)
    again.message = f"refitted from {best[1]}'s fit without it ({model.error:.3g} -> {again.error:.3g})"
    return again if again.error < model.error else None


def keep_better(res: FitResult | TaskFailed, before: FitResult | None) -> FitResult | TaskFailed:
    """The candidate's fit from this round, or its fit from before the model was refitted where
    that one is better (a refitted model is a new start, not a better one for every candidate)."""
    if before is None or before.misses_most_slips or not math.isfinite(before.error):
        return res
    if isinstance(res, TaskFailed) or before.error < res.error:
        kept = replace(before)
        kept.message = "; ".join(filter(None, [before.message, "kept from before the refit"]))
        return kept
    return res


def cost_order(
    dataset: Dataset, model: FitResult, candidates: Sequence[str]
) -> tuple[list[str], list[float]]:
    """Candidates, slowest to simulate first (so parallel workers finish together), with their
    simulation times: each is timed on the first COST_PROBE_S of the first run (long enough for
    the slow integration paths - a nonlinear slip law, a state variable - to show over the fixed
    costs). A candidate that cannot be simulated at its starting values (not physically valid on
    the model, or refused) is given the largest time measured: its fit starts elsewhere and may be
    as slow as any, and the time limit of :func:`rigctl.workbench.parallel.run_tasks` scales with
    the cost (timed at ~0 s it would get only the limit's floor, however long its fit needs). Each
    probe has the slip budget of its own length
    (:func:`~rigctl.workbench.evaluate.slip_budget`), so a chattering candidate stops early."""
    run = dataset.runs[0]
    # the probe's own length sets its slip budget (evaluate.slip_budget), not the whole run's
    n_probe = min(run.n_samples, math.ceil(COST_PROBE_S * run.sample_rate_hz) + 1)
    short = replace(run, drive=_truncate(run.drive, COST_PROBE_S), n_samples=n_probe)
    costs: list[float | None] = []
    fns = fn_range(dataset)
    for name in candidates:
        t0 = time.perf_counter()
        choice = model.choice.with_effect(name)
        cost: float | None = None
        if physically_valid(choice, fns):
            with contextlib.suppress(ValueError):
                simulate_run(choice.build(), short, bounded=True)
                cost = time.perf_counter() - t0
        costs.append(cost)
    timed = [c for c in costs if c is not None]
    fallback = max(timed) if timed else 1.0
    filled = [fallback if c is None else c for c in costs]
    order = sorted(range(len(candidates)), key=lambda i: -filled[i])
    return [candidates[i] for i in order], [filled[i] for i in order]


def _truncate(drive: DriveProfile, t_end_s: float) -> DriveProfile:
    t_end_s = min(t_end_s, float(drive.t_s[-1]))
    keep = drive.t_s < t_end_s
    t = np.append(drive.t_s[keep], t_end_s)
    x = np.interp(t, drive.t_s, drive.x_stage_m)
    f = np.interp(t, drive.t_s, drive.fn_N)
    return replace(drive, t_s=t, x_stage_m=x, fn_N=f)


def run_round(
    dataset: Dataset, model: FitResult, candidates: Sequence[str], *, workers: int | None,
    scheduler: Any, progress: Progress | None, timeout_s: float = DEFAULT_TIMEOUT_S,
    in_process: bool = False, carried: Mapping[str, FitResult] | None = None,
    on_fit: FitListener | None = None,
) -> Round:
    """Fit every candidate on ``model`` and rank them. ``carried`` holds candidate fits of the
    same round before the model was refitted (:func:`better_model`): where one of them reached a
    lower error than its fit from the new model, it is kept (the candidate's error is that of a
    full model on the same data, whatever point its fit started from). ``on_fit`` is called with
    each candidate's fit as it arrives (the GUI shows a plug-in's values during the round)."""
    candidates, costs = cost_order(dataset, model, candidates)
    tasks = [CandidateTask(dataset, model, c) for c in candidates]
    clock = RoundClock(costs)

    def done(i: int, res: FitResult | TaskFailed) -> None:
        if on_fit is not None:
            fit = keep_better(res, (carried or {}).get(candidates[i]))
            if isinstance(fit, FitResult):
                on_fit(candidates[i], fit)
        if not progress:
            return
        where = clock.finished(i)
        kept = keep_better(res, (carried or {}).get(candidates[i]))
        keeps = (f"; keeps its fit from before the refit, error {kept.error:.3g}"
                 if isinstance(kept, FitResult) and kept is not res else "")
        if isinstance(res, TaskFailed):
            progress(f"  {candidates[i]}: fit failed: {res.message.splitlines()[0]}{keeps} "
                     f"{where}")
        else:
            progress(f"  fitted {candidates[i]}: error {res.error:.3g} "
                     f"(base {model.error:.3g}; {res.n_evaluations} simulations, "
                     f"{res.elapsed_s:.1f} s, {res.cpu_s:.1f} CPU s){keeps} {where}")

    outcomes = run_tasks(fit_candidate, tasks, workers=workers, scheduler=scheduler,
                         on_done=done, timeout_s=timeout_s, in_process=in_process,
                         costs=costs)
    base_map = residual_map(dataset, evaluate(dataset, model.choice).score.comparisons)
    scores: list[CandidateScore] = []
    by_name: dict[str, FitResult] = {}
    for name, res in zip(candidates, outcomes, strict=True):
        res = keep_better(res, (carried or {}).get(name))
        if isinstance(res, TaskFailed):
            failed = score_candidate(name, model.error, math.nan, dataset.n_events, 0)
            failed.explains = f"fit failed: {res.message.splitlines()[0]}"
            scores.append(failed)
            continue
        by_name[name] = res
        sc = score_candidate(name, model.error, res.error, dataset.n_events,
                             res.n_params - model.n_params)
        if res.error < model.error:
            cmap = residual_map(dataset, evaluate(dataset, res.choice).score.comparisons)
            sc.explains = explain(base_map, cmap, model, res)
        else:
            sc.explains = "nothing (no improvement)"
        sc.values = {k: v for k, v in res.choice.values.items() if k.startswith(name + ".")}
        scores.append(sc)
    ranked = rank(scores)
    v = verdict(ranked, model.choice.effect_files, protocols_present(dataset))
    if v.runs:
        v.runs = suggest_runs(v.candidates, model.choice.effect_files, _rig_fn(dataset))
    base_disc = discrepancies(base_map)
    best = next((s for s in ranked if s.significant), None)
    if best is None:
        best = next((s for s in ranked if math.isfinite(s.error_reduction)), None)
    residual = base_disc
    if best is not None and best.effect in by_name and best.error_reduction > 0:
        residual = discrepancies(
            residual_map(dataset, evaluate(dataset, by_name[best.effect].choice).score.comparisons))
    v.unexplained = unexplained_text(best, model.error, residual)
    return Round(model, ranked, v, by_name, base_disc)


def diagnose(
    dataset: Dataset,
    choice: ModelChoice,
    *,
    candidates: Sequence[str] | None = None,
    auto: bool = False,
    workers: int | None = None,
    scheduler: Any = None,
    progress: Progress | None = None,
    baseline: FitResult | None = None,
    timeout_s: float = DEFAULT_TIMEOUT_S,
    in_process: bool = False,
    on_fit: FitListener | None = None,
) -> Diagnosis:
    """Rank candidate effects for ``choice`` on ``dataset`` (see the module docstring);
    ``on_fit``: each candidate's fit as it arrives (:func:`run_round`)."""
    say = progress or (lambda _msg: None)
    pool = list(candidates) if candidates is not None else candidate_effects(choice)
    say(f"identifying {choice.label()} on {dataset.n_events} slip events ...")
    base_workers = 1 if in_process or scheduler is not None else (workers or default_workers())
    model = baseline or identify_model(dataset, choice, workers=base_workers)
    say(f"baseline error {model.error:.3g}; fitting {len(pool)} candidate effects")
    diag = Diagnosis(dataset, [], protocols=protocols_present(dataset))
    diag.steps.append(DiagnosisStep(0, model.choice.label(), None, model.error, None))
    restarts = 0
    carried: dict[str, FitResult] = {}
    tried: dict[str, tuple[FitResult, float]] = {}  # this step's candidate fits, refits included
    while True:
        rnd = run_round(dataset, model, pool, workers=workers, scheduler=scheduler,
                        progress=progress, timeout_s=timeout_s, in_process=in_process,
                        carried=carried, on_fit=on_fit)
        _remember(tried, rnd.fits, model.error)
        better = better_model(dataset, model, rnd.fits) if restarts < MAX_BASE_RESTARTS else None
        if better is not None:
            restarts += 1
            say(f"{model.choice.label()} fits better than its own fit reached: {better.message}; "
                "ranking the candidates again")
            last = diag.steps[-1]
            last.note = "; ".join(filter(None, [last.note, better.message]))
            last.error = better.error
            model = better
            carried = {n: f for n, f in rnd.fits.items() if n in f.choice.effects}
            continue
        restarts = 0
        carried = {}
        diag.rounds.append(rnd)
        kind = rnd.verdict.kind
        counts = {"workers": workers, "scheduler": scheduler, "timeout_s": timeout_s,
                  "in_process": in_process}
        # the single effect --auto would add: the verdict's, or the first of an indistinguishable
        # group (None: nothing significant)
        single = None if kind is VerdictKind.NONE else next(
            s for s in rnd.ranking if s.effect == (rnd.verdict.verdict if kind is VerdictKind.EFFECT
                                                   else rnd.verdict.candidates[0]))
        if auto and len(diag.steps) < MAX_AUTO_STEPS and wants_pairs(model, single):
            pair = _try_pairs(dataset, model, tried, say, **counts)
            if single is not None and pair is not None and not beats_single(
                    pair, single, rnd.fits.get(single.effect), dataset.n_events):
                say(f"{single.effect} alone ({single.error:.3g}) is as good as the pair with its "
                    "fewer parameters; adding it alone")
                pair = None
            if pair is not None:
                say(f"adding {pair.first} and {pair.second} together")
                first_score = next(s for s in rnd.ranking if s.effect == pair.first)
                diag.steps.append(DiagnosisStep(
                    len(diag.steps), pair.first_fit.choice.label(), pair.first, pair.first_fit.error,
                    first_score.delta_bic, f"added with {pair.second}: alone {pair.first_fit.error:.3g}, "
                                           "it does not halve the error"))
                note = (f"together with {pair.first}: {model.error:.3g} -> {pair.fit.error:.3g} "
                        "(neither alone halves it)")
                model, note = _with_element_count(dataset, refine(dataset, pair.fit), note, say,
                                                  **counts)
                diag.steps.append(DiagnosisStep(len(diag.steps), model.choice.label(), pair.second,
                                                model.error, pair.score.delta_bic, note))
                pool = [c for c in pool if c not in (pair.first, pair.second)]
                tried = {}
                if not pool:
                    diag.rounds.append(Round(model, [], Verdict(VerdictKind.NONE, [], None), {}, []))
                    break
                continue
        if not auto or single is None or len(diag.steps) > MAX_AUTO_STEPS:
            break
        best_score, best = single, single.effect
        note = "" if kind is VerdictKind.EFFECT else \
            f"indistinguishable from {', '.join(rnd.verdict.candidates[1:])}"
        say(f"adding {best}: error {model.error:.3g} -> {best_score.error:.3g}")
        model, note = _with_element_count(dataset, refine(dataset, rnd.fits[best]), note, say,
                                          **counts)
        diag.steps.append(DiagnosisStep(len(diag.steps), model.choice.label(), best, model.error,
                               best_score.delta_bic, note))
        pool = [c for c in pool if c != best]
        tried = {}
        if not pool:
            diag.rounds.append(Round(model, [], Verdict(VerdictKind.NONE, [], None), {}, []))
            break
    if auto and len(diag.steps) > 1:
        _keep_effects_that_earn_their_place(dataset, diag, say, workers=workers,
                                            scheduler=scheduler, timeout_s=timeout_s,
                                            in_process=in_process)
    return diag


def _with_element_count(dataset: Dataset, model: FitResult, note: str, say: Progress,
                        **run: Any) -> tuple[FitResult, str]:
    """``model`` refitted at the element count that fits best where that matters
    (:func:`~rigctl.workbench.element_count.best_element_count`), with the step's note."""
    counted = best_element_count(dataset, model, say, **run)
    if counted is model:
        return model, note
    n_el = counted.choice.build().n_elements
    say(f"N = {n_el} elements: error {model.error:.3g} -> {counted.error:.3g}")
    note = "; ".join(filter(None, [note, f"N = {n_el} elements (error {model.error:.3g} "
                                         f"at N = {model.choice.build().n_elements})"]))
    return refine(dataset, counted), note


def _remember(tried: dict[str, tuple[FitResult, float]], fits: Mapping[str, FitResult],
              e_model: float) -> None:
    """Keep each candidate's fit that removed the largest fraction of its model's error."""
    for name, res in fits.items():
        old = tried.get(name)
        if old is None or (e_model - res.error) / e_model > (old[1] - old[0].error) / old[1]:
            tried[name] = (res, e_model)


def _try_pairs(dataset: Dataset, model: FitResult, tried: Mapping[str, tuple[FitResult, float]],
               say: Progress, **run: Any) -> Pair | None:
    """The best significant pair of effects (:mod:`rigctl.workbench.pairs`) of this step's
    candidate fits, or None."""
    names = pair_firsts(tried)
    if not names or len(tried) < 2:
        return None
    say(f"no single effect halves the error {model.error:.3g} while it stays above the "
        f"scatter; fitting every other candidate on {' and on '.join(names)}")
    pair = best_pair(dataset, model, tried, progress=say, **run)
    if pair is None:
        say("no pair is significant either")
    else:
        say(f"best pair: {pair.first} and {pair.second} together, error {model.error:.3g} -> "
            f"{pair.fit.error:.3g} ({pair.first} alone {pair.first_fit.error:.3g})")
    return pair


def _rig_fn(dataset: Dataset) -> float | None:
    """The campaign's median normal force where this rig can apply it (suggested runs are runs of
    this rig: a record of another rig at 20 kN gets the protocol's own default)."""
    fns = [float(np.median(r.drive.fn_N)) for r in dataset.runs]
    fn = float(np.median(fns)) if fns else math.nan
    return fn if 0.0 < fn <= MAX_NORMAL_FORCE_N else None


def _best_known(diag: Diagnosis, rest: FitResult) -> FitResult:
    """``rest``, or the model of an earlier round with the same effects where that scores better.

    Both are fits of the same model to the same data, so the lower error is the better estimate of
    that model: the refit without an effect is a short local fit from the final model's values and
    can end worse than the rounds' own fits did, and an effect must not be judged against a model
    fitted worse than it already was (history: docs/decisions.md)."""
    effects = sorted(rest.choice.effects)
    known = [r.model for r in diag.rounds
             if sorted(r.model.choice.effects) == effects and not r.model.misses_most_slips
             and r.model.error < rest.error]
    return min(known, key=lambda m: m.error, default=rest)


def _keep_effects_that_earn_their_place(dataset: Dataset, diag: Diagnosis, say: Progress,
                                        **run: Any) -> None:
    """Every effect ``--auto`` added must, in the final model, at least halve the error the scatter
    does not account for: the model refitted without it must be at least twice as wrong above the
    scatter (:func:`ranking.earns_its_place`; well above the scatter, twice E). One that does not
    is removed (the model refitted without it), and the last round's verdict says what no library
    effect explains. A lone added effect is so judged against the baseline; of two hidden effects
    each alone removes only part of the error, but in the final model each halves it. The final
    model and each model without an effect are searched over the slider mass alike
    (:mod:`rigctl.workbench.mass_search`) before they are compared."""
    model = polish(dataset, diag.rounds[-1].model, say, **run)
    if model.error < diag.rounds[-1].model.error:
        say(f"{model.choice.label()} fitted on: error {diag.rounds[-1].model.error:.3g} -> "
            f"{model.error:.3g}")
        diag.steps[-1].error = model.error
        diag.rounds[-1].model = model
    for effect in [st.added for st in diag.steps if st.added]:
        if effect not in model.choice.effects:
            continue
        try:
            rest = identify_model(dataset, without_effect(model.choice, effect),
                                  with_uncertainty=False, max_nfev=PRUNE_MAX_NFEV)
        except (ParameterError, SimulationError):
            continue
        # the model without the effect gets the same mass search as the model with it: an effect
        # is not kept for a valley the search found only for the model that has it
        rest = refit_over_mass(dataset, rest, say=say, **run)
        rest = _best_known(diag, rest)
        if earns_its_place(model.error, rest.error):
            continue
        say(f"removing {effect}: without it the error is {rest.error:.3g}, with it "
            f"{model.error:.3g} (above the scatter {excess_error(rest.error):.3g} -> "
            f"{excess_error(model.error):.3g}: it does not halve it)")
        model = refine(dataset, rest)
        diag.steps.append(DiagnosisStep(
            len(diag.steps), model.choice.label(), None, model.error, None,
            f"removed {effect}: it does not halve the error above the scatter ({rest.error:.3g} "
            f"without it, {diag.rounds[-1].model.error:.3g} with it)"))
        last = diag.rounds[-1]
        text = unexplained_text(None, model.error, discrepancies(residual_map(
            dataset, evaluate(dataset, model.choice).score.comparisons)))
        diag.rounds.append(Round(model, [], Verdict(VerdictKind.NONE, [], None, text), {},
                                 last.discrepancies))
