"""Learn what is missing: fit every candidate effect, rank by evidence; or choose the effects.

:func:`diagnose` identifies the model on the campaign, fits base + each candidate effect in parallel
(:mod:`rigctl.workbench.parallel`), ranks them (:mod:`rigctl.workbench.ranking`) and explains each
by the residual structure it removes (:mod:`rigctl.workbench.residual_map`). With ``auto`` it
chooses the model's effects by forward selection and backward elimination over the one search
(:mod:`rigctl.workbench.auto_diagnosis`); every step's error is kept for the error-fall chart.
"""

from __future__ import annotations

import contextlib
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from rigctl.model import MAX_NORMAL_FORCE_N
from rigctl.records.dataset import Dataset, protocols_present
from rigctl.records.drive_profile import DriveProfile
from rigctl.records.feature_info import FEATURES
from rigctl.workbench.evaluate import evaluate, simulate_run
from rigctl.workbench.fitting import (
    CandidateTask,
    error_or_inf,
    fit_candidate,
    identify_model,
)
from rigctl.workbench.identify import (
    FitResult,
    fn_range,
    free_params,
    least_squares_fit,
    physically_valid,
)
from rigctl.workbench.model_choice import ModelChoice, candidate_effects, without_effect
from rigctl.workbench.parallel import DEFAULT_TIMEOUT_S, TaskFailed, default_workers, run_tasks
from rigctl.workbench.ranking import (
    MIN_ERROR_REDUCTION,
    CandidateScore,
    Verdict,
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
from rigctl.workbench.run_deadline import DEFAULT_RUN_S

MAX_BASE_RESTARTS = 2
"""Times a round is run again from a better fit of its own model (:func:`better_model`)."""
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
    time_limited: str = ""
    """``--auto``: where the run's time limit (``--max-time``) ended it (empty: it ran to its
    end)."""

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
            last = self.rounds[-1].verdict
            out["final_unexplained"] = last.unexplained
            out["final_verdict"] = last.verdict
            out["final_candidates"] = last.candidates
            out["final_suggest"] = last.suggest
            out["final_suggest_runs"] = last.runs
            out["time_limited"] = self.time_limited
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
        v.runs = suggest_runs(v.candidates, model.choice.effect_files, rig_fn(dataset))
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
    max_run_s: float | None = DEFAULT_RUN_S,
) -> Diagnosis:
    """Rank candidate effects for ``choice`` on ``dataset`` (see the module docstring);
    ``on_fit``: each candidate's fit as it arrives (:func:`run_round`). With ``auto``, forward
    selection over the one search (:func:`rigctl.workbench.auto_diagnosis.diagnose_auto`), on
    this machine's worker processes (``scheduler`` is refused: the search's evaluation pool is
    local), within ``max_run_s`` wall seconds (None: no limit)."""
    if auto:
        if scheduler is not None:
            raise ValueError("--auto runs its searches on this machine's worker processes; "
                             "a Dask scheduler serves the ranking without --auto")
        # imported here: auto_diagnosis tells its selection as this module's Diagnosis
        from rigctl.workbench.auto_diagnosis import diagnose_auto

        return diagnose_auto(dataset, choice, candidates=candidates,
                             workers=0 if in_process else workers, progress=progress,
                             baseline=baseline, on_fit=on_fit, fit_wall_s=timeout_s,
                             max_run_s=max_run_s)
    say = progress or (lambda _msg: None)
    pool = list(candidates) if candidates is not None else candidate_effects(choice)
    say(f"identifying {choice.label()} on {dataset.n_events} slip events ...")
    base_workers = 1 if in_process or scheduler is not None else (workers or default_workers())
    model = baseline or identify_model(dataset, choice, workers=base_workers)
    say(f"baseline error {model.error:.3g}; fitting {len(pool)} candidate effects")
    diag = Diagnosis(dataset, [], protocols=protocols_present(dataset))
    diag.steps.append(DiagnosisStep(0, model.choice.label(), None, model.error, None))
    carried: dict[str, FitResult] = {}
    for restarts in range(MAX_BASE_RESTARTS + 1):
        rnd = run_round(dataset, model, pool, workers=workers, scheduler=scheduler,
                        progress=progress, timeout_s=timeout_s, in_process=in_process,
                        carried=carried, on_fit=on_fit)
        better = better_model(dataset, model, rnd.fits) if restarts < MAX_BASE_RESTARTS else None
        if better is None:
            diag.rounds.append(rnd)
            break
        say(f"{model.choice.label()} fits better than its own fit reached: {better.message}; "
            "ranking the candidates again")
        last = diag.steps[-1]
        last.note = "; ".join(filter(None, [last.note, better.message]))
        last.error = better.error
        model = better
        carried = {n: f for n, f in rnd.fits.items() if n in f.choice.effects}
    return diag


def rig_fn(dataset: Dataset) -> float | None:
    """The campaign's median normal force where this rig can apply it (suggested runs are runs of
    this rig: a record of another rig at 20 kN gets the protocol's own default)."""
    fns = [float(np.median(r.drive.fn_N)) for r in dataset.runs]
    fn = float(np.median(fns)) if fns else math.nan
    return fn if 0.0 < fn <= MAX_NORMAL_FORCE_N else None
