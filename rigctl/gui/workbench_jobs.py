"""The Workbench tab's work, run in worker processes (:mod:`rigctl.gui.process_job`); no Qt here.

Each job loads the runs as ``rigctl model`` does (:func:`rigctl.io.load.load_runs`, long records cut
into windows by :func:`rigctl.records.long_records.window_long_runs`) and calls the workbench's
public functions: :func:`~rigctl.workbench.compare.compare` (``rigctl model compare``) and
:func:`~rigctl.workbench.diagnose.diagnose` (``rigctl model diagnose``). What goes back to the window
is small and picklable: overlays decimated to ``OVERLAY_POINTS`` per curve
(:func:`~rigctl.gui.decimate.peak_indices`), the residual map as a matrix, the ranking as rows, the
plug-in candidates' fitted parameters with their uncertainties (:class:`CandidateParams`: during the
round as progress lines, since a progress report is text; after it in the view).
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from rigctl.gui.decimate import FloatArray, peak_indices

if TYPE_CHECKING:
    from rigctl.gui.process_job import Report
    from rigctl.records.dataset import Dataset
    from rigctl.workbench.compare import Comparison
    from rigctl.workbench.identify import FitResult
    from rigctl.workbench.model_choice import ModelChoice

OVERLAY_POINTS = 5000
MAX_OVERLAY_RUNS = 6


@dataclass(frozen=True)
class ModelRequest:
    """Which data and which model (as the ``rigctl model`` options DATA, --base, --effects,
    --effect-file)."""

    paths: tuple[str, ...]
    base: str = "paper"
    effects: tuple[str, ...] = ()
    effect_files: tuple[str, ...] = ()

    def choice(self) -> ModelChoice:
        from rigctl.workbench.model_choice import ModelChoice

        choice = ModelChoice(self.base, self.effects, {}, self.effect_files)
        choice.build()  # parameter problems surface here, as one line
        return choice

    def label(self) -> str:
        return self.base + "".join(f" + {e}" for e in self.effects)


@dataclass(frozen=True)
class Overlay:
    """One run, measured and model, decimated: Ft and delta against time."""

    name: str
    t_s: FloatArray
    ft_N: FloatArray
    delta_m: FloatArray
    t_model_s: FloatArray
    ft_model_N: FloatArray
    delta_model_m: FloatArray


@dataclass(frozen=True)
class CompareView:
    """A comparison of one model with the data, as the tab shows it."""

    label: str
    effects: tuple[str, ...]
    error: float
    n_events: int
    n_runs: int
    feature_z: dict[str, float]
    overlays: list[Overlay]
    residual: FloatArray
    """Signed trend amplitude (z) of each feature (rows) against each covariate (columns)."""
    features: tuple[str, ...]
    """The features' names (``peak_N``, ...), rows of :attr:`residual`."""
    phrases: tuple[str, ...]
    """What each feature is, in words."""
    covariates: tuple[str, ...]
    by_stage: dict[str, dict[str, float]]
    by_phase: dict[str, float]
    discrepancies: list[str]
    parameters: list[dict[str, Any]]
    notes: list[str] = field(default_factory=list)


@dataclass(frozen=True)
class RankingRow:
    effect: str
    error: float
    error_reduction: float
    delta_bic: float
    significant: bool
    explains: str


@dataclass(frozen=True)
class ParamValue:
    """One fitted parameter of a candidate effect (its name without the effect's prefix)."""

    name: str
    value: float
    sigma: float | None
    """1-sigma uncertainty (:func:`rigctl.workbench.identify.uncertainties`); None where none
    was computed (a candidate fit takes no covariance: shown as ``±?``)."""
    unit: str
    undetermined: bool = False

    def text(self) -> str:
        """``0.0312 ± 0.0021`` (``± ?`` without an uncertainty)."""
        sig = "?" if self.sigma is None or not math.isfinite(self.sigma) else f"{self.sigma:.2g}"
        unit = "" if self.unit in ("", "-") else f" {self.unit}"
        flag = " (not determined)" if self.undetermined else ""
        return f"{self.value:.4g} ± {sig}{unit}{flag}"


