"""The error of a model at its values as a start: infinite where it cannot describe the data.

A start, screen point or step that is not physically valid, cannot be run, or misses most of the
measured slips would lead a fit into the no-slip trap (:func:`~rigctl.workbench.identify.
misses_most_slips`), so its error is infinite, never a number a search could prefer.
"""

from __future__ import annotations

from rigctl.errors import SimulationError
from rigctl.records.dataset import Dataset
from rigctl.workbench.evaluate import evaluate
from rigctl.workbench.identify import misses_most_slips, physically_valid
from rigctl.workbench.metrics import Score
from rigctl.workbench.model_choice import ModelChoice


def error_or_inf(dataset: Dataset, choice: ModelChoice, fns: tuple[float, float]) -> float:
    """The event-aware error of ``choice`` as a start; inf where :func:`score_or_none` has none."""
    score = score_or_none(dataset, choice, fns)
    return float("inf") if score is None else float(score.error)


def score_or_none(dataset: Dataset, choice: ModelChoice, fns: tuple[float, float]) -> Score | None:
    """The model's score, or None when it is not physically valid, cannot be run, or misses most of
    the measured slips (no description of the data, whatever its error: a start, scan point or
    step there would lead the fit into the no-slip trap, see
    :func:`~rigctl.workbench.identify.misses_most_slips`)."""
    if not physically_valid(choice, fns):
        return None
    try:
        score = evaluate(dataset, choice, bounded=True).score
    except SimulationError:
        return None
    return None if misses_most_slips(dataset, score.comparisons) else score
