"""Compare a model with a measured campaign: identify it, simulate every run, locate the misfit.

This is ``rigctl model compare``: the model (base + chosen effects) is identified on the data
by the one search (:mod:`rigctl.workbench.search`), simulated on each run's measured stage position
and normal force,
and put against the measurement as per-event features, the event-aware error
(:mod:`rigctl.workbench.metrics`) and a residual map with the largest structured discrepancies in
words (:mod:`rigctl.workbench.residual_map`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from rigctl.data import MeasuredRun
from rigctl.model import SimResult
from rigctl.records.dataset import Dataset, prepare_dataset, protocols_present
from rigctl.records.delta_stitch import stitch_record
from rigctl.records.feature_info import FEATURES
from rigctl.records.image_features import model_ratios
from rigctl.workbench.budget import said
from rigctl.workbench.evaluate import Evaluation, evaluate
from rigctl.workbench.identify import FitResult
from rigctl.workbench.metrics import FeatureError, physical_errors
from rigctl.workbench.model_choice import ModelChoice
from rigctl.workbench.residual_map import (
    ResidualMap,
    discrepancies,
    residual_map,
    significant_trends,
)
from rigctl.workbench.search import search_model


@dataclass
class Comparison:
    runs: list[MeasuredRun]
    dataset: Dataset
    fit: FitResult
    evaluation: Evaluation
    errors: dict[str, FeatureError]
    rmap: ResidualMap
    discrepancies: list[str]
    identified: bool

    @property
    def results(self) -> list[SimResult]:
        return self.evaluation.results or []

    def parameter_rows(self) -> list[dict[str, Any]]:
        rows = []
        for p in self.fit.choice.parameter_table():
            fitted = p.name in self.fit.free
            sigma = self.fit.sigma.get(p.name, math.nan)
            rows.append({
                "name": p.name, "value": p.value, "unit": p.unit, "owner": p.owner,
                "fitted": fitted, "sigma": sigma if math.isfinite(sigma) else None,
                "determined": fitted and p.name not in self.fit.undetermined,
            })
        return rows

    def image_rows(self) -> list[dict[str, Any]]:
        """Per run: the image features measured and of the model, the per-part load ratios r(k)
        (:mod:`rigctl.records.image_features`), or why the run has none."""
        rows: list[dict[str, Any]] = []
        images = self.evaluation.images or [{} for _ in self.dataset.runs]
        results: list[SimResult | None] = list(self.results) or [None] * len(self.dataset.runs)
        for run, model, res in zip(self.dataset.runs, images, results, strict=True):
            if run.image is None:
                rows.append({"name": run.name, "absent": run.image_absent or "no camera frames"})
                continue
            rows.append({
                "name": run.name, **run.image.to_json(),
                "model": model,
                "r_model": model_ratios(res, run.image).tolist() if res is not None else None,
            })
        return rows

    def to_json(self) -> dict[str, Any]:
        return {
            "model": self.fit.choice.label(),
            "base": self.fit.choice.base,
            "effects": list(self.fit.choice.effects),
            "identified": self.identified,
            "error": self.fit.error,
            "feature_errors": {
                name: {
                    "z": self.fit.feature_error.get(name),
                    "rms": fe.rms, "mean": fe.mean, "unit": fe.unit, "n": fe.n,
                }
                for name, fe in self.errors.items()
            },
            "parameters": self.parameter_rows(),
            "image_features": self.image_rows(),
            "undetermined": list(self.fit.undetermined),
            "discrepancies": self.discrepancies,
            "residual_by_stage": self.rmap.by_stage,
            "residual_by_phase": self.rmap.by_phase,
            "residual_by_time": {k: [float(x) for x in v] for k, v in self.rmap.by_time.items()},
            "residual_trends": [
                {"feature": t.feature, "covariate": t.covariate, "log": t.log,
                 "amplitude_z": t.amplitude_z, "t": t.t_stat, "n": t.n}
                for t in significant_trends(self.rmap)
            ],
            "runs": [
                {"name": r.name, "events_measured": r.events.n, "events_model": m.n}
                for r, m in zip(self.dataset.runs, self.evaluation.events, strict=True)
            ],
            "n_events": self.dataset.n_events,
            "protocols_present": protocols_present(self.dataset),
            "notes": list(self.dataset.notes),
        }


def compare(
    runs: Sequence[MeasuredRun],
    choice: ModelChoice,
    *,
    identify: bool = True,
    dataset: Dataset | None = None,
    progress: Callable[[str], None] | None = None,
    workers: int | None = None,
    max_wall_s: float | None = None,
) -> Comparison:
    """Identify ``choice`` on the runs by the one search (unless ``identify`` is False) and
    compare it with them. ``workers``: the search's worker processes (None: the CPUs; 0: this
    process); ``max_wall_s``: the search's time limit (None: its own budget), where it ends with
    its best point so far (:attr:`FitResult.time_limited`)."""
    say = progress or (lambda _m: None)
    # the probes' readings stitched across their mounts' re-centrings, for the report's figures
    # as for the dataset (rigctl.records.delta_stitch; a stitched run is not stitched again)
    runs = [stitch_record(r) for r in runs]
    ds = dataset or prepare_dataset(runs)
    if identify:
        say(f"identifying {choice.label()} on {ds.n_events} slip events ...")
        fit = search_model(ds, choice, workers=workers, progress=said(say),
                           max_wall_s=max_wall_s)
    else:
        ev0 = evaluate(ds, choice)
        fit = FitResult(choice, ev0.score.error, ev0.score.feature_error, ())
    ev = evaluate(ds, fit.choice, keep_results=True)
    rmap = residual_map(ds, ev.score.comparisons)
    return Comparison(
        runs=list(runs), dataset=ds, fit=fit, evaluation=ev,
        errors=physical_errors(ev.score.comparisons), rmap=rmap,
        discrepancies=discrepancies(rmap) + image_discrepancies(ds, ev), identified=identify,
    )


IMAGE_DISCREPANCY_Z = 3.0
"""An image feature off by more than this many of its scatters is named among the discrepancies
(the per-event features are named by their trends, :func:`residual_map.discrepancies`)."""


def image_discrepancies(dataset: Dataset, ev: Evaluation) -> list[str]:
    """The image features the model misses, in words (one per run and feature)."""
    out: list[str] = []
    for run, model in zip(dataset.runs, ev.images or [{} for _ in dataset.runs], strict=True):
        if run.image is None:
            continue
        measured, sigma = run.image.measured(), run.image.sigma()
        for name, value in measured.items():
            m = model.get(name, math.nan)
            z = (m - value) / sigma[name]
            if math.isfinite(z) and abs(z) > IMAGE_DISCREPANCY_Z:
                nd = max(0, 1 - math.floor(math.log10(sigma[name])))  # digits of the scatter
                out.append(f"{FEATURES[name].phrase}: the images give {value:.{nd}f} +- "
                           f"{sigma[name]:.{nd}f}, the model {m:.{nd}f} ({z:+.0f} scatters) "
                           f"in {run.name}")
    return out