@dataclass(frozen=True)
class CandidateParams:
    """A plug-in candidate's fitted parameters, as the tab shows them during and after a round."""

    effect: str
    error: float
    params: tuple[ParamValue, ...]
    final: bool
    """False: the candidate fit as it arrived (no uncertainties); True: with the uncertainties of
    a Jacobian taken at its fitted values (:func:`rigctl.workbench.identify.with_uncertainties`)."""
    note: str = ""

    def line(self) -> str:
        values = ", ".join(f"{p.name} = {p.text()}" for p in self.params)
        note = f"; {self.note}" if self.note else ""
        return f"{self.effect} (error {self.error:.3g}): {values}{note}"

    def to_text(self) -> str:
        """As the worker reports it (:data:`PARAMS_TAG` + JSON): progress is text."""
        return PARAMS_TAG + json.dumps({
            "effect": self.effect, "error": self.error, "final": self.final, "note": self.note,
            "params": [[p.name, p.value, p.sigma, p.unit, p.undetermined] for p in self.params]})

    @staticmethod
    def from_text(text: str) -> CandidateParams | None:
        """The inverse of :meth:`to_text`; None for any other progress line."""
        if not text.startswith(PARAMS_TAG):
            return None
        d = json.loads(text[len(PARAMS_TAG):])
        params = tuple(ParamValue(str(n), float(v), None if s is None else float(s), str(u),
                                  bool(und)) for n, v, s, u, und in d["params"])
        return CandidateParams(str(d["effect"]), float(d["error"]), params, bool(d["final"]),
                               str(d["note"]))


PARAMS_TAG = "candidate parameters: "
"""Progress lines that carry a plug-in candidate's fitted parameters (:meth:`CandidateParams.
to_text`); the tab shows them in its table and logs them in words."""


@dataclass(frozen=True)
class DiagnoseView:
    """A diagnosis round: the model's error, the candidates ranked by evidence, the verdict."""

    label: str
    baseline_error: float
    rows: list[RankingRow]
    verdict: str
    candidates: list[str]
    unexplained: str
    suggest: str | None
    discrepancies: list[str]
    plugin_params: list[CandidateParams] = field(default_factory=list)
    """The plug-in candidates' fitted parameters with their uncertainties."""


def load(paths: Sequence[str]) -> list[Any]:
    """The runs named (files or campaign folders), long records windowed, as ``rigctl model``."""
    from rigctl.io.load import load_runs
    from rigctl.records.long_records import window_long_runs

    return window_long_runs(load_runs(list(paths)))


def compare_job(report: Report, request: ModelRequest, identify: bool = True) -> CompareView:
    """Identify ``request``'s model on its runs and compare (the worker process's target)."""
    from rigctl.workbench.compare import compare

    choice = request.choice()
    report(f"loading {len(request.paths)} path(s)", math.nan)
    runs = load(request.paths)
    cmp = compare(runs, choice, identify=identify, progress=lambda m: report(m, math.nan))
    report("simulated; preparing the overlays", 1.0)
    return compare_view(cmp)


def diagnose_job(report: Report, request: ModelRequest, candidates: tuple[str, ...] = (),
                 workers: int | None = None) -> DiagnoseView:
    """Rank candidate effects on ``request``'s model (``rigctl model diagnose``; default candidates:
    every library and plug-in effect the model does not have)."""
    from rigctl.records.dataset import prepare_dataset
    from rigctl.workbench.diagnose import diagnose
    from rigctl.workbench.model_choice import candidate_effects

    choice = request.choice()
    names = list(candidates) or candidate_effects(choice)
    if not names:
        raise ValueError("no candidate effects left to try")
    report(f"loading {len(request.paths)} path(s)", math.nan)
    dataset = prepare_dataset(load(request.paths))

    def progress(msg: str) -> None:
        report(msg.strip(), part_done(msg))

    plugins = plugin_names(names)

    def on_fit(name: str, fit: FitResult) -> None:
        if name in plugins:  # shown at once, without uncertainties (a candidate fit takes none)
            report(candidate_params(name, fit, final=False).to_text(), math.nan)

    diag = diagnose(dataset, choice, candidates=names, workers=workers, progress=progress,
                    on_fit=on_fit)
    r0 = diag.first
    rows = [RankingRow(s.effect, s.error, s.error_reduction, s.delta_bic, s.significant, s.explains)
            for s in r0.ranking]
    shown = []
    for name in plugins:
        fit = r0.fits.get(name)
        if fit is None:
            continue
        report(f"uncertainties of {name}'s parameters ({len(fit.free) + 1} simulations or more)",
               math.nan)
        cp = plugin_uncertainties(dataset, name, fit)
        report(cp.to_text(), math.nan)
        shown.append(cp)
    v = r0.verdict
    return DiagnoseView(r0.model.choice.label(), r0.model.error, rows, v.verdict,
                        list(v.candidates), v.unexplained, v.suggest, list(r0.discrepancies),
                        shown)


