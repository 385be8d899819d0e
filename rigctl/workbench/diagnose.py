"""Learn what is missing: rank the candidate effects by evidence, or choose the model's effects.

:func:`diagnose` identifies the model on the campaign by the one search
(:mod:`rigctl.workbench.search`) and ranks the candidate effects by one forward step of the
selection (:mod:`rigctl.workbench.selection`: every candidate and pair screened, the promising ones
fitted fully by the same search, scored by :mod:`rigctl.workbench.ranking`), explaining each by
the residual structure it removes (:mod:`rigctl.workbench.residual_map`). With ``auto`` it chooses
the model's effects by forward selection and backward elimination over the same search
(:mod:`rigctl.workbench.auto_diagnosis`); every step's error is kept for the error-fall chart.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from threading import Event
from typing import Any

import numpy as np

from rigctl.model import MAX_NORMAL_FORCE_N
from rigctl.records.dataset import Dataset
from rigctl.records.feature_info import FEATURES
from rigctl.workbench.identify import FitResult
from rigctl.workbench.model_choice import ModelChoice
from rigctl.workbench.parallel import DEFAULT_TIMEOUT_S
from rigctl.workbench.ranking import CandidateScore, Verdict
from rigctl.workbench.residual_map import (
    COVARIATE_NAMES,
    ResidualMap,
    significant_trends,
)
from rigctl.workbench.run_deadline import DEFAULT_RUN_S

Progress = Callable[[str], None]
FitListener = Callable[[str, FitResult], None]
"""``on_fit(candidate, fit)``: a fully fitted candidate set's fit."""


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
    """Where the run's time limit (``--max-time``) ended it (empty: it ran to its end)."""

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
            "time_limited": self.time_limited,
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


def diagnose(
    dataset: Dataset,
    choice: ModelChoice,
    *,
    candidates: Sequence[str] | None = None,
    auto: bool = False,
    workers: int | None = None,
    progress: Progress | None = None,
    baseline: FitResult | None = None,
    timeout_s: float | None = DEFAULT_TIMEOUT_S,
    on_fit: FitListener | None = None,
    max_run_s: float | None = DEFAULT_RUN_S,
    cancel: Event | None = None,
) -> Diagnosis:
    """Rank candidate effects for ``choice`` on ``dataset``, or with ``auto`` choose them (the
    module docstring; :func:`rigctl.workbench.auto_diagnosis.diagnose_auto`). ``workers``: the
    search's worker processes (None: the CPUs; 0: evaluate in this process); ``timeout_s``: each
    fit's time limit after the model's own (None: none); ``max_run_s``: the whole run's (None:
    none); ``on_fit``: each fully fitted set's fit; ``cancel``: an event that ends the run."""
    # imported here: auto_diagnosis tells its selection as this module's Diagnosis
    from rigctl.workbench.auto_diagnosis import diagnose_auto

    return diagnose_auto(dataset, choice, candidates=candidates, workers=workers,
                         progress=progress, baseline=baseline, on_fit=on_fit, cancel=cancel,
                         fit_wall_s=timeout_s, max_run_s=max_run_s, rank_only=not auto)


def rig_fn(dataset: Dataset) -> float | None:
    """The campaign's median normal force where this rig can apply it (suggested runs are runs of
    this rig: a record of another rig at 20 kN gets the protocol's own default)."""
    fns = [float(np.median(r.drive.fn_N)) for r in dataset.runs]
    fn = float(np.median(fns)) if fns else math.nan
    return fn if 0.0 < fn <= MAX_NORMAL_FORCE_N else None
