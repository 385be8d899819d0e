"""The model workbench: compare the model with measured runs, see where it fails, find what is missing.

The pipeline, one module per step (docs/workbench.md, with the detail in docs/reading-records.md and
docs/identification.md, tells the why of each):

read
    :mod:`rigctl.records` reads the runs (checked, the drive simplified, the slips found and
    measured, probes over range or absent, the rig description that came with the data, the
    scatter each feature is measured in): the workbench and the analysis share it.
score
    :mod:`~rigctl.workbench.evaluate` simulates the model on every run and reads it with the same
    eyes; :mod:`~rigctl.workbench.alignment` pairs model and measured slips;
    :mod:`~rigctl.workbench.metrics` gives the event-aware error E.
fit
    :mod:`~rigctl.workbench.data_scale` (starting values at the data's own scale),
    :mod:`~rigctl.workbench.guess` (ratio guess), :mod:`~rigctl.workbench.identify` (parameters,
    objective, uncertainties), :mod:`~rigctl.workbench.search` (the one search: starts, CMA-ES,
    a least-squares polish, one budget; its points evaluated in the worker processes of
    :mod:`~rigctl.workbench.search_pool`), :mod:`~rigctl.workbench.screening` (the score screen
    of candidate effects).
decide
    :mod:`~rigctl.workbench.residual_map` (where it fails, in words),
    :mod:`~rigctl.workbench.ranking` (evidence, verdict, what no effect explains, runnable
    suggestions), :mod:`~rigctl.workbench.selection` (forward selection and backward elimination
    over the search; the ranking is its first step), :mod:`~rigctl.workbench.diagnose` (the
    ranking and ``--auto`` told as rounds and steps).
report
    :mod:`~rigctl.workbench.compare` (one model against the data), :mod:`~rigctl.workbench.report`
    and :mod:`~rigctl.workbench.plots` (HTML and figures); :mod:`~rigctl.workbench.campaigns`
    simulates campaigns for tests and benchmarks.

The public API is below (``__all__``); everything else is free to change. Names are imported
lazily, so that importing the package does not load the fitting machinery. ``Dataset``,
``prepare_dataset`` and ``RigDescription`` live in :mod:`rigctl.records` and are re-exported here
so that scripts written against ``rigctl.workbench`` keep working.
"""

from __future__ import annotations

import importlib
from typing import Any

_API: dict[str, str] = {
    "ModelChoice": "rigctl.workbench.model_choice",
    "Dataset": "rigctl.records.dataset",
    "prepare_dataset": "rigctl.records.dataset",
    "RigDescription": "rigctl.records.rig_description",
    "evaluate": "rigctl.workbench.evaluate",
    "search_model": "rigctl.workbench.search",
    "FitResult": "rigctl.workbench.identify",
    "compare": "rigctl.workbench.compare",
    "Comparison": "rigctl.workbench.compare",
    "diagnose": "rigctl.workbench.diagnose",
    "Diagnosis": "rigctl.workbench.diagnose",
}

__all__ = sorted(_API)


def __getattr__(name: str) -> Any:
    module = _API.get(name)
    if module is None:
        raise AttributeError(f"module 'rigctl.workbench' has no attribute {name!r}")
    return getattr(importlib.import_module(module), name)