def part_done(msg: str) -> float:
    """The fraction of its part of the step a progress line reports (``[3/11, about 40 s left in
    this round]``: the screens, the full fits; :class:`~rigctl.workbench.round_eta.RoundClock`),
    NaN for a line that reports none."""
    m = re.search(r"\[(\d+)/(\d+)\b", msg)
    return int(m.group(1)) / int(m.group(2)) if m and int(m.group(2)) > 0 else math.nan


def plugin_names(names: Sequence[str]) -> list[str]:
    """The candidates that are not the library's (plug-in files and entry points)."""
    from rigctl.model.effects import LIBRARY

    return [n for n in names if n not in LIBRARY]


def candidate_params(effect: str, fit: FitResult, final: bool, note: str = "") -> CandidateParams:
    """``effect``'s fitted parameters of ``fit`` with the uncertainties it carries (none: None)."""
    prefix = f"{effect}."
    table = fit.choice.parameter_table()
    params = tuple(
        ParamValue(p.name[len(prefix):], float(p.value), fit.sigma.get(p.name), p.unit,
                   p.name in fit.undetermined)
        for p in table if p.name.startswith(prefix) and p.name in fit.free)
    return CandidateParams(effect, float(fit.error), params, final, note)


def plugin_uncertainties(dataset: Dataset, effect: str, fit: FitResult) -> CandidateParams:
    """``effect``'s parameters with uncertainties from a Jacobian of all the fit's free parameters
    at its values (:func:`~rigctl.workbench.identify.with_uncertainties`: the covariance
    s^2 (J^T J)^-1, so the effect's sigma includes its correlation with the base parameters); the
    values alone (``±?``) where the Jacobian cannot be taken."""
    from rigctl.errors import SimulationError
    from rigctl.model import ParameterError
    from rigctl.workbench.identify import with_uncertainties

    try:
        return candidate_params(effect, with_uncertainties(dataset, fit), final=True)
    except (SimulationError, ParameterError, ValueError, np.linalg.LinAlgError) as exc:
        return candidate_params(effect, fit, final=True, note=f"no uncertainty: {exc}")


def compare_view(cmp: Comparison) -> CompareView:
    """What the tab needs of a :class:`~rigctl.workbench.compare.Comparison`."""
    from rigctl.records.feature_info import FEATURES
    from rigctl.records.features import COVARIATES, EVENT_FEATURES
    from rigctl.workbench.residual_map import COVARIATE_NAMES, trend_matrix

    overlays = []
    for run, res, prep in list(zip(cmp.runs, cmp.results, cmp.dataset.runs,
                                   strict=False))[:MAX_OVERLAY_RUNS]:
        t = run.t_s - run.t_s[0]  # the model's time starts at the run's first sample
        i = peak_indices(run.ft_N, OVERLAY_POINTS)
        j = peak_indices(res.ft_N, OVERLAY_POINTS)
        dm = res.d1_m - res.d2_m
        overlays.append(Overlay(prep.name, t[i], run.ft_N[i], run.delta_m[i], res.t_s[j],
                                res.ft_N[j], dm[j]))
    amp = trend_matrix(cmp.rmap)
    choice = cmp.fit.choice
    return CompareView(
        label=choice.label(), effects=tuple(choice.effects), error=float(cmp.fit.error),
        n_events=cmp.dataset.n_events, n_runs=len(cmp.dataset.runs),
        feature_z={k: float(v) for k, v in cmp.fit.feature_error.items()},
        overlays=overlays, residual=amp,
        features=EVENT_FEATURES, phrases=tuple(FEATURES[f].phrase for f in EVENT_FEATURES),
        covariates=tuple(COVARIATE_NAMES[c] for c in COVARIATES),
        by_stage={k: dict(v) for k, v in cmp.rmap.by_stage.items()},
        by_phase=dict(cmp.rmap.by_phase), discrepancies=list(cmp.discrepancies),
        parameters=cmp.parameter_rows(), notes=list(cmp.dataset.notes),
    )
